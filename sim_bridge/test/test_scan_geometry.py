"""
The grader's own scan geometry agrees with the kit's nodes' (scan_pkg.laser) on what both answer.

The grader judges by sim_bridge.scoring.scan_geometry, never by the package a student may
replace; the kit's reference nodes read scans with scan_pkg.laser. On the lab's scanner and on a
full turn, with inf, -inf, NaN and out-of-range readings, both give the same capped readings,
range straight ahead (one beam, and a cone) and nearest return.
"""

import math

import numpy as np
import pytest

from scan_pkg.laser import Scan
from sim_bridge.scoring.scan_geometry import bearing_difference, RecordedScan

#: (beams, angle_min rad, angle_increment rad): the lab's 36 beams over +-1.57 rad, a full turn.
GEOMETRIES = [(36, -1.57, 3.14 / 35), (360, 0.0, 2.0 * math.pi / 360)]
RANGE_MIN, RANGE_MAX = 0.12, 3.5


def random_ranges(beams: int, seed: int) -> np.ndarray:
    """Return readings (m) with every kind REP-117 allows, some beyond the limits."""
    generator = np.random.default_rng(seed)
    ranges = generator.uniform(0.0, 5.0, beams)
    odd = generator.choice(beams, beams // 4, replace=False)
    ranges[odd] = generator.choice([math.inf, -math.inf, math.nan, 0.05], len(odd))
    return ranges


@pytest.mark.parametrize('seed', range(20))
@pytest.mark.parametrize('beams, angle_min, increment', GEOMETRIES)
def test_the_graders_geometry_agrees_with_the_nodes(beams, angle_min, increment, seed):
    ranges = random_ranges(beams, seed)
    kit = Scan(ranges, angle_min, increment, RANGE_MIN, RANGE_MAX)
    grader = RecordedScan(ranges, angle_min, increment, RANGE_MIN, RANGE_MAX)
    np.testing.assert_array_equal(grader.capped(10.0), kit.capped(10.0))
    for half_width in (0.0, 0.35):
        assert grader.range_ahead(half_width, 10.0) == kit.range_at(0.0, half_width, 10.0)
    expected = kit.closest()
    if expected is None:
        assert grader.closest() is None
    else:
        distance, bearing = grader.closest()
        assert distance == expected[0]
        assert bearing_difference(bearing, expected[1]) < 1e-12


def test_a_scan_with_no_valid_return_has_no_closest_and_reads_the_cap_ahead():
    grader = RecordedScan(np.array([math.nan, math.inf, 0.01]), -0.1, 0.1, RANGE_MIN, RANGE_MAX)
    assert grader.closest() is None
    assert grader.range_ahead(0.0, 10.0) == 10.0
