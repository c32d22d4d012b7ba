"""
A node that drives straight with ``twist.angular.z = 0``: an int in a float64 field.

Python accepts the assignment; Jazzy's rosidl converter aborts on it at publish. The runner must
fail the run with an error naming the field.
"""

from geometry_msgs.msg import Twist
import rclpy
from rclpy.node import Node


class StraightAhead(Node):

    def __init__(self):
        super().__init__('straight_ahead')
        self.publisher = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_timer(0.1, self.timer_callback)

    def timer_callback(self):
        twist = Twist()
        twist.linear.x = 0.2
        twist.angular.z = 0
        self.publisher.publish(twist)


def main(args=None):
    rclpy.init(args=args)
    node = StraightAhead()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
