"""A careful student's wanderbot: drives, stops within 0.7 m of what is ahead, turns, resumes."""

import math
import random

from geometry_msgs.msg import Twist
import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

FORWARD = 'forward'
STOPPED = 'stopped'
TURNING = 'turning'


class Wanderbot(Node):

    def __init__(self):
        super().__init__('wanderbot')
        self.declare_parameter('seed', 0)
        self.random = random.Random(self.get_parameter('seed').value)
        self.publisher = self.create_publisher(Twist, 'cmd_vel', 10)
        self.subscription = self.create_subscription(
            LaserScan, 'scan', self.listener_callback, 10)
        self.state = FORWARD
        self.turn_left = True
        self.turn_until = 0.0

    def ahead(self, msg, half_width):
        """Return the closest range (m) within half_width (rad) either side of straight ahead."""
        closest = 10.0
        for index, value in enumerate(msg.ranges):
            angle = msg.angle_min + index * msg.angle_increment
            angle = math.atan2(math.sin(angle), math.cos(angle))
            if abs(angle) <= half_width and math.isfinite(value) and value > msg.range_min:
                closest = min(closest, value)
        return closest

    def listener_callback(self, msg):
        now = self.get_clock().now().nanoseconds / 1e9
        ahead = self.ahead(msg, math.radians(30))
        twist = Twist()
        if self.state == FORWARD and ahead < 0.7:
            self.state = STOPPED  # stop for this scan, then turn
        elif self.state == STOPPED:
            self.state = TURNING
            self.turn_left = self.random.random() < 0.5
            turn = math.radians(self.random.uniform(110, 170))
            self.turn_until = now + turn / 1.0
        elif self.state == TURNING:
            if now < self.turn_until or self.ahead(msg, math.radians(40)) < 1.0:
                twist.angular.z = 1.0 if self.turn_left else -1.0
            else:
                self.state = FORWARD
        if self.state == FORWARD:
            twist.linear.x = 0.25
        self.get_logger().info(f'{self.state}: {ahead:.2f} m ahead')
        self.publisher.publish(twist)


def main(args=None):
    rclpy.init(args=args)
    wanderbot = Wanderbot()
    rclpy.spin(wanderbot)
    wanderbot.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
