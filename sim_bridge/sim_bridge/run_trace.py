"""
What a run leaves behind for scoring and plotting: the robot's ground-truth path and scans.

The runner appends one sample per physics step and keeps a scan now and then; metrics and plots
read the frozen arrays. Pure: no rclpy, no pybullet.
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ScanSnapshot:
    """
    A lidar scan and the pose it was taken from, for drawing.

    ``time`` in s; ``pose`` (x m, y m, yaw rad) of the laser frame in the world; ``ranges`` in m
    (+inf for no return); beam i points at ``angle_min + i * angle_increment`` (rad) in the
    laser frame.
    """

    time: float
    pose: tuple[float, float, float]
    ranges: np.ndarray
    angle_min: float
    angle_increment: float


@dataclass(frozen=True)
class CollisionEvent:
    """The start of a contact between the robot and an obstacle: time (s), place (m)."""

    time: float
    x: float
    y: float
    obstacle: str


@dataclass
class Trace:
    """
    The robot's ground truth sampled at every physics step.

    Columns: ``time`` (s), ``x``/``y`` (m), ``yaw`` (rad), ``linear``/``angular`` (achieved
    velocity, m/s and rad/s), ``clearance`` (m, robot body to the nearest obstacle surface).
    """

    robot_radius: float
    columns: dict[str, list[float]] = field(default_factory=lambda: {
        name: [] for name in ('time', 'x', 'y', 'yaw', 'linear', 'angular', 'clearance')})
    scans: list[ScanSnapshot] = field(default_factory=list)
    collisions: list[CollisionEvent] = field(default_factory=list)

    def append(self, **sample: float) -> None:
        """Add one sample; every column must be given."""
        if sample.keys() != self.columns.keys():
            raise KeyError(f'a trace sample needs exactly {sorted(self.columns)}')
        for name, value in sample.items():
            self.columns[name].append(float(value))

    def __len__(self) -> int:
        return len(self.columns['time'])

    def array(self, name: str) -> np.ndarray:
        """Return column ``name`` as a float array."""
        return np.asarray(self.columns[name], dtype=float)
