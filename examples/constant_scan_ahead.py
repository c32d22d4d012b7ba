"""
A student's scan_ahead that never reads the scan: it logs the placeholder it started with.

The line looks right (``Range ahead: 42``) on every scan, so a grader that only checks that the
node runs passes it. The grader must fail it.
"""

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ScanAhead(Node):

    def __init__(self):
        super().__init__('scan_ahead')
        self.range_ahead = 42  # TODO read it from the scan
        self.subscription = self.create_subscription(LaserScan, 'scan', self.scan_callback, 10)

    def scan_callback(self, msg):
        self.get_logger().info(f'Range ahead: {self.range_ahead}')


def main(args=None):
    rclpy.init(args=args)
    node = ScanAhead()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
