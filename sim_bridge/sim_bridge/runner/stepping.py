"""
Run rclpy nodes in step with the simulator: every ready callback runs before physics advances.

rclpy has no public "spin until idle", and ``spin_once(timeout_sec=0)`` does not say whether it
ran a callback. The executor's ``wait_for_ready_callbacks(timeout_sec=0)`` does: it hands out
every callback found ready by one wait on the wait set, then raises ``TimeoutException``. A wait
that hands out nothing is the exact "nothing is ready": no message waits in any subscription
(in one process Fast DDS delivers a publish before ``publish`` returns) and no timer is due on
its clock. This is the lockstep Gazebo keeps with its ROS nodes, on the real executor.

Each wait is made with the executor's own guard condition triggered (``Executor.wake()``): a
zero-timeout wait that finds nothing ready otherwise still waits out its timeout (Fast DDS waits
on a condition variable until "now", a timed futex wait: an empty wait took ~170 us here, ~65 us
with the guard ready). With the guard ready it returns at once, having checked every other
entity as before: the same callbacks are handed out, and none is still the exact "nothing is
ready". The guard is the executor's, no callback's.
"""

import traceback
from typing import Collection, Iterable

import rclpy
from rclpy.clock import ClockType
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor, TimeoutException
from rclpy.node import Node
from sim_bridge.runner.targets import describe, StudentCode

#: What it means for a node to leave the runner's executor, and the usual way students do.
LEFT_EXECUTOR = ("it is no longer on the executor that spins it (main's rclpy.spin), as when a "
                 'callback spins an executor of its own: on a robot it would get no more '
                 'callbacks')


class NodeError(Exception):
    """
    An exception raised by a node's code, with the node and where: a callback or constructor.

    ``place`` says what of the node's code ran, e.g. 'its /scan callback'; ``code`` finds the
    node's own line in the traceback; ``what`` replaces 'raised <the error> at <line>'.
    """

    def __init__(self, node_name: str, original: BaseException, place: str = 'its constructor',
                 code: StudentCode = StudentCode(), what: str | None = None):
        self.node_name = node_name
        self.original = original
        self.place = place
        self.code = code
        super().__init__(f"node '{node_name}' {what or 'raised ' + describe(original, code)}")


class NodeEnded(Exception):
    """
    A node shut the ROS context down (``rclpy.shutdown()``): as its process would, the run ends.

    ``place`` is the callback (or constructor), ``where`` the node's line (' at file:line').
    """

    def __init__(self, node_name: str, place: str, where: str):
        self.node_name = node_name
        self.place = place
        super().__init__(f"node '{node_name}' shut ROS down (rclpy.shutdown()) in {place}{where}")


class SteppedExecutor(SingleThreadedExecutor):
    """
    The runner's executor; it notes the node code that takes a node off it or ends ROS.

    So that :func:`spin_until_idle` reports a callback doing either at the node's line. The
    nodes in ``own_nodes`` are the runner's; those of them in ``sink_nodes`` have callbacks
    that make nothing ready: they publish nothing, trigger nothing and create nothing (the
    bridge's command handler, the recorder's writes).
    """

    def __init__(self, context: Context, code: StudentCode = StudentCode()):
        super().__init__(context=context)
        self.code = code
        self.own_nodes: set[Node] = set()
        self.sink_nodes: set[Node] = set()
        #: Nodes taken off this executor, with the node's line that did it (' at file:line').
        self.removed: dict[Node, str] = {}
        self.shutdown_where: str | None = None
        context.on_shutdown(self.note_shutdown)

    def remove_node(self, node: Node) -> None:
        """Stop managing ``node``'s callbacks; note the code that asked."""
        self.removed[node] = self.code.stack_origin(traceback.extract_stack()[:-1])
        super().remove_node(node)

    def note_shutdown(self) -> None:
        """Note the code that shuts the context down (called by the context as it does)."""
        self.shutdown_where = self.code.stack_origin(traceback.extract_stack()[:-1])


def callback_place(entity: object) -> str:
    """Name the callback an executor entity runs: 'its /scan callback', 'its timer callback'."""
    topic = getattr(entity, 'topic_name', None)
    if topic is not None:
        return f'its {topic} callback'
    if hasattr(entity, 'timer_period_ns'):
        return 'its timer callback'
    return f'its {type(entity).__name__.lower()} callback'


def check_ros_state(executor: SteppedExecutor, node: Node, place: str) -> None:
    """
    After ``node``'s code ran in ``place``: NodeEnded if it ended ROS, NodeError if it left.

    A node taken off the executor by ``rclpy.spin_once(node)`` or
    ``rclpy.spin_until_future_complete(node, ...)`` is now on rclpy's global executor: in its
    own process main's ``rclpy.spin(node)`` spins that same executor, and the node stays on
    it, so it is put back here. A node otherwise off the executor is a NodeError.
    """
    if not executor.context.ok():
        raise NodeEnded(node.get_name(), place, executor.shutdown_where or '')
    while executor.removed:
        left, where = executor.removed.popitem()
        if left.executor is rclpy.get_global_executor():
            executor.add_node(left)
        elif left not in executor.get_nodes():
            raise NodeError(left.get_name(), RuntimeError(LEFT_EXECUTOR), place, executor.code,
                            f"was taken off the runner's executor in {place}{where}: "
                            f'{LEFT_EXECUTOR}')


def spin_until_idle(executor: SteppedExecutor) -> int:
    """
    Run every callback that is ready, and those made ready by them, until none is; return count.

    NodeError when a callback raises anything, ``SystemExit`` and ``KeyboardInterrupt``
    included: the node's process would have died there; see :func:`check_ros_state` for a
    callback that ends ROS (NodeEnded) or takes its node off the executor.
    """
    count = 0
    while True:
        ran_before = count
        try:
            while True:
                executor.wake()  # a wait that finds nothing ready returns at once
                task, entity, node = executor.wait_for_ready_callbacks(timeout_sec=0)
                count += 1
                place = callback_place(entity)
                try:
                    task()
                except BaseException as error:  # noqa: B902 sys.exit() in a callback ends it
                    raise NodeError(node.get_name(), error, place, executor.code) from error
                if task.exception() is not None:
                    raise NodeError(node.get_name(), task.exception(), place,
                                    executor.code) from task.exception()
                check_ros_state(executor, node, place)
        except TimeoutException:
            if count == ran_before:
                return count


def spin_after_publishing(executor: SteppedExecutor, topics: Collection[str]) -> int:
    """
    Run the callbacks of what was just published here on ``topics``, until none is ready.

    Called when the executor was idle (nothing ready) before the publish. The runner's own
    nodes (``executor.own_nodes``: plain callbacks, no coroutines) take the messages waiting
    in their subscriptions on ``topics`` first, each handed to its callback in turn, without
    a wait: in one process Fast DDS delivers a publish before ``publish`` returns. A take is
    the executor's own first step (as the boundary's taps take); the wait that would find
    them is the part left out. When only sinks (``executor.sink_nodes``) took, nothing is
    ready now either; otherwise :func:`spin_until_idle` runs whatever else is, and its last
    wait is the exact "nothing is ready". Return the number of callbacks run.
    """
    count, only_sinks = 0, True
    for node in list(executor.own_nodes):
        for subscription in list(node.subscriptions):
            if subscription.topic_name not in topics:
                continue
            place = callback_place(subscription)
            while True:
                with subscription.handle:
                    taken = subscription.handle.take_message(subscription.msg_type,
                                                             subscription.raw)
                if taken is None:
                    break
                count += 1
                only_sinks = only_sinks and node in executor.sink_nodes
                try:
                    subscription.callback(taken[0])
                except BaseException as error:  # noqa: B902 as spin_until_idle
                    raise NodeError(node.get_name(), error, place, executor.code) from error
                check_ros_state(executor, node, place)
    return count if only_sinks else count + spin_until_idle(executor)


def next_timer_ns(nodes: Iterable[Node], after_ns: int | None = None) -> int | None:
    """
    Return the ROS time (ns) at which the first of the nodes' ROS-time timers is next due.

    None when no node has an active timer on ROS time (timers on the system or steady clock
    follow the wall clock, which stepping does not move); with ``after_ns``, timers due at
    or before it (ns) are left out.
    """
    due = None
    for node in nodes:
        for timer in node.timers:
            if timer.clock.clock_type != ClockType.ROS_TIME or timer.is_canceled():
                continue
            remaining = timer.time_until_next_call()
            if remaining is None:
                continue
            at = timer.clock.now().nanoseconds + max(remaining, 0)
            if after_ns is None or at > after_ns:
                due = at if due is None else min(due, at)
    return due
