"""
Wanderbot: drive straight until the way is blocked, then turn in place by more than 90 deg.

Pure: no rclpy. :class:`Wanderer` is fed scans (:class:`scan_pkg.laser.Scan`) and odometry yaw
with their arrival times (s, on the node's clock) and answers the command to send, as Python
floats ``(linear m/s, angular rad/s)``.

Blocked: some return lies in the corridor the robot is about to sweep (:func:`corridor_distance`:
less than ``obstacle_distance`` ahead of the laser, within the robot's radius plus a margin of
the heading line). Unlike one beam or a cone, a corridor of points catches an obstacle between
beams or off-centre, and ignores a wall the robot is passing. -inf readings (too close to
measure) are obstacles.

Manoeuvre: stop and turn towards the more open side by a random angle in
[``min_turn_deg``, ``max_turn_deg``] (or ``turn_deg``), braking on a constant-deceleration
profile so the turn ends on its angle. The turn is measured on odometry yaw, accumulated
wrap-safely message by message, and on the commanded rate integrated over time whenever
odometry is older than ``odom_timeout``. Then wait for a scan taken after the turn: if the way
(lengthened a little, for hysteresis) is still blocked, turn on the same way to the nearest
heading whose corridor is empty (:func:`clear_turn`); else drive on. Turns always continue the
direction of a turn that ended moments before, so one manoeuvre never undoes itself.
"""

from dataclasses import dataclass
import math
import random
import sys
from typing import Callable

import numpy as np

from scan_pkg.behaviors import require
from scan_pkg.laser import normalize_angle, Scan

TURN_MODES = ('random', 'constant')
"""Values of ``WanderConfig.turn_mode``."""

OPEN_SIDE_RANGE = 3.0
"""Cap (m) on the ranges averaged to tell which side is more open."""

TURN_STEP = math.radians(5.0)
"""Resolution (rad) of the search for a clear heading after a turn."""

SETTLE_MARGIN = 0.1
"""Extra length (m) of the corridor that must be clear to drive on after a turn."""

MIN_TURN_RATE = 0.2
"""Slowest turn rate (rad/s) commanded while a turn is unfinished."""

SAME_MANOEUVRE_S = 0.5
"""A turn starting this soon (s) after the last one ended continues its direction."""


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """
    Return the yaw (rad, in (-pi, pi]) of the rotation quaternion ``(x, y, z, w)``.

    The quaternion need not be normalised; the rotation about z is taken from the ZYX
    (yaw-pitch-roll) decomposition, as tf2's ``getRPY`` does.
    """
    return normalize_angle(math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z))


def obstacle_points(scan: Scan) -> np.ndarray:
    """
    Return where ``scan`` saw obstacles: an (N, 2) array of x, y (m, laser frame).

    Valid readings are obstacles where they are; -inf (too close) and readings below
    ``range_min`` are obstacles at ``range_min`` on their beam; +inf, readings beyond
    ``range_max`` and NaN are no obstacle.
    """
    ranges = scan.ranges
    # Every reading up to range_max, the too close ones included, but +inf (no return even when
    # range_max is +inf); NaN compares False.
    obstacles = ranges <= min(scan.range_max, sys.float_info.max)
    distances = np.maximum(ranges[obstacles], scan.range_min)
    # compress selects rows as [obstacles] does, faster.
    return scan.directions().compress(obstacles, axis=0) * distances[:, np.newaxis]


def corridor_distance(points: np.ndarray, length: float, radius: float,
                      margin: float) -> float | None:
    """
    Return how far ahead (m) the nearest point in the corridor is, or None if it is clear.

    ``points``: (N, 2) x, y (m) as :func:`obstacle_points` gives them. The corridor is what a
    robot of ``radius`` (m) sweeps driving ``length`` (m) ahead, widened by ``margin`` (m) on
    each side: ``0 < x < length``, ``|y| < radius + margin * min(x / radius, 1)``. The margin
    grows from nothing beside the robot to its full width one radius ahead, so a wall the
    robot is passing beside it does not block the way, while one ahead does from afar.
    """
    x, y = points[:, 0], points[:, 1]
    half_width = radius + margin * np.minimum(x / radius, 1.0) if radius > 0.0 else margin
    ahead = x[(x > 0.0) & (x < length) & (np.abs(y) < half_width)]
    return float(ahead.min()) if len(ahead) else None


def clear_turn(points: np.ndarray, direction: int, length: float, radius: float,
               margin: float, max_turn: float) -> float | None:
    """
    Return the smallest turn (rad) towards ``direction`` that faces a clear corridor.

    ``points``: obstacles (m) as :func:`obstacle_points` gives them; ``direction``: +1 for
    left (anticlockwise), -1 for right; the corridor as in :func:`corridor_distance` (m).
    Turns from 0 to ``max_turn`` (rad) are tried in steps of ``TURN_STEP``; None when no
    heading among them is clear.
    """
    for turn in np.arange(0.0, max_turn + 1e-9, TURN_STEP):
        heading = direction * turn
        cos, sin = math.cos(heading), math.sin(heading)
        # The points in the frame of the robot turned to ``heading``.
        turned = points @ np.array([[cos, -sin], [sin, cos]])
        if corridor_distance(turned, length, radius, margin) is None:
            return float(turn)
    return None


def open_side(scan: Scan) -> int:
    """
    Return +1 if the left half of ``scan`` is more open than the right, -1 if less, else 0.

    Openness is the mean range (m) of a half, capped at ``OPEN_SIDE_RANGE``; NaN is ignored.
    """
    ranges = scan.capped(OPEN_SIDE_RANGE)
    sines = np.sin(scan.angles())
    known = ~np.isnan(ranges)
    openness = []
    for half in (known & (sines > 0.0), known & (sines < 0.0)):
        openness.append(float(ranges[half].mean()) if half.any() else 0.0)
    left, right = openness
    return (left > right) - (left < right)


@dataclass(frozen=True)
class WanderConfig:
    """
    Parameters of :class:`Wanderer`, with the wanderbot node's defaults.

    Distances in m, speeds in m/s and rad/s, ``turn_decel`` in rad/s², angles in degrees,
    times in s, ``control_rate`` (commands per second) in Hz. ``turn_decel`` shapes the end of
    a turn; keep it below the base's angular acceleration limit.
    """

    speed: float = 0.5
    obstacle_distance: float = 0.7
    robot_radius: float = 0.15
    corridor_margin: float = 0.1
    turn_mode: str = 'random'
    min_turn_deg: float = 100.0
    max_turn_deg: float = 180.0
    turn_deg: float = 120.0
    turn_speed: float = 2.0
    turn_decel: float = 4.0
    odom_timeout: float = 0.5
    scan_timeout: float = 0.5
    seed: int = 0
    control_rate: float = 20.0

    def __post_init__(self):
        require(self, positive=('obstacle_distance', 'turn_speed', 'turn_decel', 'odom_timeout',
                                'scan_timeout', 'min_turn_deg', 'turn_deg', 'control_rate'),
                non_negative=('speed', 'robot_radius', 'corridor_margin'))
        if not self.max_turn_deg >= self.min_turn_deg:
            raise ValueError(f'max_turn_deg ({self.max_turn_deg!r}) must be >= min_turn_deg '
                             f'({self.min_turn_deg!r})')
        if self.turn_mode not in TURN_MODES:
            raise ValueError(f"turn_mode must be one of {', '.join(TURN_MODES)}, "
                             f'got {self.turn_mode!r}')


class Wanderer:
    """
    The wanderbot's state machine: ``driving``, ``turning`` or ``settling`` after a turn.

    Feed it with :meth:`update_scan` and :meth:`update_odom`, ask :meth:`command` at the
    control rate. Times are seconds on one clock (the node's). ``on_event`` receives a short
    text for each decision (an obstacle, a turn, odometry lost), for logging. ``turns_deg``
    lists the angle (deg) of every finished turn.
    """

    def __init__(self, config: WanderConfig | None = None,
                 on_event: Callable[[str], None] | None = None):
        config = config or WanderConfig()
        self.config = config
        self.state = 'driving'
        self.turns_deg = []
        self._on_event = on_event or (lambda text: None)
        self._random = random.Random(config.seed)
        self._scan = None
        self._scan_time = -math.inf
        self._odom_yaw = None
        self._odom_time = -math.inf
        self._heading = 0.0
        self._command_time = None
        self._angular = 0.0
        self._integrating = False
        self._odom_lost_reported = False
        self._turn_direction = 0
        self._turn_start = 0.0
        self._turn_target = 0.0
        self._turn_ended = -math.inf

    def update_scan(self, scan: Scan, time: float) -> None:
        """Take the latest scan, received at ``time`` (s); a blind one (all NaN) is ignored."""
        if scan.is_blind():
            return
        self._scan = scan
        self._scan_time = time

    def update_odom(self, yaw: float, time: float) -> None:
        """
        Take the latest odometry yaw (rad), received at ``time`` (s).

        Consecutive yaws are differenced modulo 2 pi, so the heading accumulates across the
        +-pi wrap. After a gap longer than ``odom_timeout`` the first message only sets the
        reference: the gap was covered by integrating the commanded rate.
        """
        if self._odom_yaw is not None and time - self._odom_time <= self.config.odom_timeout:
            self._heading += normalize_angle(yaw - self._odom_yaw)
        self._odom_yaw = yaw
        self._odom_time = time

    @property
    def turned(self) -> float:
        """Heading change (rad, >= 0 in the turn's direction) since the current turn began."""
        return self._turn_direction * (self._heading - self._turn_start)

    def command(self, time: float) -> tuple[float, float]:
        """Return ``(linear m/s, angular rad/s)`` to send at ``time`` (s), as Python floats."""
        self._integrate_commanded_rate(time)
        linear, angular = self._decide(time)
        self._angular = angular
        return float(linear), float(angular)

    def _integrate_commanded_rate(self, time: float) -> None:
        previous = self._command_time
        self._command_time = time
        if time - self._odom_time <= self.config.odom_timeout:
            self._integrating = self._odom_lost_reported = False
            return
        if self.state == 'turning' and not self._odom_lost_reported:
            self._odom_lost_reported = True
            self._on_event('no odometry: measuring the turn by the commanded rate')
        if previous is not None:
            # Odometry covered the heading up to its last message: integrate from there on.
            odometry_ended = not self._integrating and self._odom_yaw is not None
            since = self._odom_time if odometry_ended else previous
            self._heading += self._angular * (time - since)
        self._integrating = True

    def _decide(self, time: float) -> tuple[float, float]:
        config = self.config
        if self.state == 'turning':
            remaining = self._turn_target - self.turned
            if remaining > 0.0:
                # Brake on a constant-deceleration profile so the turn ends on its angle.
                rate = min(config.turn_speed, math.sqrt(2.0 * config.turn_decel * remaining))
                return 0.0, self._turn_direction * max(rate, MIN_TURN_RATE)
            self.turns_deg.append(math.degrees(self.turned))
            self.state = 'settling'
            self._turn_ended = time
            return 0.0, 0.0
        fresh = self._scan is not None and time - self._scan_time <= config.scan_timeout
        if not fresh or (self.state == 'settling' and self._scan_time <= self._turn_ended):
            return 0.0, 0.0
        points = obstacle_points(self._scan)
        # Leaving a turn needs a longer clear corridor than driving on does: without this
        # margin a corridor just clear would block again after a few centimetres.
        length = config.obstacle_distance + (SETTLE_MARGIN if self.state == 'settling' else 0.0)
        blocked = corridor_distance(points, length, config.robot_radius, config.corridor_margin)
        if blocked is None:
            if self.state != 'driving':
                self._on_event('way clear: driving')
            self.state = 'driving'
            return config.speed, 0.0
        if self.state == 'settling':
            self._turn_again(points)
        else:
            self._turn_away(blocked, time)
        return self._decide(time)

    def _random_turn(self) -> float:
        """Return the angle (rad) of a new turn by the configured mode."""
        config = self.config
        if config.turn_mode == 'random':
            return math.radians(self._random.uniform(config.min_turn_deg, config.max_turn_deg))
        return math.radians(config.turn_deg)

    def _start_turn(self, angle: float, reason: str) -> None:
        self._turn_target = angle
        self._turn_start = self._heading
        self.state = 'turning'
        side = 'left' if self._turn_direction > 0 else 'right'
        self._on_event(f'{reason}: turning {side} by {math.degrees(angle):.0f} deg')

    def _turn_away(self, distance: float, time: float) -> None:
        """
        Start a manoeuvre: a turn of the configured mode, towards the more open side.

        Right after another turn, the same way: turns this close together are one manoeuvre
        to an observer, and opposite turns would undo each other.
        """
        if time - self._turn_ended > SAME_MANOEUVRE_S:
            self._turn_direction = open_side(self._scan) or self._random.choice((-1, 1))
        self._start_turn(self._random_turn(), f'obstacle {distance:.2f} m ahead')

    def _turn_again(self, points: np.ndarray) -> None:
        """
        Still blocked after a turn: turn on the same way, to the nearest heading not blocked.

        The manoeuvre has already turned by more than its minimum, so the shortest further turn
        is best: to the first heading (up to half a turn) whose corridor, lengthened, holds
        none of the scan's points. Beyond the field of view nothing is known, so such a heading
        may turn out blocked too, and the robot turns on from there.
        """
        config = self.config
        angle = clear_turn(points, self._turn_direction, config.obstacle_distance + SETTLE_MARGIN,
                           config.robot_radius, config.corridor_margin, math.pi)
        # One step past the first clear heading lands inside the clear sector, not on its edge.
        self._start_turn(math.pi if angle is None else angle + TURN_STEP, 'still blocked')
