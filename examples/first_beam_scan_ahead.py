"""
A student's scan_ahead that takes the first range as the one ahead.

On a TurtleBot3 (0..2pi scan) ``ranges[0]`` is straight ahead; on the lab robot (-1.57..1.57
rad) it is the beam to the right. The grader must fail it.
"""

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ScanAhead(Node):

    def __init__(self):
        super().__init__('scan_ahead')
        self.create_subscription(LaserScan, 'scan', self.scan_callback, 10)

    def scan_callback(self, msg):
        range_ahead = msg.ranges[0]
        print('Range ahead:', range_ahead)


def main(args=None):
    rclpy.init(args=args)
    node = ScanAhead()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
