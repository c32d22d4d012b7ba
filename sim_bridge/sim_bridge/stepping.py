"""
Run rclpy nodes in step with the simulator: every ready callback runs before physics advances.

rclpy has no public "spin until idle", and ``spin_once(timeout_sec=0)`` does not say whether it
ran a callback. The executor's ``wait_for_ready_callbacks(timeout_sec=0)`` does: it hands out
every callback found ready by one wait on the wait set, then raises ``TimeoutException``. A wait
that hands out nothing is the exact "nothing is ready": no message waits in any subscription
(in one process Fast DDS delivers a publish before ``publish`` returns) and no timer is due on
its clock. This is the lockstep Gazebo keeps with its ROS nodes, on the real executor.
"""

import traceback
from typing import Iterable

from rclpy.clock import ClockType
from rclpy.executors import Executor, TimeoutException
from rclpy.node import Node


class NodeError(Exception):
    """An exception raised by a node's code (a callback or its constructor), with the node."""

    def __init__(self, node_name: str, original: BaseException):
        self.node_name = node_name
        self.original = original
        super().__init__(f"node '{node_name}' raised {describe(original)}")


def describe(error: BaseException) -> str:
    """
    Say what ``error`` was and where the node's own code raised it.

    The place is the innermost frame outside generated message code, so an int assigned to a
    float field points at the assignment, not at rosidl's setter.
    """
    text = f'{type(error).__name__}: {error}' if str(error) else type(error).__name__
    if isinstance(error, SystemExit):
        text = f'SystemExit (sys.exit({error.code!r}))'
    frames = [frame for frame in traceback.extract_tb(error.__traceback__)
              if '/msg/_' not in frame.filename and '/rclpy/' not in frame.filename]
    if frames:
        frame = frames[-1]
        text += f' at {frame.filename}:{frame.lineno}'
        if frame.line:
            text += f': {frame.line}'
    return text


def spin_until_idle(executor: Executor) -> int:
    """
    Run every callback that is ready, and those made ready by them, until none is; return count.

    NodeError when a callback raises anything, ``SystemExit`` and ``KeyboardInterrupt``
    included: the node's process would have died there.
    """
    count = 0
    while True:
        ran_before = count
        try:
            while True:
                task, _, node = executor.wait_for_ready_callbacks(timeout_sec=0)
                count += 1
                try:
                    task()
                except BaseException as error:  # noqa: B902 sys.exit() in a callback ends it
                    raise NodeError(node.get_name(), error) from error
                if task.exception() is not None:
                    raise NodeError(node.get_name(), task.exception()) from task.exception()
        except TimeoutException:
            if count == ran_before:
                return count


def next_timer_ns(nodes: Iterable[Node]) -> int | None:
    """
    Return the ROS time (ns) at which the first of the nodes' ROS-time timers is next due.

    None when no node has an active timer on ROS time (timers on the system or steady clock
    follow the wall clock, which stepping does not move).
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
            due = at if due is None else min(due, at)
    return due
