"""
Wall following: keep an obstacle on one side at a set distance, round convex and concave shapes.

Pure: no rclpy. :class:`WallFollower` is fed scans (:class:`scan_pkg.laser.Scan`) with their
arrival times (s) and answers ``(linear m/s, angular rad/s)`` as Python floats.

The controller works in a canonical frame where the wall is on the right (clockwise around an
obstacle); for ``side='left'`` the scan points are mirrored (y -> -y) on the way in and the turn
rate on the way out, so a mirrored scan gives exactly the mirrored command.

Wall estimate (:func:`estimate_wall`): the nearest return, and a total-least-squares line through
the returns within ``fit_radius`` of it. When the robot's foot on that line lies on the returns
(or less than ``extrapolation`` beyond them, since a +-90 deg scanner cannot see the part of a
wall beside and behind the robot), the wall is that line: distance = perpendicular distance,
direction = the line's. Otherwise the nearest returns end at an outside corner: the wall is the
corner point, and the robot should circle it.

Steering: the desired heading is the wall's tangent turned towards the wall by
``atan(error / lookahead)`` -- the bearing of the point ``lookahead`` m ahead on the line at the
set distance -- and the turn rate is ``heading_gain`` times the heading error, plus the rate of
the arc around a corner point. For small errors this is a PD law on the distance error (P gain
``heading_gain / lookahead``, D through the wall angle). The speed falls with the heading error
(slow in turns, turn in place beyond 90 deg) and with the free space ahead.

Cases: a wall ahead (inside corner) becomes the nearest return and turns the robot away; a wall
lost (outside corner: nothing within ``distance + lost_margin``) makes the robot arc towards its
side at the last distance until the wall reappears, and search after a full circle; searching,
it heads for the nearest return, and with nothing in sight turns half a circle to look behind,
then drives straight on.
"""

from dataclasses import dataclass
import math
from typing import Callable, NamedTuple

import numpy as np

from scan_pkg.behaviors import require
from scan_pkg.behaviors.wander import corridor_distance, obstacle_points
from scan_pkg.laser import normalize_angle, Scan

SIDES = ('right', 'left')
"""Values of ``WallFollowConfig.side``."""


class WallEstimate(NamedTuple):
    """
    The wall as seen from the robot, in the canonical (wall on the right) frame.

    ``distance``: from the laser to the wall (m). ``direction``: bearing (rad) of the wall's
    tangent, oriented so that the wall is on its right; 0 means parallel to the robot's heading.
    ``corner``: True when the nearest part of the wall is an outside corner point.
    """

    distance: float
    direction: float
    corner: bool


def estimate_wall(points: np.ndarray, fit_radius: float,
                  extrapolation: float) -> WallEstimate | None:
    """
    Estimate the nearest wall from returns ``points`` ((N, 2) x, y in m, wall on the right).

    None when there are no points. ``fit_radius`` (m): returns this close to the nearest one
    make up the wall's line. ``extrapolation`` (m): how far beyond its visible returns a line
    is assumed to go on.
    """
    if not len(points):
        return None
    nearest = points[np.hypot(points[:, 0], points[:, 1]).argmin()]
    # The returns within fit_radius of the nearest (compress selects rows as [mask] does, faster).
    apart = points - nearest
    near = points.compress(np.hypot(apart[:, 0], apart[:, 1]) <= fit_radius, axis=0)
    if len(near) < 2:
        return _corner_estimate(*nearest.tolist())
    centre = near.sum(axis=0) / len(near)
    spread = near - centre
    if not np.count_nonzero(spread):
        return _corner_estimate(*nearest.tolist())
    # The line's direction is the principal axis of the returns: closed form for 2-D.
    xs, ys = spread[:, 0], spread[:, 1]
    axis = 0.5 * math.atan2(2.0 * float(xs.dot(ys)), float(xs.dot(xs) - ys.dot(ys)))
    cos, sin = math.cos(axis), math.sin(axis)
    # Orient the line like the tangent (-y, x) of a circle around the robot through the nearest
    # return: the wall on its right.
    nearest_x, nearest_y = nearest.tolist()
    if sin * nearest_x - cos * nearest_y < 0.0:
        cos, sin = -cos, -sin
    # Positions (m) along the line, from the centre of the returns: theirs, in order, and the
    # robot's foot.
    offsets = spread.dot(np.array([cos, sin]))
    offsets.sort()
    first, last = offsets.item(0), offsets.item(-1)
    centre_x, centre_y = centre.tolist()
    foot = -(centre_x * cos + centre_y * sin)
    if first - extrapolation <= foot <= last + extrapolation:
        distance = abs(cos * centre_y - sin * centre_x)
        return WallEstimate(distance, math.atan2(sin, cos), False)
    end = min(max(foot, first), last)
    return _corner_estimate(centre_x + end * cos, centre_y + end * sin)


def _corner_estimate(x: float, y: float) -> WallEstimate:
    """Return the wall as the corner point ``(x, y)`` (m), circled clockwise."""
    # numpy's hypot, as for the returns' ranges: a corner that is the nearest return alone is
    # exactly as far as that return.
    return WallEstimate(float(np.hypot(x, y)), normalize_angle(math.atan2(y, x) + math.pi / 2),
                        True)


@dataclass(frozen=True)
class WallFollowConfig:
    """
    Parameters of :class:`WallFollower`, with the wall_follow node's defaults.

    ``side``: 'right' (wall on the right: clockwise around an obstacle) or 'left'.
    Distances in m, speeds in m/s, rates in rad/s, gains in 1/s, times in s.
    """

    side: str = 'right'
    distance: float = 0.5
    speed: float = 0.3
    lookahead: float = 0.4
    heading_gain: float = 2.0
    max_angular: float = 1.5
    robot_radius: float = 0.15
    stop_margin: float = 0.1
    lost_margin: float = 0.5
    fit_radius: float = 0.2
    extrapolation: float = 0.12
    corner_speed: float = 0.2
    scan_timeout: float = 0.5

    def __post_init__(self):
        if self.side not in SIDES:
            raise ValueError(f"side must be one of {', '.join(SIDES)}, got {self.side!r}")
        require(self, positive=('distance', 'lookahead', 'heading_gain', 'max_angular',
                                'lost_margin', 'fit_radius', 'scan_timeout', 'corner_speed'),
                non_negative=('speed', 'robot_radius', 'stop_margin', 'extrapolation'))


class WallFollower:
    """
    The wall follower: its ``mode`` is ``searching``, ``following`` or ``cornering``.

    Feed it with :meth:`update_scan`, ask :meth:`command` after each scan. ``wall`` is the
    last :class:`WallEstimate` (None with nothing in sight). ``on_event`` receives a short
    text whenever the mode changes, for logging. The nearest obstacle is the wall, on
    whichever side it is: one on the wrong side is turned round to.
    """

    def __init__(self, config: WallFollowConfig | None = None,
                 on_event: Callable[[str], None] | None = None):
        self.config = config or WallFollowConfig()
        self.mode = 'searching'
        self.wall = None
        self._on_event = on_event or (lambda text: None)
        self._mirror = -1.0 if self.config.side == 'left' else 1.0
        self._scan = None
        self._scan_time = -math.inf
        self._command_time = None
        self._last_distance = self.config.distance
        self._corner_turned = 0.0
        self._search_turned = 0.0
        self._angular = 0.0

    def update_scan(self, scan: Scan, time: float) -> None:
        """Take the latest scan, received at ``time`` (s); a blind one (all NaN) is ignored."""
        if scan.is_blind():
            return
        self._scan = scan
        self._scan_time = time

    def command(self, time: float) -> tuple[float, float]:
        """
        Return ``(linear m/s, angular rad/s)`` for the latest scan at ``time`` (s).

        A zero command when there is no scan newer than ``scan_timeout``.
        """
        elapsed = 0.0 if self._command_time is None else time - self._command_time
        self._command_time = time
        if self._scan is None or time - self._scan_time > self.config.scan_timeout:
            linear, angular = 0.0, 0.0
        else:
            linear, angular = self._steer(self._scan, elapsed)
        self._angular = angular
        return float(linear), float(self._mirror * angular)

    def _set_mode(self, mode: str, text: str) -> None:
        if mode != self.mode:
            self.mode = mode
            self._on_event(text)

    def _steer(self, scan: Scan, elapsed: float) -> tuple[float, float]:
        config = self.config
        points = obstacle_points(scan)
        if config.side == 'left':
            points *= (1.0, -1.0)
        self.wall = estimate_wall(points, config.fit_radius, config.extrapolation)
        near = (self.wall is not None
                and self.wall.distance <= config.distance + config.lost_margin)
        if not near and self.mode != 'searching':
            self._corner_turned += abs(self._angular) * elapsed
            if self._corner_turned <= 2.0 * math.pi:
                self._set_mode('cornering', 'wall lost: arcing round the corner')
                return self._arc(min(config.corner_speed, config.speed), self._last_distance)
            self._set_mode('searching', 'no wall after a full circle: searching')
        if near:
            self._set_mode('following', f'following the wall on the {config.side}')
            self._corner_turned = 0.0
            self._last_distance = min(max(self.wall.distance, 0.5 * config.distance),
                                      2.0 * config.distance)
        if self.wall is None:
            return self._search(elapsed)
        self._search_turned = 0.0
        return self._follow(points, self.wall)

    def _search(self, elapsed: float) -> tuple[float, float]:
        """With nothing in sight, look behind by turning half a circle, then drive straight."""
        self._search_turned += abs(self._angular) * elapsed
        if self._search_turned < math.pi:
            return 0.0, -0.5 * self.config.max_angular
        return self.config.speed, 0.0

    def _arc(self, speed: float, radius: float) -> tuple[float, float]:
        """Arc towards the wall's side at ``speed`` (m/s) on ``radius`` (m)."""
        return speed, -min(speed / radius, self.config.max_angular)

    def _follow(self, points: np.ndarray, wall: WallEstimate) -> tuple[float, float]:
        config = self.config
        error = wall.distance - config.distance
        heading_error = normalize_angle(wall.direction - math.atan2(error, config.lookahead))
        linear = config.speed * max(math.cos(heading_error), 0.0)
        ahead = corridor_distance(points, config.distance + config.robot_radius,
                                  config.robot_radius, config.stop_margin)
        if ahead is not None:
            room = (ahead - config.robot_radius - config.stop_margin) / config.distance
            linear *= min(max(room, 0.0), 1.0)
        angular = config.heading_gain * heading_error
        if wall.corner:
            # The rate of the arc round the corner point; at the laser itself (a point-like
            # robot) the sharpest turn, as the clamp below would make of any near it.
            radius = max(wall.distance, config.robot_radius)
            angular -= linear / radius if radius > 0.0 else config.max_angular
        angular = min(max(angular, -config.max_angular), config.max_angular)
        return linear, angular
