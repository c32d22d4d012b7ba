"""Velocity commands for the driving nodes: Twist, or TwistStamped when asked for."""

from geometry_msgs.msg import Twist, TwistStamped
from rclpy.node import Node


class CmdVelPublisher:
    """
    Publish ``(linear m/s, angular rad/s)`` commands on ``cmd_vel`` for ``node``.

    Declares the node's ``stamped`` parameter (default false): geometry_msgs/Twist, as the
    simulator bridge and teleop_twist_keyboard use by default, or geometry_msgs/TwistStamped,
    as Jazzy's diff_drive_controller expects. Values are always sent as Python floats.
    """

    def __init__(self, node: Node, topic: str = 'cmd_vel'):
        self._node = node
        self.stamped = node.declare_parameter('stamped', False).value
        self._publisher = node.create_publisher(
            TwistStamped if self.stamped else Twist, topic, 10)

    def publish(self, linear: float, angular: float) -> None:
        """Send forward speed ``linear`` (m/s) and turn rate ``angular`` (rad/s, CCW)."""
        twist = Twist()
        twist.linear.x = float(linear)
        twist.angular.z = float(angular)
        if self.stamped:
            message = TwistStamped(twist=twist)
            message.header.stamp = self._node.get_clock().now().to_msg()
            self._publisher.publish(message)
        else:
            self._publisher.publish(twist)

    def stop(self) -> None:
        """Send a zero command."""
        self.publish(0.0, 0.0)
