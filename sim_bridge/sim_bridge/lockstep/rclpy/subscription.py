"""
rclpy.subscription for the lockstep runtime: a message queue feeding one callback.

Each received message waits in a KEEP_LAST queue of the subscription's QoS depth (the oldest
undelivered message is dropped when it is full; KEEP_ALL never drops) and is delivered by its
own event at the sim time it was published, after the publishing callback returned.
"""

from collections import deque
from typing import Callable

from sim_bridge.lockstep.rclpy.qos import queue_depth

__lockstep__ = True


class Subscription:
    """A subscription to a topic."""

    def __init__(self, msg_type, topic: str, callback: Callable, callback_group, qos_profile,
                 *, lockstep_node):
        self.msg_type = msg_type
        self.topic = topic
        self.callback = callback
        self.callback_group = callback_group
        self.qos_profile = qos_profile
        self._runtime = lockstep_node._runtime
        self._lockstep_node_name = lockstep_node.get_name()
        self._lockstep_logger = lockstep_node.get_logger()
        self._inbox = deque(maxlen=queue_depth(qos_profile))
        self._active = True

    @property
    def topic_name(self) -> str:
        """The fully qualified (expanded, remapped) topic name."""
        return self.topic

    def _lockstep_receive(self, msg) -> None:
        if self._active:
            self._inbox.append(msg)
            self._runtime.schedule(self._runtime.now_ns, self)

    def _lockstep_fire(self, _token) -> None:
        if self._active and self._inbox:
            self.callback(self._inbox.popleft())

    def _lockstep_stop(self) -> None:
        self._active = False
        self._inbox.clear()

    def destroy(self) -> None:
        """Stop receiving; undelivered messages are dropped."""
        self._lockstep_stop()
        self._runtime.graph.remove(self)
