"""
rclpy.utilities for the lockstep runtime: the default context and argument helpers.

The default context follows Jazzy: ``shutdown()`` detaches it, so a second ``shutdown()`` meets
a fresh, uninitialised context and raises RuntimeError, and ``init()`` may be called again.
"""

import sys
from typing import List, Optional

from sim_bridge.lockstep import loop, rosargs
from sim_bridge.lockstep.rclpy.context import Context

__lockstep__ = True


def get_default_context(*, shutting_down: bool = False) -> Context:
    """Return the global default context (of the installed runtime)."""
    current = loop.current()
    if current.default_context is None:
        current.default_context = Context()
    context = current.default_context
    if shutting_down:
        current.default_context = None
    return context


def remove_ros_args(args: Optional[List[str]] = None) -> List[str]:
    """Return ``args`` (default ``sys.argv``) without its ``--ros-args`` sections."""
    return rosargs.remove_ros_args(list(sys.argv if args is None else args))


def ok(*, context: Optional[Context] = None) -> bool:
    """Return True if the given context is initialized and not shut down."""
    return (get_default_context() if context is None else context).ok()


def shutdown(*, context: Optional[Context] = None) -> None:
    """Shutdown the given context (default: the global one, which is then replaced)."""
    (get_default_context(shutting_down=True) if context is None else context).shutdown()


def try_shutdown(*, context: Optional[Context] = None) -> None:
    """Shutdown the given context if it is not already shut down."""
    if context is not None:
        context.try_shutdown()
        return
    current = loop.current()
    default = get_default_context()
    default.try_shutdown()
    if not default.ok():
        current.default_context = None
