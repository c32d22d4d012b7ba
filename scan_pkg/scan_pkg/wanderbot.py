"""Wander: drive straight, and turn in place by more than 90 deg when the way is blocked."""

from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from scan_pkg.behaviors.wander import WanderConfig, Wanderer, yaw_from_quaternion
from scan_pkg.cmd_vel import CmdVelPublisher, declare_config, spin_then_stop
from scan_pkg.report import read_scan
from sensor_msgs.msg import LaserScan


class Wanderbot(Node):
    """
    Subscribe to ``scan`` and ``odom``; publish ``cmd_vel`` at ``control_rate`` (Hz).

    Parameters: the fields of :class:`WanderConfig` (defaults in ``params/wanderbot.yaml``)
    and ``stamped`` (see :class:`CmdVelPublisher`).
    """

    def __init__(self):
        super().__init__('wanderbot')
        config = declare_config(self, WanderConfig)
        self.wanderer = Wanderer(config, on_event=self.get_logger().info)
        self.cmd_vel = CmdVelPublisher(self)
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)
        self.create_subscription(Odometry, 'odom', self.on_odom, qos_profile_sensor_data)
        self.create_timer(1.0 / config.control_rate, self.on_timer)

    def seconds(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_scan(self, msg):
        scan = read_scan(msg, self.get_logger())
        if scan is not None:
            self.wanderer.update_scan(scan, self.seconds())

    def on_odom(self, msg):
        q = msg.pose.pose.orientation
        self.wanderer.update_odom(yaw_from_quaternion(q.x, q.y, q.z, q.w), self.seconds())

    def on_timer(self):
        self.cmd_vel.publish(*self.wanderer.command(self.seconds()))


def main(args=None):
    spin_then_stop(Wanderbot, args)


if __name__ == '__main__':
    main()
