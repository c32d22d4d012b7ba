"""
rclpy for the lockstep runtime: the subset of Jazzy's rclpy the lab's nodes use.

Installed as ``rclpy`` in ``sys.modules`` by :func:`sim_bridge.lockstep.install` (never as a
top-level package on disk). Same names and semantics as Jazzy: ``init(*, args=None, ...)``
returns None, ``shutdown()`` twice raises, ``spin``/``spin_once`` run the runtime's
deterministic loop (until shutdown or the runtime's horizon).
"""

from typing import List, Optional

from sim_bridge.lockstep import loop
from sim_bridge.lockstep.rclpy.executors import Executor, SingleThreadedExecutor
from sim_bridge.lockstep.rclpy.node import Node
from sim_bridge.lockstep.rclpy.parameter import Parameter
from sim_bridge.lockstep.rclpy.signals import install_signal_handlers, SignalHandlerOptions
from sim_bridge.lockstep.rclpy.utilities import get_default_context, ok, shutdown, try_shutdown

__lockstep__ = True
__all__ = ['Node', 'Parameter', 'create_node', 'get_default_context', 'get_global_executor',
           'init', 'ok', 'shutdown', 'spin', 'spin_once', 'spin_until_future_complete',
           'try_shutdown']


def init(*, args: Optional[List[str]] = None, context=None, domain_id: Optional[int] = None,
         signal_handler_options=None) -> None:
    """Initialise ROS communications for ``context`` (default: the global context)."""
    if signal_handler_options is None:
        signal_handler_options = SignalHandlerOptions.ALL if context is None \
            else SignalHandlerOptions.NO
    install_signal_handlers(signal_handler_options)
    (get_default_context() if context is None else context).init(args, domain_id=domain_id)


def create_node(node_name: str, **kwargs) -> Node:
    """Create a Node (same keyword arguments as :class:`Node`)."""
    return Node(node_name, **kwargs)


def get_global_executor() -> Executor:
    """Return the executor spin() uses when none is given."""
    current = loop.current()
    if current.global_executor is None or \
            current.global_executor.context is not get_default_context():
        current.global_executor = SingleThreadedExecutor()
    return current.global_executor


def spin(node: Node, executor: Optional[Executor] = None) -> None:
    """Run callbacks until the context is shut down or the runtime's horizon is reached."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin()
    finally:
        executor.remove_node(node)


def spin_once(node: Node, *, executor: Optional[Executor] = None,
              timeout_sec: Optional[float] = None) -> None:
    """Run one callback due within ``timeout_sec`` of sim time (None: the next one)."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        executor.remove_node(node)


def spin_until_future_complete(node: Node, future, executor: Optional[Executor] = None,
                               timeout_sec: Optional[float] = None) -> None:
    """Not supported (no services or actions in lockstep)."""
    (get_global_executor() if executor is None else executor).spin_until_future_complete(
        future, timeout_sec)
