"""
rclpy.publisher for the lockstep runtime: validate, copy and deliver each message.

``publish`` checks the whole message the way Jazzy's C converter does (an int or
numpy.float32 in a float field, a float in an int field, a wrong sub-message ... would abort the
process there) and raises :class:`~sim_bridge.lockstep.errors.MessageTypeError` naming the node,
topic, field path and expected type. A valid message is copied once as it would come out of
serialisation; taps see that copy, and each matched subscription gets its own (the first
subscription the one the taps saw, as they keep nothing).
"""

from sim_bridge.lockstep.errors import MessageTypeError
from sim_bridge.lockstep.messages import msgtype_of
from sim_bridge.lockstep.rclpy.context import RCLError
from sim_bridge.lockstep.rclpy.exceptions import InvalidHandle

__lockstep__ = True


class Publisher:
    """A publisher on a topic."""

    def __init__(self, msg_type, topic: str, qos_profile, *, lockstep_node):
        self.msg_type = msg_type
        self.topic = topic
        self.qos_profile = qos_profile
        self._runtime = lockstep_node._runtime
        self._lockstep_node_name = lockstep_node.get_name()
        self._lockstep_logger = lockstep_node.get_logger()
        self._lockstep_check = msg_type._lockstep_check
        self._lockstep_copy = msg_type._lockstep_copy
        self._lockstep_recipients: list = []
        self._lockstep_history = None
        self._taps = self._runtime.taps_on(topic)
        self._unusable = None   # (exception class, text) publish raises once unusable

    @property
    def topic_name(self) -> str:
        """The fully qualified (expanded, remapped) topic name."""
        return self.topic

    def publish(self, msg) -> None:
        """Send ``msg`` to every matched subscription (delivered after the current callback)."""
        if self._unusable is not None:
            error, text = self._unusable
            raise error(text)
        if msg.__class__ is not self.msg_type:
            raise MessageTypeError(self._lockstep_node_name, self.topic, None,
                                   msgtype_of(self.msg_type), msg)
        problem = self._lockstep_check(msg)
        if problem is not None:
            raise MessageTypeError(self._lockstep_node_name, self.topic, *problem)
        runtime = self._runtime
        taps = self._taps
        history = self._lockstep_history
        recipients = self._lockstep_recipients
        if not recipients and history is None:
            # Nothing keeps this message, and taps must not either: no copy to make.
            for tap in taps:
                tap(self.topic, msg, runtime.now_ns)
            return
        copy = self._lockstep_copy
        wire = copy(msg)
        for tap in taps:
            tap(self.topic, wire, runtime.now_ns)
        if history is not None:
            history.append(wire)
            wire = copy(wire)
        # Taps have read the copy and kept nothing: the first subscription can have it.
        for index, subscription in enumerate(recipients):
            subscription._lockstep_receive(copy(wire) if index else wire)

    def get_subscription_count(self) -> int:
        """Return the number of subscriptions this publisher reaches."""
        return len(self._lockstep_recipients)

    def assert_liveliness(self) -> None:
        """Nothing to assert in one process."""

    def wait_for_all_acked(self, timeout=None) -> bool:
        """Delivery is in-process: every message is acknowledged."""
        return True

    def _lockstep_stop(self) -> None:
        self._unusable = RCLError, "failed to publish: publisher's context is invalid"

    def destroy(self) -> None:
        """Destroy the publisher."""
        self._unusable = InvalidHandle, 'cannot use Destroyable because destruction was requested'
        self._runtime.graph.remove(self)
