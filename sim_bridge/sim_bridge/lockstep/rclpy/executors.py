"""
rclpy.executors for the lockstep runtime: executors that drive the one event loop.

Every executor runs the same deterministic loop, one callback at a time, for all nodes of the
runtime (in lockstep mode the other "processes", such as the simulator bridge, live in the same
loop). ``spin`` returns when the context is shut down or sim time reaches the runtime's horizon.
``spin_once`` called again once the horizon is reached raises ExternalShutdownException, as
Jazzy does when the context is shut down from outside, so ``while rclpy.ok(): spin_once()``
loops end. An exception from a callback leaves ``spin``/``spin_once`` as it would in rclpy (the
original exception), with a note naming the node and the sim time.
"""

from typing import Optional

from sim_bridge.lockstep import loop
from sim_bridge.lockstep.errors import LockstepError, NodeError
from sim_bridge.lockstep.rclpy.constants import S_TO_NS
from sim_bridge.lockstep.rclpy.utilities import get_default_context

__lockstep__ = True


class ExternalShutdownException(Exception):
    """Context has been shutdown."""


class ShutdownException(Exception):
    """Signal that executor was shut down."""


class TimeoutException(Exception):
    """Signal that a timeout occurred."""


def _reraise_original(error: NodeError, time_ns: int):
    original = error.original
    original.add_note(f"(lockstep: raised in a callback of node '{error.node_name}' at "
                      f'sim time {time_ns / S_TO_NS:.9f} s)')
    return original


class Executor:
    """Runs callbacks of the runtime's nodes in sim-time order."""

    def __init__(self, *, context=None) -> None:
        self._context = get_default_context() if context is None else context
        self._nodes: list = []
        self._is_shutdown = False

    @property
    def context(self):
        """The context whose ok() the executor checks."""
        return self._context

    def add_node(self, node) -> bool:
        """Add a node; False when it was already added."""
        if node in self._nodes:
            return False
        self._nodes.append(node)
        node._executor = self
        return True

    def remove_node(self, node) -> None:
        """Remove a node."""
        if node in self._nodes:
            self._nodes.remove(node)
            node._executor = None

    def get_nodes(self) -> list:
        """Nodes added to this executor."""
        return list(self._nodes)

    def wake(self) -> None:
        """Nothing to wake: the loop never waits on the wall clock."""

    def shutdown(self, timeout_sec: Optional[float] = None) -> bool:
        """Stop spinning; returns True."""
        self._is_shutdown = True
        return True

    def spin(self) -> None:
        """Run callbacks until the context is shut down or the horizon is reached."""
        current = loop.current()
        try:
            while self._context.ok() and not self._is_shutdown and current.spin_once():
                pass
        except NodeError as error:
            raise _reraise_original(error, current.now_ns) from None

    def spin_once(self, timeout_sec: Optional[float] = None) -> None:
        """Run the next callback due within ``timeout_sec`` of sim time (None: whenever)."""
        if self._is_shutdown or not self._context.ok():
            raise ExternalShutdownException()
        current = loop.current()
        if current.horizon_reached():
            raise ExternalShutdownException(
                f'lockstep horizon reached at sim time {current.now_ns / S_TO_NS:.9f} s')
        timeout_ns = None if timeout_sec is None or timeout_sec < 0 \
            else int(timeout_sec * S_TO_NS)
        try:
            current.spin_once(timeout_ns)
        except NodeError as error:
            raise _reraise_original(error, current.now_ns) from None

    def spin_until_future_complete(self, future, timeout_sec: Optional[float] = None) -> None:
        """Not supported: futures come from services and actions, which lockstep lacks."""
        raise LockstepError('spin_until_future_complete() is not supported by the lockstep '
                            'runtime (it has no services or actions)')


class SingleThreadedExecutor(Executor):
    """Runs callbacks in the thread that calls spin."""


class MultiThreadedExecutor(Executor):
    """Same deterministic single loop: lockstep runs callbacks one at a time."""

    def __init__(self, num_threads: Optional[int] = None, *, context=None) -> None:
        super().__init__(context=context)
