"""Log the range straight ahead of the robot on every scan."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from scan_pkg.report import positive_parameter, range_ahead_line, read_scan
from sensor_msgs.msg import LaserScan


class ScanAhead(Node):
    """Subscribe to ``scan`` and log the front-most range, capped at ``max_range`` (m)."""

    def __init__(self):
        super().__init__('scan_ahead')
        self.max_range = positive_parameter(
            'max_range', self.declare_parameter('max_range', 10.0).value)
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)

    def on_scan(self, msg):
        scan = read_scan(msg, self.get_logger())
        if scan is not None:
            self.get_logger().info(range_ahead_line(scan, self.max_range))


def main(args=None):
    rclpy.init(args=args)
    node = ScanAhead()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
