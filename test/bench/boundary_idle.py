"""A node that does nothing: a run of it costs what the simulator and the recorder cost."""

import rclpy
from rclpy.node import Node


def main():
    rclpy.init()
    rclpy.spin(Node('idle'))


if __name__ == '__main__':
    main()
