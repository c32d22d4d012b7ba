"""A student's driver that paces its main() loop with time.sleep: it drives, then turns."""

import time

from geometry_msgs.msg import Twist
import rclpy

PERIOD_S = 0.1


def main():
    rclpy.init()
    node = rclpy.create_node('sleeper')
    pub = node.create_publisher(Twist, 'cmd_vel', 10)
    ticks = 0
    while rclpy.ok():
        twist = Twist()
        if ticks % 40 < 30:
            twist.linear.x = 0.2
        else:
            twist.angular.z = 0.8
        pub.publish(twist)
        ticks += 1
        time.sleep(PERIOD_S)


if __name__ == '__main__':
    main()
