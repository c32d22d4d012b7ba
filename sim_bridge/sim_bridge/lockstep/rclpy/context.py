"""
rclpy.context for the lockstep runtime: the init/shutdown lifecycle of a Context.

As in Jazzy: ``init`` twice raises, ``shutdown`` of an uninitialised context raises, a second
``shutdown`` raises rclpy's RCLError (a RuntimeError), ``try_shutdown`` never does. ``init``
parses the ROS arguments (``--ros-args ...``) of its argument list, like rcl. Shutting a context
down stops the callbacks of the nodes created with it.
"""

from contextlib import contextmanager
import sys
from typing import Callable, Iterator, List, Optional

from sim_bridge.lockstep import loop, rosargs

__lockstep__ = True


class RCLError(RuntimeError):
    """rclpy's _rclpy_pybind11.RCLError: an rcl call failed."""


class Context:
    """Encapsulates the lifecycle of init and shutdown."""

    def __init__(self) -> None:
        self._initialized = False
        self._shut_down = False
        self._arguments = rosargs.RosArguments()
        self._domain_id = 0
        self._callbacks: List[Callable[[], None]] = []
        self._nodes: list = []

    def init(self, args: Optional[List[str]] = None, *, initialize_logging: bool = True,
             domain_id: Optional[int] = None) -> None:
        """Initialise with the ROS arguments in ``args`` (default: ``sys.argv``)."""
        if domain_id is not None and domain_id < 0:
            raise RuntimeError(f'Domain id ({domain_id}) should not be lower than zero.')
        if self._initialized:
            raise RuntimeError('Context.init() must only be called once')
        self._arguments = rosargs.parse(list(sys.argv if args is None else args))
        loop.current().logger_levels.update(self._arguments.log_levels)
        self._domain_id = 0 if domain_id is None else domain_id
        self._initialized = True

    @property
    def ros_arguments(self) -> rosargs.RosArguments:
        """The parsed ROS arguments given to :meth:`init`."""
        return self._arguments

    @contextmanager
    def lockstep_arguments(self, args: List[str]) -> Iterator[None]:
        """
        Parse ``args`` as this context's ROS arguments for the nodes created inside the block.

        Not rclpy API: the lockstep runner uses it to give each node the command line its own
        process would have had (``ros2 run ... --ros-args ...``), while sharing one context.
        """
        saved = self._arguments
        self._arguments = rosargs.parse(list(args))
        try:
            yield
        finally:
            self._arguments = saved

    def ok(self) -> bool:
        """Check if context hasn't been shut down."""
        return self._initialized and not self._shut_down

    def track_node(self, node) -> None:
        """Remember a node created with this context (its callbacks stop at shutdown)."""
        self._nodes.append(node)

    def untrack_node(self, node) -> None:
        """Forget a destroyed node."""
        if node in self._nodes:
            self._nodes.remove(node)

    def _cleanup(self) -> None:
        self._shut_down = True
        for node in list(self._nodes):
            node._lockstep_stop()
        for callback in self._callbacks:
            callback()
        self._callbacks = []

    def shutdown(self) -> None:
        """Shutdown this context."""
        if not self._initialized:
            raise RuntimeError('Context must be initialized before it can be shutdown')
        if self._shut_down:
            raise RCLError('failed to shutdown: rcl_shutdown already called on the given context')
        self._cleanup()

    def try_shutdown(self) -> None:
        """Shutdown this context, if not already shutdown."""
        if self.ok():
            self._cleanup()

    def on_shutdown(self, callback: Callable[[], None]) -> None:
        """Add a callback to be called on shutdown (at once when already shut down)."""
        if not callable(callback):
            raise TypeError(f'callback should be a callable, got {type(callback)}')
        if self._shut_down:
            callback()
        else:
            self._callbacks.append(callback)

    def get_domain_id(self) -> int:
        """Get domain id of context."""
        if not self._initialized:
            raise RuntimeError('Context must be initialized before it can have a domain id')
        return self._domain_id

    def __enter__(self) -> 'Context':
        if not self._initialized:
            raise RuntimeError(
                'init() must be called on this Context before using it with a context manager')
        return self

    def __exit__(self, exc_type, exc_val, exc_tb) -> None:
        self.try_shutdown()
