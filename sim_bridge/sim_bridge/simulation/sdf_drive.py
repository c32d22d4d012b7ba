"""
Reading a model's diff-drive plugin: Gazebo Sim's DiffDrive system or Classic's gazebo_ros one.

:func:`plugin_kind` tells the two apart (and from any other plugin); :class:`DriveReading` is
the part of the SDF reader (:mod:`.sdf`) that turns one into a
:class:`~.robot.DiffDriveConfig`, with Gazebo's defaults for what the plugin leaves unset. Its
methods use the reader's value parsers and error (``number``, ``boolean``, ``error``...).
Units: m, s, rad.
"""

from collections.abc import Callable
import math
from pathlib import Path
import xml.etree.ElementTree as ElementTree

from sim_bridge.simulation.robot import DiffDriveConfig, DriveLimits

#: Speed limit (m/s and rad/s) standing for "none": a diff-drive plugin without a velocity
#: limit has none in Gazebo, and DriveLimits needs a finite number.
NO_SPEED_LIMIT = 1000.0
#: Gazebo Classic gazebo_ros_diff_drive's wheel separation (m) when the plugin gives none.
CLASSIC_WHEEL_SEPARATION = 0.34
#: Gazebo Sim's DiffDrive odometry rate (Hz) when <odom_publish_frequency> is not given.
SIM_ODOMETRY_RATE = 50.0
#: Gazebo Classic gazebo_ros_diff_drive's update rate (Hz) when <update_rate> is not given.
CLASSIC_UPDATE_RATE = 100.0
#: The ROS 1 gazebo_ros_diff_drive's names (ROBOTIS's ROS 1 TurtleBot3 uses them) of the ROS 2
#: plugin's elements: the same values, in the same units.
ROS1_CLASSIC_NAMES = {'wheel_separation': 'wheelSeparation', 'wheel_diameter': 'wheelDiameter',
                      'max_wheel_acceleration': 'wheelAcceleration', 'update_rate': 'updateRate',
                      'command_topic': 'commandTopic', 'odometry_topic': 'odometryTopic',
                      'odometry_frame': 'odometryFrame', 'robot_base_frame': 'robotBaseFrame',
                      'publish_odom_tf': 'publishOdomTF'}


def plugin_kind(plugin: ElementTree.Element) -> str | None:
    """Return 'sim' or 'classic' for a diff-drive plugin, None for any other plugin."""
    filename = (plugin.get('filename') or '').strip()
    stem = Path(filename).name.removeprefix('lib').removesuffix('.so')
    if stem in ('gz-sim-diff-drive-system', 'ignition-gazebo-diff-drive-system') or \
            plugin.get('name') in ('gz::sim::systems::DiffDrive',
                                   'ignition::gazebo::systems::DiffDrive'):
        return 'sim'
    if stem == 'gazebo_ros_diff_drive':
        return 'classic'
    return None


class DriveReading:
    """The SDF reader's diff-drive part (mixed into it)."""

    def drive_reader(self, plugin: ElementTree.Element, where: str, kind: str
                     ) -> Callable[[str, str], DiffDriveConfig]:
        """Return a function of (model name, canonical link) giving the plugin's config."""
        if kind == 'sim':
            return self.sim_drive(plugin, where)
        return self.classic_drive(plugin, where)

    def optional(self, plugin: ElementTree.Element, tag: str, where: str) -> float | None:
        return self.number(plugin, tag, where) if plugin.find(tag) is not None else None

    def limit(self, plugin: ElementTree.Element, where: str, tags: tuple[str, ...],
              default: float) -> float:
        """Return the magnitude of the last given of ``tags`` (Gazebo lets later ones win)."""
        value = default
        for tag in tags:
            given = self.optional(plugin, tag, where)
            if given is not None:
                if given == 0.0:
                    raise self.error(f'{where}/<{tag}>', 'must not be 0')
                value = abs(given)
        return value

    def sim_drive(self, plugin: ElementTree.Element, where: str
                  ) -> Callable[[str, str], DiffDriveConfig]:
        # gz-sim's DiffDrive: the general <max_velocity>/<max_acceleration> set both the
        # linear and the angular limiter, the specific elements override them; a <min_*> only
        # given stands for the limit the other way (DriveLimits is symmetric).
        def speed(which: str) -> float:
            return self.limit(plugin, where, ('min_velocity', 'max_velocity',
                                              f'min_{which}_velocity', f'max_{which}_velocity'),
                              NO_SPEED_LIMIT)

        def accel(which: str) -> float:
            return self.limit(plugin, where, ('min_acceleration', 'max_acceleration',
                                              f'min_{which}_acceleration',
                                              f'max_{which}_acceleration'), math.inf)

        limits = self.drive_limits(where, max_linear_speed=speed('linear'),
                                   max_angular_speed=speed('angular'),
                                   max_linear_accel=accel('linear'),
                                   max_angular_accel=accel('angular'))
        separation = self.optional_positive(plugin, 'wheel_separation', where)
        radius = self.optional_positive(plugin, 'wheel_radius', where)
        rate = self.optional_positive(plugin, 'odom_publish_frequency', where)
        text = {tag: (plugin.findtext(tag) or '').strip()
                for tag in ('topic', 'odom_topic', 'frame_id', 'child_frame_id')}

        def config(model: str, link: str) -> DiffDriveConfig:
            return DiffDriveConfig(
                wheel_separation=separation, wheel_radius=radius, limits=limits,
                command_topic=text['topic'] or f'/model/{model}/cmd_vel',
                odometry_topic=text['odom_topic'] or f'/model/{model}/odometry',
                odometry_frame=text['frame_id'] or f'{model}/odom',
                base_frame=text['child_frame_id'] or f'{model}/{link}',
                odometry_rate=rate or SIM_ODOMETRY_RATE, publish_tf=True)
        return config

    def classic_drive(self, plugin: ElementTree.Element, where: str
                      ) -> Callable[[str, str], DiffDriveConfig]:
        # gazebo_ros_diff_drive: <max_wheel_acceleration> (m/s² at the wheel's rim, 0 = none)
        # bounds each wheel; the body's linear acceleration is that, its angular one twice that
        # over the wheel separation. It has no velocity limit. ROS 1's plugin names its
        # elements in camelCase (ROS1_CLASSIC_NAMES).
        def named(tag: str) -> str:
            return tag if plugin.find(tag) is not None else ROS1_CLASSIC_NAMES.get(tag, tag)

        separation = self.optional_positive(plugin, named('wheel_separation'), where)
        diameter = self.optional_positive(plugin, named('wheel_diameter'), where)
        wheel_accel = self.optional(plugin, named('max_wheel_acceleration'), where) or 0.0
        if wheel_accel < 0.0:
            raise self.error(f"{where}/<{named('max_wheel_acceleration')}>",
                             'must not be negative')
        linear = wheel_accel if wheel_accel > 0.0 else math.inf
        angular = 2.0 * linear / (separation or CLASSIC_WHEEL_SEPARATION)
        limits = self.drive_limits(where, max_linear_speed=NO_SPEED_LIMIT,
                                   max_angular_speed=NO_SPEED_LIMIT, max_linear_accel=linear,
                                   max_angular_accel=angular)
        rate = self.optional(plugin, named('update_rate'), where)
        namespace = (plugin.findtext('ros/namespace') or '').strip()
        remaps = {}
        for remapping in plugin.findall('ros/remapping'):
            source, _, target = (remapping.text or '').strip().partition(':=')
            remaps[source.strip().lstrip('~').lstrip('/')] = target.strip()

        def topic(name: str, legacy: str) -> str:
            # The ROS 2 plugin subscribes to 'cmd_vel' and publishes 'odom' under its node's
            # namespace, renamed by <ros><remapping>; <command_topic>/<odometry_topic> are
            # the ROS 1 plugin's names, honoured when no remapping is given.
            chosen = remaps.get(name) or (plugin.findtext(named(legacy)) or '').strip() or name
            if namespace and not chosen.startswith('/'):
                chosen = f"{namespace.rstrip('/')}/{chosen}"
            return chosen

        config = DiffDriveConfig(
            wheel_separation=separation,
            wheel_radius=0.5 * diameter if diameter is not None else None, limits=limits,
            command_topic=topic('cmd_vel', 'command_topic'),
            odometry_topic=topic('odom', 'odometry_topic'),
            odometry_frame=(plugin.findtext(named('odometry_frame')) or '').strip() or 'odom',
            base_frame=(plugin.findtext(named('robot_base_frame')) or '').strip()
            or 'base_footprint',
            odometry_rate=rate if rate and rate > 0.0 else CLASSIC_UPDATE_RATE,
            publish_tf=self.boolean(plugin.find(named('publish_odom_tf')),
                                    f"{where}/<{named('publish_odom_tf')}>", default=False))
        return lambda _model, _link: config

    def drive_limits(self, where: str, **values: float) -> DriveLimits:
        try:
            return DriveLimits(**values)
        except ValueError as error:
            raise self.error(where, str(error)) from None

    def optional_positive(self, parent: ElementTree.Element, tag: str,
                          where: str) -> float | None:
        return self.positive(parent, tag, where) if parent.find(tag) is not None else None
