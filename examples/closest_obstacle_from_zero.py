"""
A student's closest_obstacle that measures the bearing from the first beam, not from ahead.

``index * angle_increment`` leaves out ``angle_min``: on the lab robot (-1.57..1.57 rad) every
bearing is 90 deg too far to the left; the distance is right. The grader must fail it.
"""

import math

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ClosestObstacle(Node):

    def __init__(self):
        super().__init__('closest_obstacle')
        self.create_subscription(LaserScan, 'scan', self.scan_callback, 10)

    def scan_callback(self, msg):
        closest = min(msg.ranges)
        index = list(msg.ranges).index(closest)
        angle = index * msg.angle_increment
        self.get_logger().info(
            f'Closest obstacle: {closest:.2f} m at {math.degrees(angle):.1f} degrees')


def main(args=None):
    rclpy.init(args=args)
    node = ClosestObstacle()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
