"""
Differential-drive kinematics (REP-103: x forward, y left, yaw counter-clockwise).

A commanded forward speed v (m/s) and turn rate w (rad/s) move the robot along a circular arc;
:func:`integrate_arc` does that exactly for constant (v, w). :class:`DiffDrive` holds the
robot's pose and velocity and applies :class:`DriveLimits`: commands beyond the speed limits
are clamped, commands that are not finite numbers are rejected (the robot stops), and the
velocity follows the command no faster than the acceleration limits allow. Collisions are the
simulator's business.
"""

from dataclasses import dataclass
import math

import numpy as np

from sim_bridge.simulation.geometry import wrap_angle

Pose = tuple[float, float, float]
#: Below this turn rate (rad/s) an arc is integrated as a straight line (no division by ~0).
STRAIGHT_TURN_RATE = 1e-12


@dataclass(frozen=True)
class DriveLimits:
    """
    Speed and acceleration limits of the drive, the same forwards and backwards.

    ``max_linear_speed`` (m/s, default 1.0) and ``max_angular_speed`` (rad/s, default 2.84, a
    TurtleBot3's) clamp commands; ``max_linear_accel`` (m/s², default 2.5) and
    ``max_angular_accel`` (rad/s², default 5.0) limit how fast the velocity follows them
    (``math.inf`` for an instant response).
    """

    max_linear_speed: float = 1.0
    max_angular_speed: float = 2.84
    max_linear_accel: float = 2.5
    max_angular_accel: float = 5.0

    def __post_init__(self) -> None:
        for name in ('max_linear_speed', 'max_angular_speed'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be a positive finite number, got {value!r}')
        for name in ('max_linear_accel', 'max_angular_accel'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 0.0):
                raise ValueError(f'{name} must be a positive number (inf for no limit), '
                                 f'got {value!r}')


@dataclass(frozen=True)
class DiffDriveConfig:
    """
    A model's differential-drive plugin, as Gazebo reads it.

    Gazebo Sim's DiffDrive system or Classic's ``libgazebo_ros_diff_drive.so``; what the plugin
    leaves unset is Gazebo's default. ``wheel_separation`` and ``wheel_radius`` (m, None when
    not given); ``limits`` (the plugin's velocity and acceleration limits,
    :class:`DriveLimits`); the command and odometry topics, the odometry frame and the robot's
    base frame (its child); ``odometry_rate`` (Hz); ``publish_tf`` whether it broadcasts
    odom -> base. ``command_timeout`` (s): with no new command for longer, the robot stops;
    None (Gazebo's DiffDrive) keeps the last command.
    """

    wheel_separation: float | None = None
    wheel_radius: float | None = None
    limits: DriveLimits = DriveLimits()
    command_topic: str = 'cmd_vel'
    odometry_topic: str = 'odom'
    odometry_frame: str = 'odom'
    base_frame: str = 'base_link'
    odometry_rate: float = 50.0
    publish_tf: bool = True
    command_timeout: float | None = None


def pose_from(origin: Pose, pose: Pose) -> Pose:
    """
    Return world ``pose`` seen from ``origin`` (x m, y m, yaw rad): odometry from a start.

    Gazebo's DiffDrive starts its odometry at (0, 0, 0) in ``odom``, wherever the robot was
    spawned: odom is the spawn pose's frame. numpy arrays work element-wise.
    """
    ox, oy, oyaw = origin
    dx, dy = pose[0] - ox, pose[1] - oy
    cos_yaw, sin_yaw = math.cos(oyaw), math.sin(oyaw)
    yaw = np.arctan2(np.sin(pose[2] - oyaw), np.cos(pose[2] - oyaw))
    return (cos_yaw * dx + sin_yaw * dy, cos_yaw * dy - sin_yaw * dx, yaw)


def pose_in_world(origin: Pose, odometry: Pose) -> Pose:
    """Return the world pose of an ``odometry`` pose taken from ``origin`` (see pose_from)."""
    ox, oy, oyaw = origin
    cos_yaw, sin_yaw = math.cos(oyaw), math.sin(oyaw)
    x, y, yaw = odometry
    turned = yaw + oyaw
    return (ox + cos_yaw * x - sin_yaw * y, oy + sin_yaw * x + cos_yaw * y,
            np.arctan2(np.sin(turned), np.cos(turned)))


def integrate_arc(pose: Pose, linear: float, angular: float, dt: float) -> Pose:
    """
    Return the pose (x m, y m, yaw rad) after driving at constant (v m/s, w rad/s) for dt s.

    Exact: the robot moves on a circle of radius v / w (a straight line when w is 0).
    """
    x, y, yaw = pose
    if abs(angular) < STRAIGHT_TURN_RATE:
        distance = linear * dt
        return (x + distance * math.cos(yaw), y + distance * math.sin(yaw), yaw)
    radius = linear / angular
    new_yaw = yaw + angular * dt
    return (x + radius * (math.sin(new_yaw) - math.sin(yaw)),
            y - radius * (math.cos(new_yaw) - math.cos(yaw)),
            wrap_angle(new_yaw))


def ramp(current: float, target: float, max_accel: float, dt: float) -> tuple[float, float]:
    """
    Return (end, mean) of a velocity moving from ``current`` towards ``target`` for dt s.

    The velocity changes at ``max_accel`` (per s) until it reaches the target, then holds;
    ``mean`` is its average over the step, so mean * dt is exactly the distance (or angle)
    covered.
    """
    change = target - current
    max_change = max_accel * dt
    if abs(change) <= max_change:
        reach_time = abs(change) / max_accel
        return target, target - 0.5 * change * reach_time / dt
    end = current + math.copysign(max_change, change)
    return end, 0.5 * (current + end)


def check_command(linear: float, angular: float, limits: DriveLimits
                  ) -> tuple[float, float, str | None]:
    """
    Return the command to apply for a requested (v m/s, w rad/s) and a warning, or None.

    A value that is not a finite number (NaN, inf, not a number at all) rejects the whole
    command: the robot is told to stop. Values beyond the limits are clamped to them.
    """
    try:
        values = (float(linear), float(angular))
    except (TypeError, ValueError):
        values = (math.nan, math.nan)
    if not all(math.isfinite(value) for value in values):
        return 0.0, 0.0, (f'rejected command (linear {linear!r} m/s, angular {angular!r} '
                          'rad/s): not a finite number; stopping the robot')
    clamped_linear = max(-limits.max_linear_speed, min(limits.max_linear_speed, values[0]))
    clamped_angular = max(-limits.max_angular_speed, min(limits.max_angular_speed, values[1]))
    if (clamped_linear, clamped_angular) == values:
        return values[0], values[1], None
    return clamped_linear, clamped_angular, (
        f'clamped command (linear {values[0]:g} m/s, angular {values[1]:g} rad/s) to the '
        f'limits: linear {clamped_linear:g} m/s, angular {clamped_angular:g} rad/s')


class DiffDrive:
    """The robot's drive: pose (x m, y m, yaw rad), velocity (v m/s, w rad/s) and command."""

    def __init__(self, pose: Pose = (0.0, 0.0, 0.0), limits: DriveLimits | None = None) -> None:
        self.limits = limits or DriveLimits()
        self.pose = (float(pose[0]), float(pose[1]), wrap_angle(float(pose[2])))
        self.velocity = (0.0, 0.0)
        self.command = (0.0, 0.0)

    def set_command(self, linear: float, angular: float) -> str | None:
        """Command (v m/s, w rad/s); return a warning when it was rejected or clamped."""
        linear, angular, warning = check_command(linear, angular, self.limits)
        self.command = (linear, angular)
        return warning

    def accelerate(self, dt: float) -> tuple[float, float]:
        """
        Move the velocity towards the command for dt s; return the step's mean (v, w).

        Driving the mean velocities' arc is exact for constant velocities and covers the exact
        distance and turn of a ramp.
        """
        linear, mean_linear = ramp(self.velocity[0], self.command[0],
                                   self.limits.max_linear_accel, dt)
        angular, mean_angular = ramp(self.velocity[1], self.command[1],
                                     self.limits.max_angular_accel, dt)
        self.velocity = (linear, angular)
        return mean_linear, mean_angular

    def step(self, dt: float) -> Pose:
        """Drive for dt s without obstacles; return the new pose."""
        linear, angular = self.accelerate(dt)
        self.pose = integrate_arc(self.pose, linear, angular, dt)
        return self.pose

    def halt(self) -> None:
        """Stop the forward motion at once (the robot hit something); turning goes on."""
        self.velocity = (0.0, self.velocity[1])
