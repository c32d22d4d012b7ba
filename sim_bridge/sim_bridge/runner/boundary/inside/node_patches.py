"""
What the agent changes in a node's process (boundary.inside.agent), and nothing else.

Each patch is listed in the runner's package docstring (sim_bridge.runner) with what it keeps
as under ``ros2 run``; sim_bridge/test/test_agent_differential.py runs the same node files under
plain rclpy at real time and under the agent, and compares what they print and publish.
Imported only in a node's process, never on the trusted side.
"""

import ctypes
import os
import sys
import threading
import time
import traceback
from typing import Any

#: Seconds to nanoseconds.
NANOSECONDS_PER_SECOND = 10 ** 9
#: What a run says of a MultiThreadedExecutor, which the agent runs in lockstep.
MULTITHREADED_NOTE = ('its MultiThreadedExecutor ran its callbacks one at a time, in lockstep '
                      "with the simulator (their order is the executor's, every time)")
#: rcutils' output handler: (location, severity, logger name, time, format, va_list pointer).
OUTPUT_HANDLER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p,
                                  ctypes.c_int64, ctypes.c_char_p, ctypes.c_void_p)


class CountedStream:
    """A text stream whose writes are counted for the sync frames (see Lockstep.sync)."""

    def __init__(self, stream, lockstep, name: str):
        self._stream = stream
        self._lockstep = lockstep
        self._name = name

    def write(self, text: str) -> int:
        self._lockstep.note_write(self._name)
        return self._stream.write(text)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


class ConsoleCounter:
    """
    Count rcutils' console lines where they are written: its output handler, not the logger.

    rclpy decides everything a line shows (severity, ``once``, ``throttle_duration_sec``,
    ``skip_first``, the caller's file and line, found by walking the stack) before it calls
    rcutils, which calls its output handler only for a line it prints. The handler rclpy set
    is called by a C function of ours that counts the line first (Lockstep.note_write); rclpy
    sets its handler at its first ``rclpy.init``, so :meth:`install` is called as each node is
    made, and puts the count back in front of a handler set anew.
    """

    def __init__(self, lockstep):
        self.lockstep = lockstep
        self.rcutils = ctypes.CDLL('librcutils.so')  # rclpy's, already loaded
        self.rcutils.rcutils_logging_get_output_handler.restype = ctypes.c_void_p
        self.rcutils.rcutils_logging_set_output_handler.argtypes = [ctypes.c_void_p]
        self.stream = ('STDOUT' if os.environ.get('RCUTILS_LOGGING_USE_STDOUT') == '1'
                       else 'STDERR')
        self.counting = OUTPUT_HANDLER(self.count)
        self.address = ctypes.cast(self.counting, ctypes.c_void_p).value
        self.handler = None

    def install(self) -> None:
        """Put the count in front of rcutils' current output handler, unless it is there."""
        current = self.rcutils.rcutils_logging_get_output_handler()
        if current and current != self.address:
            self.handler = OUTPUT_HANDLER(current)
            self.rcutils.rcutils_logging_set_output_handler(self.address)

    def count(self, location, severity, name, timestamp, text_format, arguments) -> None:
        self.lockstep.note_write(self.stream)
        self.handler(location, severity, name, timestamp, text_format, arguments)


class TracedCallback:
    """An executor's task, run between two sync frames; its node noted if it raises."""

    def __init__(self, task, lockstep, node: str, place: str):
        self.task = task
        self.lockstep = lockstep
        self.node = node
        self.place = place

    def __call__(self) -> None:
        lockstep = self.lockstep
        lockstep.sync('')
        lockstep.running = (self.node, self.place)
        try:
            with lockstep.in_step():
                self.task()
        except BaseException:  # noqa: B902 sys.exit(), KeyboardInterrupt: not kept by the task
            lockstep.failed_in = (self.node, self.place)
            raise
        finally:
            lockstep.running = None
            if self.task.exception() is not None:
                lockstep.failed_in = (self.node, self.place)
            lockstep.sync(self.node)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.task, name)


def patch_waits(lockstep) -> None:
    """Patch the executors' wait, MultiThreadedExecutor, ``Rate.sleep`` and ``time.sleep``."""
    from rclpy import executors, timer
    from sim_bridge.runner.stepping import callback_place, next_timer_ns
    original_wait = executors.Executor.wait_for_ready_callbacks

    def stepped_wait(executor, timeout_sec=None, nodes=None, condition=lambda: False):
        if threading.current_thread() is not threading.main_thread():
            return lockstep.thread_wait(original_wait, executor, timeout_sec, nodes, condition)
        timeout = getattr(timeout_sec, 'timeout', timeout_sec)
        deadline = (None if timeout is None or timeout < 0
                    else lockstep.now_ns + round(timeout * NANOSECONDS_PER_SECOND))
        while True:
            executor.wake()  # its guard ready: a wait with nothing else ready returns at once
            try:
                task, entity, node = original_wait(executor, 0, nodes, condition)
            except executors.TimeoutException:
                if getattr(executor, '_lab_ran', False):
                    executor._lab_ran = False  # a callback ran: more may be ready now
                    continue
                if deadline is not None and lockstep.now_ns >= deadline:
                    raise
                wake = next_timer_ns(nodes or executor.get_nodes())
                if deadline is not None:
                    wake = min(deadline if wake is None else wake,
                               max(deadline, lockstep.now_ns + 1))
                lockstep.exchange(wake, executor.context)
                continue
            executor._lab_ran = True
            return (TracedCallback(task, lockstep, node.get_name(), callback_place(entity)),
                    entity, node)

    def stepped_sleep(seconds: float) -> None:
        if seconds < 0:
            raise ValueError('sleep length must be non-negative')
        lockstep.sleep_until(lockstep.now_ns + max(1, round(seconds * NANOSECONDS_PER_SECOND)))

    def rate_sleep(rate) -> None:
        rate._presleep()
        try:
            stepped = False
            while not rate._event.is_set():  # set by its timer's callback, as in rclpy
                remaining = rate._timer.time_until_next_call()
                if remaining is not None and remaining > 0:
                    lockstep.sleep_until(lockstep.now_ns + remaining)
                    stepped = True
                    continue
                # Its tick is due and nothing ran its timer (no executor spins its node on
                # another thread): rclpy would never wake; it wakes at its timer's ticks.
                if not stepped:
                    late_ns = -(remaining or 0) % rate._timer.timer_period_ns
                    lockstep.sleep_until(lockstep.now_ns + rate._timer.timer_period_ns - late_ns)
                return
        finally:
            rate._postsleep()

    class LockstepMultiThreadedExecutor(executors.SingleThreadedExecutor):
        """MultiThreadedExecutor in lockstep: its callbacks run one at a time, in order."""

        def __init__(self, num_threads=None, *, context=None):
            super().__init__(context=context)
            if MULTITHREADED_NOTE not in lockstep.notes:
                lockstep.notes.append(MULTITHREADED_NOTE)

    executors.Executor.wait_for_ready_callbacks = stepped_wait
    executors.MultiThreadedExecutor = LockstepMultiThreadedExecutor
    timer.Rate.sleep = rate_sleep
    time.sleep = stepped_sleep


def patch_clocks(lockstep) -> None:
    """
    Make the wall clocks a node reads follow its simulated time (Lockstep.clock_ns).

    ``time.time``, ``time.monotonic`` (and their ``_ns``), and rclpy's system and steady
    clocks (``Clock()``, the default clock of a logger's ``throttle_duration_sec``) read
    their real value at the start, plus the node's clock since. ``time.perf_counter``,
    ``time.process_time`` and ``datetime`` keep the wall: they measure the code's own work.
    """
    from rclpy.clock import Clock, ClockType
    from rclpy.time import Time
    origins = {ClockType.SYSTEM_TIME: time.time_ns(), ClockType.STEADY_TIME: time.monotonic_ns()}
    original_now = Clock.now

    def system_ns() -> int:
        return origins[ClockType.SYSTEM_TIME] + lockstep.clock_ns()

    def steady_ns() -> int:
        return origins[ClockType.STEADY_TIME] + lockstep.clock_ns()

    def node_clock_now(clock) -> Time:
        origin = origins.get(clock.clock_type)
        if origin is None:  # ROS time: the simulator's /clock
            return original_now(clock)
        return Time(nanoseconds=origin + lockstep.clock_ns(), clock_type=clock.clock_type)

    time.time_ns, time.monotonic_ns = system_ns, steady_ns
    time.time = lambda: system_ns() / NANOSECONDS_PER_SECOND
    time.monotonic = lambda: steady_ns() / NANOSECONDS_PER_SECOND
    Clock.now = node_clock_now


def install(lockstep) -> None:
    """Make every patch of sim_bridge.runner's list, each going through ``lockstep``."""
    import rclpy
    from rclpy.node import Node
    original_init = Node.__init__
    console = ConsoleCounter(lockstep)

    def track(node, *args, **kwargs) -> None:
        original_init(node, *args, **kwargs)
        console.install()  # rclpy's first init sets rcutils' handler
        if not getattr(node, '_lab_proxy', False):
            lockstep.nodes.append(node)

    Node.__init__ = track
    lockstep.console = console  # the C function is called as long as it is kept
    sys.stdout = CountedStream(sys.stdout, lockstep, 'STDOUT')
    sys.stderr = CountedStream(sys.stderr, lockstep, 'STDERR')
    patch_waits(lockstep)
    patch_clocks(lockstep)

    def note_shutdown() -> None:
        lockstep.shutdown_where = lockstep.code.stack_origin(traceback.extract_stack()[:-1])
        lockstep.shutdown_in = lockstep.running
        lockstep.shutdown_seen()
    lockstep.note_shutdown = note_shutdown  # the context keeps a weak reference to methods
    rclpy.utilities.get_default_context().on_shutdown(note_shutdown)
