"""
Run rclpy nodes in step with the simulator: every ready callback runs before physics advances.

rclpy has no public "spin until idle", and ``spin_once(timeout_sec=0)`` does not say whether it
ran a callback. The executor's ``wait_for_ready_callbacks(timeout_sec=0)`` does: it hands out
every callback found ready by one wait on the wait set, then raises ``TimeoutException``. A wait
that hands out nothing is the exact "nothing is ready": no message waits in any subscription
(in one process Fast DDS delivers a publish before ``publish`` returns) and no timer is due on
its clock. This is the lockstep Gazebo keeps with its ROS nodes, on the real executor.
"""

import os
import traceback
from typing import Iterable

from rclpy.clock import ClockType
from rclpy.executors import Executor, TimeoutException
from rclpy.node import Node

#: Frames in here are the runner's, never a node's own code.
PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep


class NodeError(Exception):
    """
    An exception raised by a node's code, with the node and where: a callback or constructor.

    ``place`` says what of the node's code ran, e.g. 'its /scan callback'.
    """

    def __init__(self, node_name: str, original: BaseException, place: str = 'its constructor'):
        self.node_name = node_name
        self.original = original
        self.place = place
        super().__init__(f"node '{node_name}' raised {describe(original)}")


def callback_place(entity: object) -> str:
    """Name the callback an executor entity runs: 'its /scan callback', 'its timer callback'."""
    topic = getattr(entity, 'topic_name', None)
    if topic is not None:
        return f'its {topic} callback'
    if hasattr(entity, 'timer_period_ns'):
        return 'its timer callback'
    return f'its {type(entity).__name__.lower()} callback'


def describe(error: BaseException) -> str:
    """Say what ``error`` was and where the node's own code raised it (see :func:`origin`)."""
    text = f'{type(error).__name__}: {error}' if str(error) else type(error).__name__
    if isinstance(error, SystemExit):
        text = f'SystemExit (sys.exit({error.code!r}))'
    return text + origin(error)


def origin(error: BaseException) -> str:
    """
    Return ' at file:line: code' of where ``error`` was raised, or '' when unknown.

    The place is the innermost frame outside generated message code, rclpy and this package,
    so an int assigned to a float field points at the assignment, not at rosidl's setter, and
    a watchdog's stop at the node's line it interrupted, not at the signal handler.
    """
    frames = [frame for frame in traceback.extract_tb(error.__traceback__)
              if '/msg/_' not in frame.filename and '/rclpy/' not in frame.filename
              and not frame.filename.startswith(PACKAGE_DIR)]
    if not frames:
        return ''
    frame = frames[-1]
    return f' at {frame.filename}:{frame.lineno}' + (f': {frame.line}' if frame.line else '')


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
                task, entity, node = executor.wait_for_ready_callbacks(timeout_sec=0)
                count += 1
                try:
                    task()
                except BaseException as error:  # noqa: B902 sys.exit() in a callback ends it
                    raise NodeError(node.get_name(), error, callback_place(entity)) from error
                if task.exception() is not None:
                    raise NodeError(node.get_name(), task.exception(),
                                    callback_place(entity)) from task.exception()
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
