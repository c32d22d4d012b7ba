"""
A naive wanderbot, as the lab's own solution writes it: one front beam, turn while it is blocked.

It looks at the single beam straight ahead and turns in place only as long as that beam sees
something closer than the obstacle distance, then drives on: its turns are as small as it takes
for the beam to slip past the obstacle's edge (well under 90 deg), and whatever lies between
beams, or beside the robot's body, is never seen. The grader must fail it.
"""

from geometry_msgs.msg import Twist
import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan


class NaiveWanderbot(Node):

    def __init__(self):
        super().__init__('wanderbot')
        self.speed = 0.5
        self.turn_speed = 1.0
        self.obstacle_distance = 0.7
        self.publisher = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(LaserScan, 'scan', self.scan_callback, qos_profile_sensor_data)

    def scan_callback(self, msg):
        front = msg.ranges[len(msg.ranges) // 2]
        twist = Twist()
        if front < self.obstacle_distance:
            twist.angular.z = self.turn_speed
        else:
            twist.linear.x = self.speed
        self.publisher.publish(twist)


def main(args=None):
    rclpy.init(args=args)
    node = NaiveWanderbot()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
