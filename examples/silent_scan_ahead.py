"""
A student's scan_ahead that finds the range ahead and never prints it.

It runs to the end without an error. The grader must fail it.
"""

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ScanAhead(Node):

    def __init__(self):
        super().__init__('scan_ahead')
        self.range_ahead = None
        self.create_subscription(LaserScan, 'scan', self.scan_callback, 10)

    def scan_callback(self, msg):
        self.range_ahead = msg.ranges[len(msg.ranges) // 2]


def main(args=None):
    rclpy.init(args=args)
    node = ScanAhead()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
