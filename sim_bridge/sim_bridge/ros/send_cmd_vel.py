"""
Send a velocity command, as ``ros2 topic pub /cmd_vel geometry_msgs/msg/Twist ...`` does.

``send_cmd_vel --linear 0.2 --angular 0.5 --once`` waits (at most ``--wait`` s) for a
subscriber, publishes one geometry_msgs/Twist and exits. ``--rate HZ`` (default 10) publishes
until Ctrl-C or ``--times N`` messages, then a zero command: a driving program stops the robot
when it ends (``ros2 topic pub`` does not). ``--stamped`` sends TwistStamped. Arguments after
``--ros-args`` are rclpy's (remapping, domain, logging).
"""

import argparse
import math
import signal
import sys
import time

from geometry_msgs.msg import Twist, TwistStamped
import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import InvalidTopicNameException
from rclpy.executors import ExternalShutdownException
from rclpy.expand_topic_name import expand_topic_name
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from rclpy.validate_full_topic_name import validate_full_topic_name
from rclpy.validate_topic_name import validate_topic_name

#: The node's name, which a topic name's '~' stands for.
NODE_NAME = 'send_cmd_vel'
#: Longest wait (s) for the published commands to be acknowledged before exiting.
ACK_TIMEOUT_S = 1.0


def numeric(kind: str, minimum: float | None = None, integer: bool = False):
    """Return an argparse type: a finite number (of unit ``kind``), at least ``minimum``."""
    def convert(text: str):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'expected {kind}, got {text!r}') from None
        if not math.isfinite(value) or (minimum is not None and value < minimum):
            raise argparse.ArgumentTypeError(f'expected {kind}, got {text!r}')
        return value
    return convert


def attach_negative_numbers(argv: list[str]) -> list[str]:
    """
    Return ``argv`` with each option followed by a negative number written ``--option=-1e-3``.

    argparse takes ``-1`` and ``-0.5`` for values but anything else that starts with '-'
    (``-1e-3``, ``-.5e1``) for an option, and this program has no option that looks like a
    number.
    """
    joined: list[str] = []
    for argument in argv:
        if joined and joined[-1].startswith('--') and '=' not in joined[-1] \
                and argument.startswith('-') and _is_float(argument):
            joined[-1] += '=' + argument
        else:
            joined.append(argument)
    return joined


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """Parse the command line without its ROS arguments (``argv`` without program name)."""
    parser = argparse.ArgumentParser(
        prog='send_cmd_vel',
        description='Publish a velocity command on cmd_vel, as ros2 topic pub does.',
        epilog='Arguments after --ros-args go to rclpy, e.g. --ros-args -r cmd_vel:=/other.')
    parser.add_argument('--linear', type=numeric('a finite speed in m/s'), default=0.0,
                        help='forward speed linear.x (m/s, default 0.0)')
    parser.add_argument('--angular', type=numeric('a finite turn rate in rad/s'), default=0.0,
                        help='turn rate angular.z, counter-clockwise (rad/s, default 0.0)')
    how = parser.add_mutually_exclusive_group()
    how.add_argument('--once', action='store_true', help='publish one message and exit')
    how.add_argument('--rate', type=numeric('a rate in Hz above 0', 1e-3), default=10.0,
                     help='publish at this rate (Hz, default 10) until Ctrl-C or --times')
    parser.add_argument('--times', type=numeric('a whole number, 1 or more', 1, integer=True),
                        help='with --rate: publish this many messages, then stop')
    parser.add_argument('--wait', type=numeric('a time in s, 0 or more', 0.0), default=5.0,
                        help='with --once or --times: longest wait for a subscriber (s, '
                        'default 5.0)')
    parser.add_argument('--stamped', action='store_true',
                        help='publish geometry_msgs/TwistStamped instead of Twist')
    parser.add_argument('--topic', default='cmd_vel', help='topic name (default cmd_vel)')
    arguments = parser.parse_args(attach_negative_numbers(argv))
    if arguments.once and arguments.times is not None:
        parser.error('argument --times: not allowed with argument --once')
    try:
        validate_topic_name(arguments.topic)
        # As the node will expand it: 'a//b' passes the check above, not rcl's of the result.
        validate_full_topic_name(expand_topic_name(arguments.topic, NODE_NAME, '/'))
    except (InvalidTopicNameException, ValueError) as error:
        # The first line of rclpy's message: the others repeat the name with a caret.
        problem = str(error).splitlines()[0].rstrip(': ')
        parser.error(f'argument --topic: {problem}, got {arguments.topic!r}')
    return arguments


class CmdVelSender(Node):

    def __init__(self, arguments: argparse.Namespace):
        super().__init__(NODE_NAME)
        self.arguments = arguments
        self.publisher = self.create_publisher(
            TwistStamped if arguments.stamped else Twist, arguments.topic, 10)

    def publish(self, linear: float, angular: float) -> None:
        """Send forward speed ``linear`` (m/s) and turn rate ``angular`` (rad/s)."""
        twist = Twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        if self.arguments.stamped:
            message = TwistStamped(twist=twist)
            message.header.stamp = self.get_clock().now().to_msg()
            self.publisher.publish(message)
        else:
            self.publisher.publish(twist)

    def pause(self, until: float) -> None:
        """Run the node's callbacks (its clock, its parameters) until ``until`` (monotonic s)."""
        while (remaining := until - time.monotonic()) > 0.0:
            rclpy.spin_once(self, timeout_sec=remaining)

    def wait_for_subscriber(self) -> bool:
        """Wait at most ``--wait`` s for a subscriber to match; return whether one did."""
        deadline = time.monotonic() + self.arguments.wait
        while self.publisher.get_subscription_count() == 0:
            if time.monotonic() >= deadline:
                return False
            self.pause(min(deadline, time.monotonic() + 0.02))
        return True

    def send(self) -> int:
        """Publish as the arguments say; return the exit status."""
        arguments = self.arguments
        bounded = arguments.once or arguments.times is not None
        if bounded and not self.wait_for_subscriber():
            self.get_logger().error(
                f'no subscriber on {self.publisher.topic_name} after {arguments.wait:g} s: '
                'is the simulator running, on the same ROS_DOMAIN_ID?')
            return 1
        command = arguments.linear, arguments.angular
        if arguments.once:
            self.publish(*command)
            self.get_logger().info(f'sent linear.x {command[0]:g} m/s, angular.z '
                                   f'{command[1]:g} rad/s on {self.publisher.topic_name}')
            return 0
        self.get_logger().info(
            f'sending linear.x {command[0]:g} m/s, angular.z {command[1]:g} rad/s on '
            f'{self.publisher.topic_name} at {arguments.rate:g} Hz'
            + ('' if bounded else ' until Ctrl-C'))
        period_s = 1.0 / arguments.rate
        start, sent = time.monotonic(), 0
        while arguments.times is None or sent < arguments.times:
            self.publish(*command)
            sent += 1
            self.pause(start + sent * period_s)
        return 0


def main(args=None):
    argv = sys.argv if args is None else args
    arguments = parse_arguments(remove_ros_args(args=argv)[1:])
    # Ctrl-C raises KeyboardInterrupt while the context can still send the stop command, even
    # when started with SIGINT ignored (in the background); SIGTERM as Ctrl-C: stop, then exit.
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, signal.default_int_handler)
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = CmdVelSender(arguments)
    status = 0
    try:
        status = node.send()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if rclpy.ok():
            if not arguments.once:
                node.publish(0.0, 0.0)
            node.publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))
        node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == '__main__':
    sys.exit(main())
