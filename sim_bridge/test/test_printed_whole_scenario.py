"""
Printed values scored over the whole scenario: a stopped node's scans, wrong beams, long lines.

A line counts for a scan only when its value is the one asked for, within RIGHT_WITHIN_M; the
scans a run did not reach (its node raised, exited, hung or was stopped) are scans with no
line; values that are another beam's or region's are named as such; a printed line is read
only up to LINE_CHARS characters (its speed: test/bench/bench_printed_text.py).
"""

import numpy as np
import pytest

from sim_bridge.grading.task_points import judge_points
from sim_bridge.scoring import printed_text
from sim_bridge.scoring.printed_text import LINE_CHARS, read_range_ahead
from sim_bridge.scoring.printed_values import RIGHT_WITHIN_M, score_printed
from sim_bridge.scoring.run_trace import ScanSnapshot

BEAMS, ANGLE_MIN, ANGLE_MAX = 36, -1.57, 1.57
INCREMENT = (ANGLE_MAX - ANGLE_MIN) / (BEAMS - 1)
PERIOD = 0.1  # s, the lab lidar's


def snapshot(ranges, t):
    return ScanSnapshot(t, (0.0, 0.0, 0.0), np.array(ranges, dtype=np.float32), ANGLE_MIN,
                        INCREMENT, 0.12, 10.0)


def approach(count=10):
    """Return scans of a robot nearing a wall ahead (beams 17, 18), a post on its right."""
    scans = []
    for index in range(count):
        ranges = [3.0] * BEAMS
        ranges[17] = ranges[18] = 2.0 - 0.1 * index
        ranges[0] = 0.5 + 0.05 * index
        scans.append(snapshot(ranges, PERIOD * (index + 1)))
    return scans


def line(t, text):
    return {'t': t, 'node': 'scan_ahead', 'level': 'INFO', 'text': text, 'line': text}


def test_the_scans_after_a_node_stopped_are_scans_with_no_line():
    scans = approach()
    lines = [line(snap.time, f'Range ahead: {snap.ranges[18]:.2f}') for snap in scans]
    scored = score_printed('range_ahead', scans, lines, not_run_s=2.0, scan_period_s=PERIOD)
    assert (scored['scans'], scored['not_run'], scored['missed']) == (30, 20, 20)
    assert (scored['right'], scored['parts_right']) == (10, 4)
    assert scored['right_fraction'] == pytest.approx(1 / 3)
    assert scored['last_scan_s'] == pytest.approx(1.0)
    whole = score_printed('range_ahead', scans, lines, not_run_s=0.0, scan_period_s=PERIOD)
    assert (whole['scans'], whole['right'], whole['parts_right']) == (10, 10, 10)


def test_the_rightmost_beam_printed_as_ahead_counts_for_no_scan_and_is_named():
    scans = approach()
    lines = [line(snap.time, f'Front distance: {snap.ranges[0]:.2f} m') for snap in scans]
    scored = score_printed('range_ahead', scans, lines)
    assert (scored['lines'], scored['missed'], scored['right']) == (10, 0, 0)
    assert scored['matches'] == [{'what': 'range ahead', 'lines': 10, 'of': 10,
                                  'source': 'beam 0 (angle -1.57 rad, the rightmost)'}]
    points = judge_points('range_ahead', {'printed': {'range_ahead': scored}})
    assert not any(point.earned for point in points)
    for point in points:
        assert point.reason.endswith('the printed values match beam 0 (angle -1.57 rad, the '
                                     'rightmost), not the beam ahead'), point.reason
        assert f'{RIGHT_WITHIN_M:g} m' in point.rule


def test_a_value_off_by_more_than_the_tolerance_counts_for_no_scan():
    scans = approach()
    lines = [line(snap.time, f'Range ahead: {snap.ranges[18] + 0.08:.2f}') for snap in scans]
    scored = score_printed('range_ahead', scans, lines)
    assert (scored['missed'], scored['right']) == (0, 0)


def test_a_region_printed_under_another_regions_name_is_named():
    scans = []
    for index in range(10):
        ranges = [3.0] * BEAMS
        ranges[24] = 1.0 + 0.1 * index  # front-left: 36 deg bands, beam 24 at +29 deg
        scans.append(snapshot(ranges, PERIOD * (index + 1)))
    lines = [line(snap.time, f'R: 3.00 FR: 3.00 F: 3.00 FL: 3.00 L: {snap.ranges[24]:.2f}')
             for snap in scans]
    scored = score_printed('regions', scans, lines)
    assert scored['right'] == 0
    # The 3.00 printed as front-left is every other region's, and most beams': no one source.
    assert [(match['what'], match['source']) for match in scored['matches']] == [
        ('left', 'the front-left region')]


def test_a_node_right_on_every_scan_but_silent_after_half_the_run_loses_printed_right():
    scans = approach(20)
    lines = [line(snap.time, f'{snap.ranges[17]:.2f} m') for snap in scans[:10]]
    points = judge_points('range_ahead', {'printed': {'range_ahead': score_printed(
        'range_ahead', scans, lines)}})
    assert [point.earned for point in points] == [False, False]
    assert points[1].reason == "right values in 5 of the scenario's 10 parts only"


def test_a_line_is_read_up_to_its_cap_only():
    padding = 'x' * LINE_CHARS
    assert read_range_ahead(f'{padding} Range ahead: 1.5') is None
    assert read_range_ahead(f'Range ahead: 1.5 {padding}').value == 1.5


class ScannedLengths:
    """A compiled pattern that notes the length of each text it substitutes in."""

    def __init__(self, pattern):
        self.pattern, self.lengths = pattern, []

    def sub(self, replace, text):
        self.lengths.append(len(text))
        return self.pattern.sub(replace, text)


def test_a_line_of_12000_numbers_on_every_scan_is_read_up_to_its_cap_only(monkeypatch):
    """Bounded work per line, whatever its length (the speed: test/bench/bench_printed_text)."""
    scans = approach()
    dump = 'ranges: ' + ', '.join(['1.234'] * 12000)
    lines = [line(snap.time, dump) for snap in scans]
    scanned = ScannedLengths(printed_text._INDEXED)
    monkeypatch.setattr(printed_text, '_INDEXED', scanned)
    score_printed('range_ahead', scans, lines)
    assert len(scanned.lengths) >= len(lines) and max(scanned.lengths) <= LINE_CHARS
