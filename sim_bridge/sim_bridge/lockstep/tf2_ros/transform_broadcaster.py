"""tf2_ros.transform_broadcaster: publish tf2_msgs/TFMessage on /tf (QoS depth 100)."""

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.rclpy.qos import QoSProfile

__lockstep__ = True


class TransformBroadcaster:
    """Send dynamic transforms on ``/tf``, as tf2_ros does."""

    def __init__(self, node, qos=None) -> None:
        if qos is None:
            qos = QoSProfile(depth=100)
        self._tf_message = message_class('tf2_msgs/msg/TFMessage')
        self.pub_tf = node.create_publisher(self._tf_message, '/tf', qos)

    def sendTransform(self, transform) -> None:  # noqa: N802 (tf2_ros's name)
        """Publish one TransformStamped or a list of them in one TFMessage."""
        if not isinstance(transform, list):
            transform = list(transform) if hasattr(transform, '__iter__') else [transform]
        self.pub_tf.publish(self._tf_message(transforms=transform))
