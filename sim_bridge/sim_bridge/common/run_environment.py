"""
The ROS 2 environment of an in-process run: its traffic kept in the process, field checks on.

``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF``: the process still talks to itself, and no other process
(another run, a live simulator, another machine) sees it or is seen. NO_SHARED_MEMORY: nor
does it open Fast DDS's files in /dev/shm.

``ROS_PYTHON_CHECK_FIELDS=1``: rosidl's generated setters raise ``AssertionError: The 'z' field
must be of type 'float'`` when a node puts an int in a float field. Jazzy's default (unset)
sends such a value as garbage: the float64 is read from the int's bits, ``5`` arrives as
5e-324 and ``-3`` as nan. Each generated message module reads the variable once, when it is
imported, into its global ``ros_python_check_fields``; modules imported before the run get the
run's value there too.
"""

from contextlib import contextmanager
from importlib import metadata
import os
import sys
from typing import Iterator, Mapping

CHECK_FIELDS_VARIABLE = 'ROS_PYTHON_CHECK_FIELDS'
#: Fast DDS without its shared-memory transport: a run's traffic stays in its process
#: (intra-process delivery), and no file in /dev/shm, which every user shares, is opened. A
#: process of any user that squats Fast DDS's port files there (fs.protected_regular=0) makes
#: every participant that opens them abort ("The futex facility returned an unexpected error
#: code"): the grader's, another run's.
NO_SHARED_MEMORY = {'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'}
#: What a run's error adds when a field check fails.
FIELD_CHECK_HINT = (
    "field checks are on in runs (ROS_PYTHON_CHECK_FIELDS=1); on a robot, Jazzy's default does "
    'not check, and the value would arrive as garbage (an int 5 in a float64 field as 5e-324, '
    '-3 as nan): publish floats, e.g. float(x) or 0.0')


def _message_modules() -> list:
    return [module for name, module in list(sys.modules.items())
            if '.msg._' in name and hasattr(module, 'ros_python_check_fields')]


@contextmanager
def environment_set(values: Mapping[str, str | None]) -> Iterator[None]:
    """Set the environment variables ``values`` (None: unset them) for the block; restore after."""
    saved = {name: os.environ.get(name) for name in values}
    for name, value in values.items():
        _put(name, value)
    try:
        yield
    finally:
        for name, value in saved.items():
            _put(name, value)


def _put(name: str, value: str | None) -> None:
    if value is None:
        os.environ.pop(name, None)
    else:
        os.environ[name] = value


@contextmanager
def run_environment(field_checks: bool = True) -> Iterator[None]:
    """Set the run's variables (and message modules' field-check flag); restore them after."""
    check = '1' if field_checks else ''
    modules = {module: module.ros_python_check_fields for module in _message_modules()}
    outside = os.environ.get(CHECK_FIELDS_VARIABLE, '')  # what a module first imported here gets
    with environment_set({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'OFF', CHECK_FIELDS_VARIABLE: check,
                          **NO_SHARED_MEMORY}):
        for module in modules:
            module.ros_python_check_fields = check
        try:
            yield
        finally:
            for module in _message_modules():
                module.ros_python_check_fields = modules.get(module, outside)


def is_field_check_failure(error: BaseException) -> bool:
    """Tell whether ``error`` is rosidl's field check refusing a value."""
    return isinstance(error, AssertionError) and 'field must be' in str(error)


def keep_dds_in_process() -> None:
    """Make this process's ROS 2 traffic invisible to every other (tests set it first)."""
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
    os.environ.pop('ROS_STATIC_PEERS', None)


def rclpy_origin() -> str:
    """Say which rclpy this Python imports: a sourced ROS 2 installation or the PyPI wheels."""
    import rclpy
    location = os.path.dirname(rclpy.__file__)
    try:
        wheel = metadata.version('ros-jazzy-rclpy')
    except metadata.PackageNotFoundError:
        distro = os.environ.get('ROS_DISTRO', 'unknown distribution')
        return f'rclpy of the sourced ROS 2 {distro} installation ({location})'
    return f'rclpy {wheel} of ROS 2 Jazzy, from the PyPI wheels ({location})'
