"""
Lockstep: run unmodified rclpy nodes in one process, on simulated time, deterministically.

A faithful, in-process stand-in for the parts of ROS 2 Jazzy the lab's nodes use: ``rclpy``
(init/shutdown, Node, publishers, subscriptions, timers, parameters, logging, QoS, executors),
the message packages (classes generated from rosbags' ROS2_JAZZY type store) and ``tf2_ros``'s
broadcasters. Where Jazzy would abort or silently drop (an int in a float field, incompatible
QoS), the runtime raises or warns the same way; what it does not model (services, actions,
rates, wall-clock time, /rosout, /parameter_events) raises LockstepError or is left out.

Modules: ``aliasing`` (install/uninstall), ``loop`` (Runtime: clock, event queue, taps, log
sink), ``topics`` (QoS matching and delivery), ``messages`` (generated classes, publish checks,
delivery copies, rosbags conversion), ``rosargs`` and ``names`` (rcl's argument, YAML and name
rules), ``rclpy`` and ``tf2_ros`` (the modules user code imports), ``errors``.

Typical use by a runner::

    from sim_bridge import lockstep

    rt = lockstep.install()           # `import rclpy` now resolves to the runtime
    rt.add_tap(recorder)              # fn(topic, msg, t_ns) on every publish
    import rclpy
    rclpy.init(args=['--ros-args', '-p', 'distance:=0.5'])
    node = NodeClass()
    try:
        rt.run_until(60 * 10**9)      # 60 s of sim time, every timer and message in order
    except lockstep.NodeError as error:
        print(error)                  # "node 'wall_follow' raised ZeroDivisionError: ..."
    finally:
        lockstep.uninstall()

A node file's ``main()`` runs too: ``rt.set_horizon(t_ns)`` makes ``rclpy.spin`` return there.
"""

from sim_bridge.lockstep.aliasing import install, installed, installed_runtime, uninstall
from sim_bridge.lockstep.errors import (
    LockstepError, MessageTypeError, NodeError, StalledError, TopicTypeError)
from sim_bridge.lockstep.loop import current as runtime, LogRecord, Runtime
from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.messages.rosbags_conversion import msg_to_rosbags

__all__ = ['LockstepError', 'LogRecord', 'MessageTypeError', 'NodeError', 'Runtime',
           'StalledError', 'TopicTypeError', 'install', 'installed', 'installed_runtime',
           'message_class', 'msg_to_rosbags', 'runtime', 'uninstall']
