"""
Hints for two errors students meet when lab code written for another setup runs here.

:func:`scan_hint`: TurtleBot3 code (``msg.ranges[90]`` as the left, ``ranges[260:280]``) on a
scan with other beams fails with an IndexError or a reduction of an empty slice; the hint gives
the geometry of the scan the node had in hand, and that of ``--robot turtlebot3_burger``.

:func:`ros_module_hint`: a module a ROS 2 installation provides (``tf_transformations``,
``tf2_ros``, ...) is not among the ROS wheels pip installs; the hint says so, and what PyPI has
instead where it has something.
"""

import ast
import functools
import inspect
import math
import os
import re
from types import FrameType

from sim_bridge.common.paths import find_model
from sim_bridge.runner.targets import error_message, StudentCode
from sim_bridge.simulation.sdf import LidarConfig, load_model, SdfError

#: The robot model whose scan most students' code is written for.
TURTLEBOT3 = 'turtlebot3_burger'

#: What Python, statistics and numpy say when asked to reduce no data.
EMPTY_DATA = re.compile(r'empty sequence|iterable argument is empty|zero-size array|'
                        r'requires at least (one|two) data point|for empty data')

#: Directions (rad, REP-103: x ahead, y left) that a beam's angle is named by, within
#: DIRECTION_TOLERANCE.
DIRECTIONS = ((0.0, 'ahead'), (math.pi / 2, 'left'), (math.pi, 'behind'),
              (-math.pi / 2, 'right'))
DIRECTION_TOLERANCE = 0.1

#: Where the pose is without TF (the bridge publishes TF only where tf2_ros imports).
NO_TF = 'without TF here, read the robot pose from /odom (nav_msgs/Odometry)'
#: What replaces a launch file without ROS's launch.
NO_LAUNCH = "launch files are for `ros2 launch` on a ROS machine: here use './lab live'"

#: Modules of a ROS 2 Jazzy installation that the PyPI ROS wheels do not have, with what PyPI
#: (or this kit) offers instead, where it offers something.
ROS_MODULES = {
    'tf_transformations': 'for Euler angles and quaternions PyPI has transforms3d '
                          '(transforms3d.euler.quat2euler takes w, x, y, z; ROS orders x, y, '
                          'z, w); a yaw alone is math.atan2(2 * (w * z + x * y), '
                          '1 - 2 * (y * y + z * z))',
    'tf2_ros': NO_TF,
    'tf2_py': NO_TF,
    'tf2_geometry_msgs': f'{NO_TF}; transforms3d from PyPI rotates points',
    'tf2_msgs': '',
    'sensor_msgs_py': 'read a PointCloud2 with numpy (numpy.frombuffer on its data)',
    'laser_geometry': "a beam's angle is angle_min + i * angle_increment: numpy gives the "
                      'points as ranges * cos(angle), ranges * sin(angle)',
    'launch': NO_LAUNCH,
    'launch_ros': NO_LAUNCH,
    'ros2cli': '',
    'rosbag2_py': 'rosbags from PyPI reads and writes rosbag2 bags',
    'cv_bridge': 'convert a sensor_msgs/Image with numpy (numpy.frombuffer on its data, '
                 'reshaped to height x width x channels)',
    'message_filters': '',
    'nav2_simple_commander': '',
    'turtlebot3_msgs': '',
}

#: rcl's refusal of a second message type on a topic within one DDS participant.
TYPE_CLASH = re.compile(r'existing topic name rt(/\S+) with incompatible type (\w+)::(\w+)::'
                        r'dds_::(\w+)_')


def topic_type_hint(error: BaseException) -> str:
    """
    Return what to do when rcl refused a publisher or subscription of a second type, or ''.

    The runner republishes every node process's topics in its own process (one DDS
    participant), where Fast DDS refuses a topic's second type; across processes the two would
    never connect.
    """
    if type(error).__name__ != 'RCLError':  # rclpy's; a student's error may not even str()
        return ''
    found = TYPE_CLASH.search(str(error))
    if found is None:
        return ''
    topic, package, kind, name = found.groups()
    return (f'another node of this run already uses {topic} with another type than '
            f'{package}/{kind}/{name}: every node of a run must use one type on a topic')


def ros_module_hint(error: BaseException) -> str:
    """
    Return what to know about a missing module a ROS 2 installation provides, or ''.

    On a sourced ROS 2 (``ROS_DISTRO`` set), which package to install; otherwise that the
    module comes with ROS, not the wheels, and what PyPI has instead where it has something.
    '' for any other error, and for a module ROS does not provide either.
    """
    # A folder named like the module (this package's launch/) imports as an empty namespace
    # package: `from launch import LaunchDescription` then fails 'from launch (unknown
    # location)'.
    missing = isinstance(error, ModuleNotFoundError) or (
        isinstance(error, ImportError) and '(unknown location)' in str(error))
    name = (getattr(error, 'name', None) or '').partition('.')[0]
    if not missing or name not in ROS_MODULES:
        return ''
    package = f"ros-jazzy-{name.replace('_', '-')}"
    if os.environ.get('ROS_DISTRO'):  # a sourced ROS 2 installation without that package
        return f'{name} is part of ROS 2 but not installed here: sudo apt install {package}'
    text = (f'{name} comes with a ROS 2 Jazzy installation (apt package {package}), not with '
            'the ROS wheels from PyPI')
    return f'{text}; {ROS_MODULES[name]}' if ROS_MODULES[name] else text


def direction(angle: float) -> str:
    """Return ', ahead' (left, behind, right) for a beam angle (rad) near one, else ''."""
    for towards, name in DIRECTIONS:
        if abs(math.remainder(angle - towards, 2 * math.pi)) <= DIRECTION_TOLERANCE:
            return f', {name}'
    return ''


def angle_text(angle: float) -> str:
    """Return an angle (rad) as '-1.57 rad', '+1.57 rad' or '0 rad'."""
    return '0 rad' if round(angle, 2) == 0 else f'{angle:+.2f} rad'


def geometry(beams: int, angle_min: float, angle_increment: float) -> str:
    """Say where the first and last of ``beams`` beams point (angles in rad)."""
    last = angle_min + angle_increment * (beams - 1)
    return (f'{beams} ranges from {angle_text(angle_min)} (index 0{direction(angle_min)}) to '
            f'{angle_text(last)} (index {beams - 1}{direction(last)})')


@functools.cache
def turtlebot3_lidar() -> LidarConfig | None:
    """Return the lidar of the kit's TurtleBot3 Burger model, or None when it cannot be read."""
    try:
        return load_model(find_model(TURTLEBOT3)).lidar
    except (OSError, SdfError, LookupError):
        return None


def slices(frame: FrameType) -> bool:
    """Return True when the function running in ``frame`` slices anything (``x[a:b]``)."""
    try:
        tree = ast.parse(inspect.cleandoc('\n' + inspect.getsource(frame.f_code)))
    except (OSError, TypeError, SyntaxError):
        return False
    return any(isinstance(node, ast.Slice) for node in ast.walk(tree))


def held_scan(frames: list[FrameType], failing_line: str) -> object | None:
    """
    Return the LaserScan the node's failing code had in hand, innermost first, or None.

    A scan among a frame's locals (a scan callback's message, or what it passed on), else a
    scan the node kept as an attribute when the failing line reads ``ranges``.
    """
    # Imported here, as the runner imports message modules once the run's environment is set.
    from sensor_msgs.msg import LaserScan
    for frame in reversed(frames):
        for value in frame.f_locals.values():
            if isinstance(value, LaserScan):
                return value
    if 'ranges' in failing_line:
        for frame in reversed(frames):
            node = frame.f_locals.get('self')
            for value in getattr(node, '__dict__', {}).values():
                if isinstance(value, LaserScan):
                    return value
    return None


def scan_hint(error: BaseException, code: StudentCode) -> str:
    """
    Return the scan's geometry when ``error`` looks like scan code written for another lidar.

    That is an IndexError, or a reduction of no data (min/max of an empty sequence, statistics
    of an empty list, numpy's zero-size reduction) in a node function that slices, raised while
    the node's code held a LaserScan (:func:`held_scan`). The geometry is that scan's, then that
    of ``--robot turtlebot3_burger`` when it differs. '' otherwise.
    """
    frames = code.live_frames(error)
    if not frames:
        return ''
    if not (isinstance(error, IndexError)
            or (EMPTY_DATA.search(error_message(error)) and slices(frames[-1]))):
        return ''
    scan = held_scan(frames, code.origin(error))
    if scan is None:
        return ''
    return scan_geometry(len(scan.ranges), scan.angle_min, scan.angle_increment)


def scan_geometry(beams: int, angle_min: float, angle_increment: float) -> str:
    """Return the geometry of a scan (angles in rad), then the TurtleBot3's when it differs."""
    text = f'this scan has {geometry(beams, angle_min, angle_increment)}'
    lidar = turtlebot3_lidar()
    if lidar is not None and (lidar.beams, round(lidar.min_angle, 2)) != \
            (beams, round(angle_min, 2)):
        text += (f'; `--robot {TURTLEBOT3}` has '
                 f'{geometry(lidar.beams, lidar.min_angle, lidar.angle_increment)}')
    return text


def printed_scan_hint(error_line: str, failing_line: str, lidar: LidarConfig) -> str:
    """
    Return the scan's geometry for scan code of a node run as its own process, or ''.

    Its error is only the text it printed (``Type: message``) and its failing line's code: an
    IndexError, or a reduction of no data, on a line that reads ``ranges``, gets the geometry
    of the scans the simulator's ``lidar`` sends (as :func:`scan_hint` gives a stepped node).
    """
    kind = error_line.partition(':')[0]
    if 'ranges' not in failing_line or not (
            kind == 'IndexError' or kind == 'ValueError' and EMPTY_DATA.search(error_line)):
        return ''
    return scan_geometry(lidar.beams, lidar.min_angle, lidar.angle_increment)
