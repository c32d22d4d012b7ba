"""
The deterministic event loop every lockstep node runs in: one clock, one queue, no threads.

Events are timer firings and message deliveries, kept in one heap ordered by (sim time ns,
sequence number). A timer with period P created at time S fires at S + k·P exactly (integer
nanoseconds, no drift). A message published during a callback is queued for each matching
subscription at the same sim time, behind the events already queued for that time, so it is
delivered after the callback returns and in publish order. Nothing reads the wall clock.

The runner drives the loop with :meth:`Runtime.run_until`; a node file's ``main()`` drives it
through ``rclpy.spin``, which stops at the horizon set with :meth:`Runtime.set_horizon`.
"""

from dataclasses import dataclass
import heapq
import itertools
import sys
from typing import Callable, Iterable, Optional

from sim_bridge.lockstep.errors import LockstepError, NodeError, StalledError

NANOSECONDS_PER_SECOND = 1_000_000_000


@dataclass(frozen=True)
class LogRecord:
    """One log call that passed its logger's level and filters."""

    name: str       # logger name: the node name, or 'ns.node' inside a namespace
    level: str      # 'DEBUG', 'INFO', 'WARN', 'ERROR' or 'FATAL'
    time_ns: int    # sim time of the call (ns)
    text: str

    def line(self) -> str:
        """Format the record as rcutils' console does: ``[INFO] [12.340000000] [name]: …``."""
        seconds, nanoseconds = divmod(self.time_ns, NANOSECONDS_PER_SECOND)
        return f'[{self.level}] [{seconds}.{nanoseconds:09d}] [{self.name}]: {self.text}'


def print_log_record(record: LogRecord) -> None:
    """Print the record's console line to stderr, where rcutils writes (the default sink)."""
    print(record.line(), file=sys.stderr)


class Runtime:
    """
    Sim clock, event queue, topic graph, taps and log sink of one lockstep session.

    Entities put on the queue (timers, subscriptions) provide ``_lockstep_fire(token)`` and
    ``_lockstep_node_name``; an exception from ``_lockstep_fire`` leaves the loop wrapped in
    :class:`NodeError`.
    """

    def __init__(self) -> None:
        from sim_bridge.lockstep.topics import Graph
        self.now_ns = 0
        self.horizon_ns: Optional[int] = None
        self.graph = Graph()
        self.nodes: list = []
        self.taps: list = []        # (tap, topic names or None for all)
        self._topic_taps: dict = {}  # topic name -> the taps publishers on it call
        self.last_node_error: Optional[NodeError] = None
        self.logger_levels: dict = {}
        self.default_context = None
        self.global_executor = None
        self._queue: list = []
        self._sequence = itertools.count()
        self._log_sink: Callable = print_log_record
        self._running = False

    # --- observers -------------------------------------------------------------------------

    def add_tap(self, tap: Callable, topics: Optional[Iterable[str]] = None) -> None:
        """
        Call ``tap(topic, msg, t_ns)`` on every successful publish, during the publish.

        ``topics``: the fully qualified topic names to tap (None: every topic). ``msg`` may be
        the publisher's own object: a tap reads it there and then, and copies what it keeps,
        as a subscriber's copy is not made when nobody subscribes.
        """
        self.taps.append((tap, None if topics is None else frozenset(topics)))
        self._refresh_taps()

    def remove_tap(self, tap: Callable) -> None:
        """Stop calling ``tap``."""
        self.taps = [(added, topics) for added, topics in self.taps if added != tap]
        self._refresh_taps()

    def taps_on(self, topic: str) -> list:
        """
        Return the live list of taps on ``topic``, for its publishers to keep.

        The list is updated in place when taps are added or removed.
        """
        if topic not in self._topic_taps:
            self._topic_taps[topic] = []
            self._refresh_taps()
        return self._topic_taps[topic]

    def _refresh_taps(self) -> None:
        for topic, taps in self._topic_taps.items():
            taps[:] = [tap for tap, topics in self.taps if topics is None or topic in topics]

    def set_log_sink(self, sink: Optional[Callable]) -> None:
        """Send every :class:`LogRecord` to ``sink(record)``; None restores stderr printing."""
        self._log_sink = print_log_record if sink is None else sink

    def log(self, record: LogRecord) -> None:
        """Hand one log record to the sink."""
        self._log_sink(record)

    # --- the queue ---------------------------------------------------------------------------

    def schedule(self, time_ns: int, entity, token=None) -> None:
        """Queue ``entity._lockstep_fire(token)`` at ``time_ns`` (after what is queued then)."""
        heapq.heappush(self._queue, (time_ns, next(self._sequence), entity, token))

    def next_event_ns(self) -> Optional[int]:
        """Sim time of the next queued event (ns), or None when the queue is empty."""
        return self._queue[0][0] if self._queue else None

    def set_horizon(self, time_ns: Optional[int]) -> None:
        """Make ``rclpy.spin*`` return once sim time reaches ``time_ns`` (None: no horizon)."""
        self.horizon_ns = time_ns

    def horizon_reached(self) -> bool:
        """Tell whether sim time is at the horizon with nothing left to run before it."""
        return self.horizon_ns is not None and self.now_ns >= self.horizon_ns and \
            (not self._queue or self._queue[0][0] > self.horizon_ns)

    def _fire(self, event) -> None:
        time_ns, _, entity, token = event
        self.now_ns = time_ns
        try:
            entity._lockstep_fire(token)
        except Exception as error:
            self.last_node_error = NodeError(entity._lockstep_node_name, error)
            raise self.last_node_error from error

    def _enter(self, caller: str) -> None:
        if self._running:
            raise LockstepError(
                f'{caller} was called from inside a callback; the lockstep loop runs one '
                'callback at a time and cannot re-enter itself')
        self._running = True

    def run_until(self, time_ns: int) -> None:
        """Run every event due at or before ``time_ns`` (ns), then set the clock to it."""
        if time_ns < self.now_ns:
            raise ValueError(f'run_until({time_ns}): sim time is already {self.now_ns} ns')
        self._enter('run_until()')
        queue = self._queue
        try:
            while queue and queue[0][0] <= time_ns:
                self._fire(heapq.heappop(queue))
        finally:
            self._running = False
        self.now_ns = time_ns

    def spin_once(self, timeout_ns: Optional[int] = None) -> bool:
        """
        Run the next event if due within ``timeout_ns`` and the horizon; True if one ran.

        Sim time advances to the event, or to the timeout / horizon when nothing is due before
        it. With no event, no timeout and no horizon, nothing could ever happen: StalledError.
        """
        limit = self.horizon_ns
        if timeout_ns is not None and timeout_ns >= 0:
            deadline = self.now_ns + timeout_ns
            limit = deadline if limit is None else min(limit, deadline)
        queue = self._queue
        if not queue or (limit is not None and queue[0][0] > limit):
            if limit is None:
                raise StalledError(
                    f'rclpy.spin at t={self.now_ns / NANOSECONDS_PER_SECOND:.9f} s has nothing '
                    'left to do: no timer, no undelivered message and no horizon. Set one with '
                    'lockstep.runtime().set_horizon(t_ns) or run the loop with run_until().')
            self.now_ns = max(self.now_ns, limit)
            return False
        self._enter('rclpy.spin_once()')
        try:
            self._fire(heapq.heappop(queue))
        finally:
            self._running = False
        return True


_current: Optional[Runtime] = None


def current() -> Runtime:
    """Return the installed runtime; LockstepError when :func:`lockstep.install` has not run."""
    if _current is None:
        raise LockstepError('the lockstep runtime is not installed: call '
                            'sim_bridge.lockstep.install() before using its rclpy')
    return _current


def set_current(runtime: Optional[Runtime]) -> None:
    """Make ``runtime`` the installed one (None: uninstalled)."""
    global _current
    _current = runtime
