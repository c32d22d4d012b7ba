"""
tf2_ros.static_transform_broadcaster: latched transforms on /tf_static.

The publisher is transient local with depth 1, and the broadcaster republishes every static
transform it was ever given (one per child frame, the latest winning), so a late subscriber
receives them all in one TFMessage.
"""

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile

__lockstep__ = True


class StaticTransformBroadcaster:
    """Send static transforms on ``/tf_static``, as tf2_ros does."""

    def __init__(self, node, qos=None) -> None:
        if qos is None:
            qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             history=HistoryPolicy.KEEP_LAST)
        message = message_class('tf2_msgs/msg/TFMessage')
        self.pub_tf = node.create_publisher(message, '/tf_static', qos)
        self.net_message = message()
        self._child_frame_ids: dict = {}

    def sendTransform(self, transform) -> None:  # noqa: N802 (tf2_ros's name)
        """Add (or replace, by child frame) transforms and publish the whole set."""
        if not isinstance(transform, list):
            transform = list(transform) if hasattr(transform, '__iter__') else [transform]
        for incoming in transform:
            self._child_frame_ids[incoming.child_frame_id] = incoming
        self.net_message.transforms = list(self._child_frame_ids.values())
        self.pub_tf.publish(self.net_message)
