"""
ROS 2 message types as the installed message packages define them: class, definition, hash.

Everything here is read from what rosidl generated and installed for each package, so that any
type rclpy can publish can be recorded: the Python class (``<package>.<kind>``), the ``.msg``
file in the package's share folder (found through the ament index) and the type description
rosidl_generator_type_description wrote beside it (``<Name>.json``, which holds the RIHS01 type
hash). :func:`message_definition` concatenates the ``.msg`` files of a type and of every type
it uses as rosbag2's LocalMessageDefinitionSource does for an MCAP schema (encoding
``ros2msg``): the type's own text first, then each dependency once, depth first in name order,
after a line of 80 ``=`` and ``MSG: <package>/<Name>``.
"""

import functools
import importlib
import json
import os
from pathlib import Path
import re
import sys
from typing import Any

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError

#: Interface kinds whose generated classes are messages on a topic (services' and actions'
#: parts included: rosbag2 records action feedback and status topics under such names).
INTERFACE_KINDS = ('msg', 'srv', 'action')
#: What separates the definitions of a type's dependencies (rosbag2's ros2msg encoding).
DEFINITION_SEPARATOR = '=' * 80 + '\n'
#: Primitive field types of .msg files, which are no dependency.
_PRIMITIVES = frozenset({'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8',
                         'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64', 'string'})
# A field's type at the start of a line of a .msg file ("pkg/Name[] name" gives "pkg/Name").
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_TYPE_NAME = re.compile(r'^(\w+)/(msg|srv|action)/(\w+)$')


class UnknownMessageType(ValueError):
    """A type name that is not a message type of an installed package."""


def message_type_name(msg_or_class: Any) -> str:
    """
    Return the ROS type name (``sensor_msgs/msg/LaserScan``) of an rclpy message or its class.

    rosidl generates each class in a module ``<package>.<kind>._<snake_name>`` (``kind`` being
    ``msg``, or ``srv`` / ``action`` for their parts) with a metaclass holding its type support.
    Raises TypeError for anything else.
    """
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    parts = cls.__module__.split('.')
    if len(parts) != 3 or parts[1] not in INTERFACE_KINDS or not parts[2].startswith('_') \
            or not hasattr(type(cls), '_TYPE_SUPPORT'):
        raise TypeError(f'{cls.__module__}.{cls.__qualname__} is not a generated ROS 2 '
                        'message class')
    return f'{parts[0]}/{parts[1]}/{cls.__name__}'


def _split(type_name: str) -> tuple[str, str, str]:
    """Return (package, kind, name) of ``pkg/kind/Name``; UnknownMessageType if malformed."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise UnknownMessageType(f'{type_name!r} is not a ROS 2 type name (pkg/msg/Name)')
    return match[1], match[2], match[3]


@functools.cache
def message_class(type_name: str) -> type:
    """Return the rclpy class of ``type_name``; UnknownMessageType if none is installed."""
    package, kind, name = _split(type_name)
    try:
        cls = getattr(importlib.import_module(f'{package}.{kind}'), name)
    except (ImportError, AttributeError):
        raise UnknownMessageType(f'{type_name!r}: no installed package defines it') from None
    message_type_name(cls)  # a generated message class, nothing else
    return cls


def _share(package: str) -> Path:
    """
    Return the share folder of ``package``: the ament index's, else the Python prefix's.

    A sourced ROS 2 sets AMENT_PREFIX_PATH; the PyPI wheels install the packages' share
    folders under the Python environment's prefix and set nothing.
    """
    if not os.environ.get('AMENT_PREFIX_PATH'):
        return Path(sys.prefix) / 'share' / package
    try:
        return Path(get_package_share_directory(package))
    except PackageNotFoundError:
        return Path(sys.prefix) / 'share' / package


def _interface_file(type_name: str, suffix: str) -> Path:
    """
    Return the file ``<share>/<kind>/<Name><suffix>`` of ``type_name``'s package.

    A service's or an action's part (``SetBool_Request``) is in its interface's file.
    """
    package, kind, name = _split(type_name)
    if kind != 'msg':
        name = name.split('_')[0]
    share = _share(package)
    path = share / kind / f'{name}{suffix}'
    if not path.is_file():
        raise UnknownMessageType(f'{type_name!r}: {package} installed no {kind}/{name}{suffix}')
    return path


@functools.cache
def type_hash(type_name: str) -> str:
    """Return the RIHS01 hash of ``type_name`` from its installed type description (.json)."""
    description = json.loads(_interface_file(type_name, '.json').read_text('utf-8'))
    for entry in description['type_hashes']:
        if entry['type_name'] == type_name:
            return entry['hash_string']
    raise UnknownMessageType(f'{type_name!r}: its type description holds no hash of it')


def _dependencies(text: str, package: str) -> list[str]:
    """Return the message types the fields of a .msg ``text`` use, in name order."""
    found = set()
    for field_type in _FIELD_TYPE.findall(text):
        if field_type not in _PRIMITIVES:
            found.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(found)


@functools.cache
def message_definition(type_name: str) -> str:
    """
    Return the full ros2msg definition of ``type_name``, as rosbag2 stores it in MCAP.

    A service's or an action's part has none ('': rosbag2 leaves it empty too).
    """
    seen: set[str] = set()

    def with_dependencies(name: str) -> str:
        package, _, short = name.partition('/')
        text = _interface_file(f"{package}/msg/{short.split('/')[-1]}", '.msg').read_text(
            'utf-8')
        for dependency in _dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                text += f'\n{DEFINITION_SEPARATOR}MSG: {dependency}\n'
                text += with_dependencies(dependency)
        return text
    if _split(type_name)[1] != 'msg':
        return ''
    return with_dependencies(type_name)
