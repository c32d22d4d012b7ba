"""
What the driving nodes share: their parameters, their velocity commands, their main loop.

Parameters are the fields of a controller's config dataclass; commands are Twist, or
TwistStamped when asked for; the main loop stops the robot before the node shuts down.
"""

from dataclasses import fields
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

#: Longest wait (s) for work in the driving nodes' spin before Python can handle Ctrl-C.
SPIN_TIMEOUT_S = 0.1
#: Longest wait (s) for the subscribers to acknowledge the zero command a stopping node sends.
STOP_ACK_TIMEOUT_S = 1.0


def declare_config(node: Node, config_class: type) -> Any:
    """
    Declare one parameter per field of the dataclass ``config_class``; return the config.

    Each parameter is typed by the field's default (rclpy's rule); the config checks the
    values, so a bad one stops the node at start-up with a ValueError naming it.
    """
    return config_class(**{field.name: node.declare_parameter(field.name, field.default).value
                           for field in fields(config_class)})


class CmdVelPublisher:
    """
    Publish ``(linear m/s, angular rad/s)`` commands on ``cmd_vel`` for ``node``.

    Declares the node's ``stamped`` parameter (default false): geometry_msgs/Twist, as the
    simulator bridge and teleop_twist_keyboard use by default, or geometry_msgs/TwistStamped,
    as Jazzy's diff_drive_controller expects. Values are always sent as Python floats.
    """

    def __init__(self, node: Node, topic: str = 'cmd_vel'):
        self._node = node
        self.stamped = node.declare_parameter('stamped', False).value
        self._publisher = node.create_publisher(
            TwistStamped if self.stamped else Twist, topic, 10)

    def publish(self, linear: float, angular: float) -> None:
        """Send forward speed ``linear`` (m/s) and turn rate ``angular`` (rad/s, CCW)."""
        twist = Twist()
        twist.linear.x = float(linear)
        twist.angular.z = float(angular)
        if self.stamped:
            message = TwistStamped(twist=twist)
            message.header.stamp = self._node.get_clock().now().to_msg()
            self._publisher.publish(message)
        else:
            self._publisher.publish(twist)

    def stop(self) -> None:
        """
        Send a zero command and wait (bounded) until every reliable subscriber has it.

        The node's process may end right after: on a busy machine it would otherwise end before
        DDS delivered the command to another process, and the robot would drive on.
        """
        self.publish(0.0, 0.0)
        self._publisher.wait_for_all_acked(Duration(seconds=STOP_ACK_TIMEOUT_S))


def spin_then_stop(node_class: type, args: list[str] | None = None) -> None:
    """
    Spin a driving node (one with a ``cmd_vel`` CmdVelPublisher) until Ctrl-C or shutdown.

    Jazzy's demo_nodes_py main, plus a zero command before shutting down, as
    teleop_twist_keyboard sends. rclpy's signal handler is off, so Ctrl-C raises
    KeyboardInterrupt while the context is still valid for that last publish; spinning with a
    timeout returns to Python often enough for it to be raised even when no message arrives.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = node_class()
    try:
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=SPIN_TIMEOUT_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if rclpy.ok():
            node.cmd_vel.stop()
        node.destroy_node()
        rclpy.try_shutdown()
