"""
Put the runtime's modules into ``sys.modules`` under the real ROS names, and take them out.

``install()`` makes ``import rclpy``, ``from rclpy.node import Node``, ``from sensor_msgs.msg
import LaserScan``, ``from tf2_ros import TransformBroadcaster`` ... resolve to the lockstep
runtime, with a fresh :class:`~sim_bridge.lockstep.loop.Runtime`. Nothing is written to disk
or site-packages. It refuses when any of those names is already imported from somewhere else
(a real ROS 2 installation must never be shadowed). ``uninstall()`` restores ``sys.modules``.
"""

from contextlib import contextmanager
import importlib
import sys
from types import ModuleType
from typing import Dict, Iterator

from sim_bridge.lockstep import loop, messages
from sim_bridge.lockstep.errors import LockstepError

_RCLPY_MODULES = ('clock', 'clock_type', 'constants', 'context', 'duration', 'exceptions',
                  'executors', 'logging', 'node', 'parameter', 'publisher', 'qos', 'signals',
                  'subscription', 'time', 'timer', 'utilities')
_TF2_MODULES = ('transform_broadcaster', 'static_transform_broadcaster')

_saved: Dict[str, ModuleType] = {}


def _shim_modules() -> Dict[str, ModuleType]:
    modules = {'rclpy': importlib.import_module('sim_bridge.lockstep.rclpy'),
               'tf2_ros': importlib.import_module('sim_bridge.lockstep.tf2_ros')}
    for name in _RCLPY_MODULES:
        modules[f'rclpy.{name}'] = importlib.import_module(f'sim_bridge.lockstep.rclpy.{name}')
    for name in _TF2_MODULES:
        modules[f'tf2_ros.{name}'] = importlib.import_module(f'sim_bridge.lockstep.tf2_ros.{name}')
    for package in messages.packages():
        top, msg = messages.package_modules(package)
        modules[package] = top
        modules[f'{package}.msg'] = msg
    return modules


def installed() -> bool:
    """Return True between install() and uninstall()."""
    return loop._current is not None


def install() -> loop.Runtime:
    """Alias the runtime's modules as rclpy, the message packages and tf2_ros; new Runtime."""
    if installed():
        raise LockstepError('the lockstep runtime is already installed; uninstall() it first')
    modules = _shim_modules()
    foreign = sorted(name for name in modules
                     if name in sys.modules and not getattr(sys.modules[name], '__lockstep__',
                                                            False))
    if foreign:
        where = getattr(sys.modules[foreign[0]], '__file__', None) or 'an unknown location'
        raise RuntimeError(
            f'a real ROS 2 Python package is already imported ({", ".join(foreign[:5])}'
            f'{" ..." if len(foreign) > 5 else ""}; {foreign[0]} from {where}); the lockstep '
            'runtime will not shadow it. Use real ROS 2, or install lockstep before importing '
            'rclpy in a process without ROS 2.')
    for name, module in modules.items():
        if name in sys.modules:
            _saved[name] = sys.modules[name]
        sys.modules[name] = module
    fresh = loop.Runtime()
    loop.set_current(fresh)
    return fresh


def uninstall() -> None:
    """Remove the aliases (restoring whatever was there) and drop the runtime."""
    for name, module in _shim_modules().items():
        if sys.modules.get(name) is module:
            del sys.modules[name]
    sys.modules.update(_saved)
    _saved.clear()
    loop.set_current(None)


@contextmanager
def installed_runtime() -> Iterator[loop.Runtime]:
    """Install the runtime for a ``with`` block, yield it, and uninstall it afterwards."""
    fresh = install()
    try:
        yield fresh
    finally:
        uninstall()
