"""
A naive wall follower: it reads the wall distance once and then drives a fixed arc, open-loop.

From the first scan it takes the side beam's range as the distance to the wall and plans a
circle around the obstacle, as if the obstacle were a disc of ``OBSTACLE_RADIUS_GUESS`` just
beyond that wall; it never looks at the lidar again. A box, a cylinder of another size or an L
is not that disc, so the robot drives into it. The grader must fail it.
"""

from geometry_msgs.msg import Twist
import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan

OBSTACLE_RADIUS_GUESS = 0.5


class NaiveWallFollow(Node):

    def __init__(self):
        super().__init__('wall_follow')
        self.side = self.declare_parameter('side', 'right').value
        self.distance = self.declare_parameter('distance', 0.5).value
        self.speed = self.declare_parameter('speed', 0.3).value
        self.wall_distance = None
        self.publisher = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(LaserScan, 'scan', self.scan_callback, qos_profile_sensor_data)
        self.create_timer(0.1, self.timer_callback)

    def scan_callback(self, msg):
        if self.wall_distance is None:
            side_beam = 0 if self.side == 'right' else -1
            self.wall_distance = msg.ranges[side_beam]
            self.get_logger().info(f'Wall at {self.wall_distance:.2f} m')

    def timer_callback(self):
        if self.wall_distance is None:
            return
        turn_radius = self.wall_distance + OBSTACLE_RADIUS_GUESS
        direction = -1.0 if self.side == 'right' else 1.0
        twist = Twist()
        twist.linear.x = self.speed
        twist.angular.z = direction * self.speed / turn_radius
        self.publisher.publish(twist)


def main(args=None):
    rclpy.init(args=args)
    node = NaiveWallFollow()
    rclpy.spin(node)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
