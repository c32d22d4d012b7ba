"""
What printed values that are not the asked-for value match instead: a beam, or another region.

A TA's most useful hint for a reading node whose values are wrong is what they are: "the printed
values match beam 0 (angle -1.57 rad, the rightmost), not the beam ahead" (``ranges[0]``, a
TurtleBot3 habit, on the lab's -1.57..1.57 rad lidar), or "the values printed as left match the
front-left region". :func:`matching_source` compares each printed value (already capped as the
node caps, m) with every beam's capped reading of its scan, and with every region's minimum;
the one source that holds for more values than any other, and for at least MOST of them,
is named.

Pure: numpy and the grader's scan geometry, no rclpy.
"""

import math
from typing import Callable, Sequence

import numpy as np

from sim_bridge.scoring.scan_geometry import RecordedScan as Scan, REGION_NAMES

#: The share of a label's printed values a beam or region must match to be named.
MOST = 0.9


def beam_name(index: int, angle: float, beams: int) -> str:
    """Return how a report names beam ``index`` at ``angle`` (rad) of a scan of ``beams``."""
    side = ''
    if index == 0 and beams > 1:
        side = ', the rightmost' if angle < 0.0 else ', the first'
    elif index == beams - 1 and beams > 1:
        side = ', the leftmost' if angle > 0.0 else ', the last'
    return f'beam {index} (angle {angle:+.2f} rad{side})'


def matching_source(values: Sequence[float], scans: Sequence[Scan], cap: float,
                    tolerance_m: float, regions: Callable[[Scan], dict] | None = None
                    ) -> tuple[str, int] | None:
    """
    Return (name, how many match) of the beam or region ``values`` (m) match, or None.

    ``values[i]`` was printed about ``scans[i]``; a beam matches a value when its reading,
    capped at ``cap`` (m), is within ``tolerance_m`` (m) of it; a region (``regions(scan)``
    gives each region's (lowest, highest) right minimum, m) when the value lies within
    ``tolerance_m`` of its bounds. Regions are tried first, then beams: the one source that
    matches more values than any other of its kind, and at least MOST of them, is named; a
    tie names none (a constant printed in an open view matches every beam).
    """
    if not values or len({len(scan) for scan in scans}) != 1:
        return None
    printed = np.asarray(values, dtype=float)
    groups = []
    if regions is not None:
        bounds = [regions(scan) for scan in scans]
        groups.append([(sum(1 for value, truth in zip(printed, bounds)
                            if truth.get(name) is not None
                            and truth[name][0] - tolerance_m <= value
                            <= truth[name][1] + tolerance_m),
                        f"the {name.replace('_', '-')} region") for name in REGION_NAMES])
    readings = np.stack([scan.capped(cap) for scan in scans])
    with np.errstate(invalid='ignore'):
        beam_counts = (np.abs(readings - printed[:, None]) <= tolerance_m).sum(axis=0)
    angles = scans[0].angles()
    groups.append([(int(matched), beam_name(index, float(angles[index]), len(angles)))
                   for index, matched in enumerate(beam_counts)])
    wanted = math.ceil(MOST * len(values))
    for counts in groups:
        ranked = sorted(counts, key=lambda item: -item[0])
        best = ranked[0]
        if best[0] >= wanted and (len(ranked) == 1 or ranked[1][0] < best[0]):
            return best[1], best[0]
    return None
