"""install()/uninstall() alias the runtime under the real module names and restore sys.modules."""

import importlib.util
import sys
import types

import pytest

from sim_bridge import lockstep

ROS_NAMES = ['rclpy', 'rclpy.node', 'rclpy.qos', 'rclpy.executors', 'rclpy.time',
             'rclpy.duration', 'rclpy.clock', 'rclpy.parameter', 'rclpy.logging',
             'rclpy.exceptions', 'rclpy.timer', 'rclpy.publisher', 'rclpy.subscription',
             'sensor_msgs.msg', 'geometry_msgs.msg', 'nav_msgs.msg', 'std_msgs.msg',
             'builtin_interfaces.msg', 'rosgraph_msgs.msg', 'tf2_msgs.msg', 'tf2_ros']


def test_install_makes_the_ros_names_importable_and_uninstall_removes_them():
    before = dict(sys.modules)
    runtime = lockstep.install()
    try:
        for name in ROS_NAMES:
            assert importlib.import_module(name).__lockstep__
        from rclpy.node import Node
        from sensor_msgs.msg import LaserScan
        assert Node.__module__.startswith('sim_bridge.lockstep.')
        assert LaserScan is lockstep.message_class('sensor_msgs/msg/LaserScan')
        assert lockstep.runtime() is runtime
    finally:
        lockstep.uninstall()
    assert not any(name in sys.modules for name in ROS_NAMES)
    assert set(sys.modules) - set(before) <= {name for name in sys.modules
                                              if name.startswith('sim_bridge.')}
    with pytest.raises(lockstep.LockstepError, match='not installed'):
        lockstep.runtime()


def test_nothing_named_rclpy_exists_outside_the_runtime():
    assert importlib.util.find_spec('rclpy') is None or \
        'sim_bridge' not in (importlib.util.find_spec('rclpy').origin or '')


def test_install_refuses_to_shadow_a_real_rclpy(monkeypatch):
    real = types.ModuleType('rclpy')
    real.__file__ = '/opt/ros/jazzy/lib/python3.12/site-packages/rclpy/__init__.py'
    monkeypatch.setitem(sys.modules, 'rclpy', real)
    with pytest.raises(RuntimeError, match='a real ROS 2 Python package is already imported'):
        lockstep.install()
    assert sys.modules['rclpy'] is real and not lockstep.installed()


def test_install_twice_is_refused(runtime):
    with pytest.raises(lockstep.LockstepError, match='already installed'):
        lockstep.install()


def test_context_manager_installs_a_fresh_runtime_each_time():
    with lockstep.installed_runtime() as first:
        assert 'rclpy' in sys.modules
    with lockstep.installed_runtime() as second:
        assert second is not first and second.now_ns == 0
    assert 'rclpy' not in sys.modules
