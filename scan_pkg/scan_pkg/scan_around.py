"""Log the nearest range in each of five regions around the robot on every scan."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from scan_pkg.report import positive_parameter, read_scan, regions_line
from sensor_msgs.msg import LaserScan


class ScanAround(Node):
    """Subscribe to ``scan`` and log the minima of right … left, capped at ``max_range`` (m)."""

    def __init__(self):
        super().__init__('scan_around')
        self.max_range = positive_parameter(
            'max_range', self.declare_parameter('max_range', 10.0).value)
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)

    def on_scan(self, msg):
        scan = read_scan(msg, self.get_logger())
        if scan is not None:
            self.get_logger().info(regions_line(scan.regions(self.max_range)))


def main(args=None):
    rclpy.init(args=args)
    node = ScanAround()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
