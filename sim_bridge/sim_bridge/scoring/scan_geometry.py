"""
The grader's own scan geometry: where each beam looks, the lab's five regions, capped readings.

What a node's printed values and its motion are judged against (sim_bridge.scoring.printed_values,
sim_bridge.scoring.motion_evidence) is the grader's, never the student's package's: a student
makes a ``scan_pkg`` of their own (the handout's ``ros2 pkg create``), which takes the kit's
place on the path, so sim_bridge imports nothing of scan_pkg. This module is that reference,
kept to what the grader asks of a recorded scan: beam bearings, readings capped at a distance,
the range straight ahead and the nearest valid return, and the bands of the lab's regions.

The kit's nodes keep their own, richer :mod:`scan_pkg.laser` (a range at any bearing, cached
windows per geometry, a node's input refused field by field) rather than sharing this one: a
student's node may import scan_pkg's library in its sandbox, whereas this module is an answer
key (its bands are what task 3 prints) hidden from every node's run in bubblewrap
(sim_bridge.runner.boundary.outside.kit_answers), so the library a node reads cannot be built
on it.

Conventions as REP-103 and REP-117 state them, and scan_pkg.laser follows: beam ``i`` looks at
``angle_min + i * angle_increment`` (rad, CCW from straight ahead); a reading is valid when
finite and within ``[range_min, range_max]`` (m); capping makes +inf and readings beyond the cap
the cap, -inf and readings below ``range_min`` the ``range_min``, and leaves NaN (no
information) NaN. Pure numpy.
"""

from dataclasses import dataclass
import math
from typing import Any

import numpy as np

#: Two bearings closer than this (rad) are the same bearing.
ANGLE_TOLERANCE = 1e-9
#: The lab's five regions, right to left.
REGION_NAMES = ('right', 'front_right', 'front', 'front_left', 'left')
#: The bearing (rad) of each region's centre, in REGION_NAMES' order.
REGION_CENTRES = tuple(math.radians(degrees) for degrees in (-72.0, -36.0, 0.0, 36.0, 72.0))
#: Half a region's width (rad): each is 36 degrees wide.
REGION_HALF_WIDTH = math.radians(18.0)


def bearing_difference(first: float, second: float) -> float:
    """Return how far apart two bearings (rad) are, modulo 2 pi: in [0, pi] (rad)."""
    return abs(math.remainder(first - second, 2.0 * math.pi))


@dataclass(frozen=True)
class RecordedScan:
    """
    One recorded laser scan as the grader reads it: ranges (m) on beams at even bearings (rad).

    Built from the simulator's own scans (a ``run_trace.ScanSnapshot``), never a node's.
    """

    ranges: np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float

    @classmethod
    def of(cls, snapshot: Any) -> 'RecordedScan':
        """Return the scan of anything with a LaserScan's fields (a ``ScanSnapshot``)."""
        return cls(np.asarray(snapshot.ranges, dtype=np.float64), float(snapshot.angle_min),
                   float(snapshot.angle_increment), float(snapshot.range_min),
                   float(snapshot.range_max))

    def __len__(self) -> int:
        return len(self.ranges)

    def angles(self) -> np.ndarray:
        """Return each beam's bearing as the scan gives it, ``angle_min + i * increment`` (rad)."""
        return self.angle_min + np.arange(len(self.ranges)) * self.angle_increment

    def bearings(self) -> np.ndarray:
        """Return each beam's bearing wrapped into [-pi, pi) (rad)."""
        return np.mod(self.angles() + math.pi, 2.0 * math.pi) - math.pi

    def capped(self, cap: float) -> np.ndarray:
        """Return the readings capped at ``cap`` (m) as the module's docstring says; NaN kept."""
        return np.minimum(np.maximum(self.ranges, self.range_min), cap)

    def range_ahead(self, half_width: float, cap: float) -> float:
        """
        Return the smallest capped reading (m) within ``half_width`` (rad) of straight ahead.

        The beams nearest straight ahead always count (both when two are equally near, none
        more than half an increment away); NaN readings do not. With none: the cap (m).
        """
        if not len(self.ranges):
            return cap
        away = np.abs(self.bearings())
        nearest = (away <= away.min() + ANGLE_TOLERANCE) & (
            away <= abs(self.angle_increment) / 2.0 + ANGLE_TOLERANCE)
        values = self.capped(cap)[nearest | (away <= half_width + ANGLE_TOLERANCE)]
        values = values[~np.isnan(values)]
        return float(values.min()) if len(values) else cap

    def closest(self) -> tuple[float, float] | None:
        """Return (range m, bearing rad) of the nearest valid return, the lowest of equal beams."""
        ranges = self.ranges
        with np.errstate(invalid='ignore'):
            valid = np.isfinite(ranges) & (ranges >= self.range_min) & (ranges <= self.range_max)
        if not valid.any():
            return None
        index = int(np.argmin(np.where(valid, ranges, np.inf)))
        return float(ranges[index]), float(self.bearings()[index])
