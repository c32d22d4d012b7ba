"""
ROS 2 Jazzy message classes generated from rosbags' ``ROS2_JAZZY`` type store.

Every message of every interface package in the store (std_msgs, geometry_msgs, sensor_msgs,
nav_msgs, builtin_interfaces, rosgraph_msgs, tf2_msgs, rcl_interfaces, ...) is available; a class
is generated the first time it is used and cached, so ``sensor_msgs.msg.LaserScan`` is always the
same class object. :func:`package_modules` makes the ``<package>`` and ``<package>.msg`` module
objects that :mod:`sim_bridge.lockstep.aliasing` puts into ``sys.modules``.
"""

import importlib.machinery
from types import ModuleType

from rosbags.typesys import get_typestore, Stores

from sim_bridge.lockstep.messages.classes import build_class, LockstepMessage
from sim_bridge.lockstep.messages.fields import message_spec

__all__ = ['LockstepMessage', 'message_class', 'msgtype_of', 'package_modules', 'packages']

_FIELDDEFS = get_typestore(Stores.ROS2_JAZZY).fielddefs
_CLASSES: dict = {}


def message_class(msgtype: str) -> type:
    """Return the class of ``msgtype`` (``'sensor_msgs/msg/LaserScan'``), generated once."""
    cls = _CLASSES.get(msgtype)
    if cls is None:
        if msgtype not in _FIELDDEFS:
            raise LookupError(
                f"unknown message type '{msgtype}' (not in rosbags' ROS2_JAZZY store)")
        cls = _CLASSES[msgtype] = build_class(message_spec(_FIELDDEFS, msgtype), message_class)
    return cls


def msgtype_of(message_or_class) -> str:
    """Return ``'pkg/msg/Name'`` for a runtime message class or instance."""
    return message_or_class._lockstep_spec.msgtype


def packages() -> list[str]:
    """Names of the interface packages that have messages in the store."""
    return sorted({name.split('/')[0] for name in _FIELDDEFS if '/msg/' in name})


def _message_names(package: str) -> list[str]:
    prefix = f'{package}/msg/'
    return sorted(name[len(prefix):] for name in _FIELDDEFS if name.startswith(prefix))


def _module(name: str, doc: str, is_package: bool) -> ModuleType:
    module = ModuleType(name, doc)
    module.__spec__ = importlib.machinery.ModuleSpec(name, None, is_package=is_package)
    if is_package:
        module.__path__ = []
    module.__lockstep__ = True
    return module


_MODULES: dict = {}


def package_modules(package: str) -> tuple[ModuleType, ModuleType]:
    """Return the ``package`` and ``package.msg`` modules; classes appear on first access."""
    if package not in _MODULES:
        names = _message_names(package)
        if not names:
            raise LookupError(f"no message package '{package}' in rosbags' ROS2_JAZZY store")
        top = _module(package, f'{package} messages (lockstep runtime).', is_package=True)
        msg = _module(f'{package}.msg', f'{package} message classes (lockstep runtime).',
                      is_package=True)

        def lookup(name: str):
            if name in names:
                value = message_class(f'{package}/msg/{name}')
                setattr(msg, name, value)
                return value
            raise AttributeError(f"module '{package}.msg' has no attribute '{name}'")

        msg.__getattr__ = lookup
        msg.__dir__ = lambda: sorted(set(vars(msg)) | set(names))
        msg.__all__ = names
        top.msg = msg
        _MODULES[package] = (top, msg)
    return _MODULES[package]
