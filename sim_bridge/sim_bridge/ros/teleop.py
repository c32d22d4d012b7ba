"""
Drive by keyboard, as ROS 2 Jazzy's teleop_twist_keyboard does (it is not on PyPI).

Publishes ``cmd_vel`` (geometry_msgs/Twist; TwistStamped with ``-p stamped:=true``, stamped
with ``frame_id``) on every key, and a zero command when it quits. Keys: see
:mod:`sim_bridge.ros.teleop_keys`. Reads the keys from the terminal in raw mode.
"""

import os
import select
import signal
import sys
import termios
import tty

from geometry_msgs.msg import Twist, TwistStamped
import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sim_bridge.ros.teleop_keys import BANNER, CTRL_C, TeleopKeys


class TeleopKeyboard(Node):

    def __init__(self):
        super().__init__('teleop_twist_keyboard')
        self.stamped = self.declare_parameter('stamped', False).value
        self.frame_id = self.declare_parameter('frame_id', '').value
        if self.frame_id and not self.stamped:
            raise ValueError("'frame_id' can only be set when 'stamped' is True")
        self.publisher = self.create_publisher(TwistStamped if self.stamped else Twist,
                                               'cmd_vel', 10)

    def publish(self, x: float, y: float, z: float, th: float) -> None:
        """Send linear velocity (x, y, z) in m/s and turn rate th in rad/s."""
        message = TwistStamped() if self.stamped else Twist()
        twist = message.twist if self.stamped else message
        twist.linear.x, twist.linear.y, twist.linear.z = float(x), float(y), float(z)
        twist.angular.z = float(th)
        if self.stamped:
            message.header.stamp = self.get_clock().now().to_msg()
            message.header.frame_id = self.frame_id
        self.publisher.publish(message)


def main(args=None):
    if not sys.stdin.isatty():
        sys.exit('teleop_keyboard: standard input is not a terminal; it reads key presses, '
                 'so run it in a terminal of its own')
    fd = sys.stdin.fileno()
    terminal = termios.tcgetattr(fd)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # as Ctrl-C: stop, then exit
    # Ctrl-C arrives as a key in raw mode; rclpy's handler would shut down before the stop.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = TeleopKeyboard()
    except (ValueError, ParameterException) as error:  # -p frame_id without stamped, a type
        rclpy.try_shutdown()
        sys.exit(f'teleop_keyboard: {error}')
    keys = TeleopKeys()
    try:
        tty.setraw(fd)
        raw = termios.tcgetattr(fd)
        raw[1] |= termios.OPOST  # '\n' still starts a new line, for print and the logger
        termios.tcsetattr(fd, termios.TCSADRAIN, raw)
        print(BANNER + '\n' + keys.status())
        while rclpy.ok() and not keys.done:
            # Waiting for a key at most 0.1 s lets the node's callbacks (clock, parameters) run.
            if select.select([fd], [], [], 0.1)[0]:
                key = os.read(fd, 1).decode('latin-1') or CTRL_C  # the end of input quits too
                for line in keys.press(key):
                    print(line)
                if not keys.done:
                    node.publish(*keys.velocity)
            rclpy.spin_once(node, timeout_sec=0.0)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, terminal)
        if rclpy.ok():
            node.publish(0.0, 0.0, 0.0, 0.0)
            node.publisher.wait_for_all_acked(Duration(seconds=1.0))
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
