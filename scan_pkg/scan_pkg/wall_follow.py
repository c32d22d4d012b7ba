"""Follow a wall: keep an obstacle on one side at a set distance, and circle it."""

from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from scan_pkg.behaviors.wall_follow import WallFollowConfig, WallFollower
from scan_pkg.cmd_vel import CmdVelPublisher, declare_config, spin_then_stop
from scan_pkg.report import read_scan
from sensor_msgs.msg import LaserScan


class WallFollow(Node):
    """
    Subscribe to ``scan`` and publish one ``cmd_vel`` per scan.

    A command is computed from a scan, so it is sent when one arrives: no staler than the
    scan, and when scans stop, commands stop and the base's command timeout halts the robot.
    Parameters: the fields of :class:`WallFollowConfig` (defaults in
    ``params/wall_follow.yaml``) and ``stamped`` (see :class:`CmdVelPublisher`).
    """

    def __init__(self):
        super().__init__('wall_follow')
        config = declare_config(self, WallFollowConfig)
        self.follower = WallFollower(config, on_event=self.get_logger().info)
        self.cmd_vel = CmdVelPublisher(self)
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)

    def on_scan(self, msg):
        now = self.get_clock().now().nanoseconds * 1e-9
        scan = read_scan(msg, self.get_logger())
        if scan is not None:
            self.follower.update_scan(scan, now)
        self.cmd_vel.publish(*self.follower.command(now))


def main(args=None):
    spin_then_stop(WallFollow, args)


if __name__ == '__main__':
    main()
