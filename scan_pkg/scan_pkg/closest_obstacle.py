"""Log the distance and bearing of the nearest obstacle on every scan."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from scan_pkg.report import closest_line, read_scan
from sensor_msgs.msg import LaserScan


class ClosestObstacle(Node):
    """Subscribe to ``scan`` and log the nearest valid return (m) and its bearing (deg)."""

    def __init__(self):
        super().__init__('closest_obstacle')
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)

    def on_scan(self, msg):
        scan = read_scan(msg, self.get_logger())
        if scan is not None:
            self.get_logger().info(closest_line(scan))


def main(args=None):
    rclpy.init(args=args)
    node = ClosestObstacle()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
