"""
Drive the robot as a person at the teleop would: a list of segments, each held for a while.

A scenario's ``drive:`` (and ``run_simulation(..., drive=...)``) is a list of segments::

    drive:
      - {duration: 3, linear: 0.3}                     # forward at 0.3 m/s for 3 s
      - {duration: 2, angular: 0.8}                    # turn left on the spot, 0.8 rad/s
      - {duration: 15, linear: 0.2,                    # forward at 0.2 m/s until 0.4 m
         until: {within_m: 0.4, of: cube}}             # from the cube, for at most 15 s
      - {duration: 1}                                  # stand still 1 s

``duration`` (s, required, positive) is how long the segment lasts, or with ``until`` the
longest it may; ``linear`` (m/s, forward +) and ``angular`` (rad/s, counter-clockwise +)
default to 0. ``until: {within_m: D, of: NAME}`` ends the segment as soon as the robot's
centre is within D m of the surface of the world's obstacle NAME. After the last segment the
robot gets a zero command, and stays stopped. The simulator keeps the last command until the
next one, as Gazebo's diff drive does.

This module is the plan alone, plain numbers in and out: :func:`parse_drive` validates it
(a one-line :class:`DriveError` naming the segment and key) and :class:`DrivePlan` says what
to command at a time and pose. The runner's teleop node publishes it on ``cmd_vel``
(sim_bridge.runner.run).
"""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from sim_bridge.common.values import is_finite_number

#: Keys of a segment, and of its ``until``.
SEGMENT_KEYS = ('duration', 'linear', 'angular', 'until')
UNTIL_KEYS = ('within_m', 'of')


class DriveError(ValueError):
    """A drive plan that cannot be used; the message names the segment and the key."""


@dataclass(frozen=True)
class Segment:
    """
    One segment: ``linear`` (m/s) and ``angular`` (rad/s) for at most ``duration_s`` (s).

    With ``of`` (an obstacle's name), the segment ends once the robot's centre is within
    ``within_m`` (m) of that obstacle's surface.
    """

    duration_s: float
    linear: float = 0.0
    angular: float = 0.0
    within_m: float | None = None
    of: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """Return the segment in its YAML form."""
        entry: dict[str, Any] = {'duration': self.duration_s, 'linear': self.linear,
                                 'angular': self.angular}
        if self.of is not None:
            entry['until'] = {'within_m': self.within_m, 'of': self.of}
        return entry


def _number(value: Any, where: str, unit: str, *, positive: bool = False) -> float:
    """Return ``value`` as a finite float (> 0 when ``positive``); DriveError otherwise."""
    if not is_finite_number(value) or (positive and value <= 0):
        wanted = 'a positive number' if positive else 'a finite number'
        raise DriveError(f'{where}: must be {wanted} ({unit}), got {value!r}')
    return float(value)


def parse_segment(entry: Any, index: int) -> Segment:
    """Validate the segment ``drive[index]``; DriveError names it and its key."""
    where = f'drive[{index}]'
    if isinstance(entry, Segment):
        return entry
    if not isinstance(entry, Mapping):
        raise DriveError(f'{where}: must be a mapping such as {{duration: 2.0, linear: 0.2}}, '
                         f'got {entry!r}')
    for key in entry:
        if key not in SEGMENT_KEYS:
            raise DriveError(f'{where}.{key}: unknown key; a segment has '
                             f"{', '.join(SEGMENT_KEYS)}")
    if 'duration' not in entry:
        raise DriveError(f'{where}.duration: missing (s; with until, the longest it may take)')
    duration = _number(entry['duration'], f'{where}.duration', 's', positive=True)
    linear = _number(entry.get('linear', 0.0), f'{where}.linear', 'm/s')
    angular = _number(entry.get('angular', 0.0), f'{where}.angular', 'rad/s')
    until = entry.get('until')
    if until is None:
        return Segment(duration, linear, angular)
    if not isinstance(until, Mapping):
        raise DriveError(f'{where}.until: must be a mapping such as {{within_m: 0.4, of: cube}}, '
                         f'got {until!r}')
    for key in UNTIL_KEYS:
        if key not in until:
            raise DriveError(f'{where}.until.{key}: missing')
    for key in until:
        if key not in UNTIL_KEYS:
            raise DriveError(f'{where}.until.{key}: unknown key; until has '
                             f"{', '.join(UNTIL_KEYS)}")
    within = _number(until['within_m'], f'{where}.until.within_m', 'm', positive=True)
    name = until['of']
    if not isinstance(name, str) or not name:
        raise DriveError(f"{where}.until.of: must be an obstacle's name, got {name!r}")
    return Segment(duration, linear, angular, within, name)


def parse_drive(entries: Any) -> tuple[Segment, ...]:
    """Validate a drive plan (a list of segments); DriveError names the segment and key."""
    if not isinstance(entries, (list, tuple)) or not entries:
        raise DriveError(f'drive: must be a non-empty list of segments, got {entries!r}')
    return tuple(parse_segment(entry, index) for index, entry in enumerate(entries))


def check_obstacles(segments: Iterable[Segment], names: Iterable[str], world: str) -> None:
    """Raise DriveError when a segment's ``until`` names an obstacle ``world`` lacks."""
    names = list(names)
    for index, segment in enumerate(segments):
        if segment.of is not None and segment.of not in names:
            raise DriveError(f"drive[{index}].until.of: world '{world}' has no obstacle "
                             f"'{segment.of}'; its obstacles are {', '.join(names) or 'none'}")


class DrivePlan:
    """
    What to command when: the segments, each started when the previous one ended.

    ``distance(name, x, y)`` returns the distance (m) from the floor point (x, y) to the
    obstacle ``name``'s surface. ``missed`` says of each segment that ended at its duration
    before the robot came near its obstacle (the scenario's author wants to know).
    """

    def __init__(self, segments: Iterable[Segment],
                 distance: Callable[[str, float, float], float]):
        self.segments = tuple(segments)
        self.distance = distance
        self.index = 0
        self.started_s: float | None = None
        self.missed: list[str] = []

    @property
    def done(self) -> bool:
        """Return True once every segment has ended."""
        return self.index >= len(self.segments)

    def command(self, t_s: float, x: float, y: float) -> tuple[float, float] | None:
        """
        Return (linear m/s, angular rad/s) at sim time ``t_s`` (s), robot centre (x, y) (m).

        None once the plan is done. A segment starts at the first call after the previous
        one ended.
        """
        while not self.done:
            segment = self.segments[self.index]
            if self.started_s is None:
                self.started_s = t_s
            reached = segment.of is not None and \
                self.distance(segment.of, x, y) <= segment.within_m
            if not reached and t_s - self.started_s < segment.duration_s:
                return segment.linear, segment.angular
            if segment.of is not None and not reached:
                self.missed.append(
                    f'drive[{self.index}]: ended after its {segment.duration_s:g} s with the '
                    f'robot never within {segment.within_m:g} m of {segment.of}')
            self.index, self.started_s = self.index + 1, None
        return None
