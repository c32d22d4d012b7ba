"""
What a run leaves behind for scoring and plotting: the robot's ground-truth path and scans.

The runner appends one sample per physics step and every scan the lidar published; metrics (what
the nodes printed is compared with the scans they received) and plots read them. Pure: no
rclpy, no pybullet.
"""

from dataclasses import dataclass, field
import math

import numpy as np


@dataclass(frozen=True)
class ScanSnapshot:
    """
    A lidar scan as the nodes received it, and the pose it was taken from.

    ``time`` in s (the step that published it); ``pose`` (x m, y m, yaw rad) of the laser frame
    in the world; ``ranges`` in m (+inf for no return), as the message carried them (float32);
    beam i points at ``angle_min + i * angle_increment`` (rad) in the laser frame;
    ``range_min``/``range_max`` (m) the sensor's limits.
    """

    time: float
    pose: tuple[float, float, float]
    ranges: np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float = 0.0
    range_max: float = math.inf


@dataclass(frozen=True)
class CollisionEvent:
    """The start of a contact between the robot and an obstacle: time (s), place (m)."""

    time: float
    x: float
    y: float
    obstacle: str


#: The columns of a Trace, in the order of a sample's values.
TRACE_COLUMNS = ('time', 'x', 'y', 'yaw', 'linear', 'angular', 'clearance')


@dataclass
class Trace:
    """
    The robot's ground truth sampled at every physics step.

    Columns: ``time`` (s), ``x``/``y`` (m), ``yaw`` (rad), ``linear``/``angular`` (achieved
    velocity, m/s and rad/s), ``clearance`` (m, robot body to the nearest obstacle surface).
    """

    robot_radius: float
    samples: list[tuple[float, ...]] = field(default_factory=list)
    scans: list[ScanSnapshot] = field(default_factory=list)
    collisions: list[CollisionEvent] = field(default_factory=list)
    #: The time (s) between the lidar's scans, when known.
    scan_period_s: float | None = None
    _table: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def append(self, time: float, x: float, y: float, yaw: float, linear: float,
               angular: float, clearance: float) -> None:
        """Add one sample (units as in the class text)."""
        self.samples.append((time, x, y, yaw, linear, angular, clearance))

    def __len__(self) -> int:
        return len(self.samples)

    def array(self, name: str) -> np.ndarray:
        """Return column ``name`` (one of TRACE_COLUMNS) as a float array."""
        column = TRACE_COLUMNS.index(name)
        if self._table is None or len(self._table) != len(self.samples):
            self._table = np.array(self.samples, dtype=float).reshape(-1, len(TRACE_COLUMNS))
        return self._table[:, column]
