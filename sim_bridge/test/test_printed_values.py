"""What students print is read back from the text and scored against the scans they received."""

import math

import numpy as np
import pytest

from scan_pkg.laser import Scan
from scan_pkg.report import closest_line, range_ahead_line, regions_line
from sim_bridge.scoring.printed_text import read_closest, read_range_ahead, read_regions
from sim_bridge.scoring.printed_values import (
    closest_truth, excerpt, judge_printed, range_ahead_truth, region_truths, score_printed)
from sim_bridge.scoring.run_trace import ScanSnapshot
from sim_bridge.scoring.scan_geometry import RecordedScan

# The lab's scanner: 36 beams from -1.57 to +1.57 rad; beams 17 and 18 are the two nearest
# straight ahead (+-2.6 deg), beam 0 points right (-90 deg), beam 35 left (+90 deg).
BEAMS, ANGLE_MIN, ANGLE_MAX = 36, -1.57, 1.57
INCREMENT = (ANGLE_MAX - ANGLE_MIN) / (BEAMS - 1)
RANGE_MIN, RANGE_MAX = 0.12, 10.0
INF = math.inf


def snapshot(ranges, time=0.0):
    return ScanSnapshot(time, (0.0, 0.0, 0.0), np.array(ranges, dtype=np.float32), ANGLE_MIN,
                        INCREMENT, RANGE_MIN, RANGE_MAX)


def scan(ranges):
    """Return the scan as the kit's nodes read it (what they print is made from it)."""
    return Scan(ranges, ANGLE_MIN, INCREMENT, RANGE_MIN, RANGE_MAX)


def recorded(ranges):
    """Return the scan as the grader reads it (the truth printed values are judged by)."""
    return RecordedScan.of(snapshot(ranges))


def line(t, text, node='reader', level='INFO'):
    return {'t': t, 'node': node, 'level': level, 'text': text,
            'line': f'[{level}] [0.0] [{node}]: {text}'}


@pytest.mark.parametrize('text, value', [
    ('Range ahead: 1.23 m', 1.23),
    ('Range ahead: 1.23', 1.23),
    ('range ahead = 1.230000', 1.23),
    ('F=1.2 m', 1.2),
    ('F: 1.2', 1.2),
    ('1.234', 1.234),
    ('1.234 m', 1.234),
    ('inf', INF),
    ('Range ahead: inf', INF),
    ('Range ahead: Infinity m', INF),
    ('front distance is 1.23', 1.23),
    ('Distance to obstacle ahead = 1.23m', 1.23),
    ('Obstacle ahead at 123 cm', 1.23),
    ('ranges[17] = 1.23', 1.23),
    ('msg.ranges[len(msg.ranges)//2]: 1.23', 1.23),
    ('scan 17: 1.23 m', 1.23),
    ('[scan_ahead] front: 0.57', 0.57),
    ('t=4.2 s, ahead 1.5', 1.5),
    ('The robot sees 1.5 m in front', 1.5),
    ('Range ahead: 42', 42.0),
    ('ahead:-0.5', -0.5),
])
def test_a_range_ahead_is_read_as_students_write_it(text, value):
    assert read_range_ahead(text).value == pytest.approx(value)


@pytest.mark.parametrize('text', [
    'Scan received', 'Node started', 'x=1 y=2', 'took 12 ms',
    'no valid reading among 36 beams (36 +inf (no return))', 'angle 35 deg',
])
def test_lines_without_a_range_ahead_give_none(text):
    assert read_range_ahead(text) is None


LAB_LINE = ('right: 0.88 m | front-right: 1.20 m | front: 2.00 m | front-left: 1.10 m | '
            'left: 10.00 m')
REGION_VALUES = {'right': 0.88, 'front_right': 1.2, 'front': 2.0, 'front_left': 1.1,
                 'left': 10.0}


@pytest.mark.parametrize('text', [
    LAB_LINE,
    'right=0.88 front_right=1.2 front=2.0 front_left=1.1 left=10.0',
    "{'right': 0.88, 'fright': 1.2, 'front': 2.0, 'fleft': 1.1, 'left': 10.0}",
    'R: 0.88 FR: 1.2 F: 2.0 FL: 1.1 L: 10.0',
    'Right 0.88, Front Right 1.2, Front 2.0, Front Left 1.1, Left 10.0',
    'left: 10.0 | front: 2.0 | right: 0.88 | front-left: 1.1 | front-right: 1.2',
    'min_right: 0.880 min_front_right: 1.200 min_front: 2.000 min_front_left: 1.100 '
    'min_left: 10.000',
    'Regions -> right: 0.88m, right front: 1.2m, front: 2m, left front: 1.1m, left: 10m',
    'right region is 0.88 m, front-right region is 1.2 m, front region is 2.0 m, '
    'front-left region is 1.1 m, left region is 10.0 m',
    'Right: 88 cm | Front-Right: 120 cm | Front: 200 cm | Front-Left: 110 cm | Left: 1000 cm',
    '0.88 1.2 2.0 1.1 10.0',
    '[0.88, 1.2, 2.0, 1.1, 10.0]',
])
def test_five_regions_are_read_in_any_order_and_spelling(text):
    assert {name: number.value for name, number in read_regions(text)} == \
        pytest.approx(REGION_VALUES)


@pytest.mark.parametrize('text, name, value', [
    ('Right: 0.88', 'right', 0.88),
    ('Front-right: 1.20 m', 'front_right', 1.2),
    ('FRONT_RIGHT = 1.2', 'front_right', 1.2),
    ('fr=1.2', 'front_right', 1.2),
    ('Front Left: inf', 'front_left', INF),
    ('front: 2.00', 'front', 2.0),
    ('left: 10', 'left', 10.0),
    ('Range ahead: 2.0', 'front', 2.0),  # the handout's scan_around: 'ahead' is the front
    ('Range front-left: 1.5', 'front_left', 1.5),
])
def test_a_region_on_a_line_of_its_own_is_read(text, name, value):
    assert [(found, number.value) for found, number in read_regions(text)] == [(name, value)]


@pytest.mark.parametrize('text', ['Turning left', 'front is clear', 'left: n/a',
                                  'ranges[28:35]', 'scan 12 received', '0.88 1.2 2.0 1.1',
                                  'regions at t=1.0 s: 1 2 3 4'])
def test_lines_without_a_region_value_give_none(text):
    assert read_regions(text) == []


@pytest.mark.parametrize('text, distance, bearing_deg', [
    ('Closest obstacle: 0.87 m at -35.0 deg', 0.87, -35.0),
    ('Closest obstacle: 0.87 m at +35.0 deg', 0.87, 35.0),
    ('closest: 0.87 at -0.61', 0.87, math.degrees(-0.61)),
    ('Nearest obstacle at 0.87 m, angle 1.2 rad', 0.87, math.degrees(1.2)),
    ('Closest 0.87m @ 45\u00b0', 0.87, 45.0),
    ('closest: 0.5, angle: 30', 0.5, 30.0),
    ('min distance 0.87 at index 12', 0.87, None),
    ('Closest obstacle is 0.87 meters away', 0.87, None),
    ('0.87', 0.87, None),
    ('No valid obstacle readings.', INF, None),
    ('nothing in range', INF, None),
    ('Obstacle at 0.87 m', 0.87, None),
    ('distance=0.87 bearing=-20.0 degrees', 0.87, -20.0),
])
def test_the_closest_obstacle_is_read_with_its_bearing(text, distance, bearing_deg):
    printed, bearing = read_closest(text)
    assert printed.value == pytest.approx(distance)
    if bearing_deg is None:
        assert bearing is None
    else:
        assert math.degrees(bearing) == pytest.approx(bearing_deg)


def test_the_truth_ahead_is_any_beam_within_one_increment():
    ranges = [5.0] * BEAMS
    ranges[17], ranges[18] = 1.2, 1.4
    ranges[16] = ranges[19] = 0.5  # 7.7 deg off: not ahead
    assert range_ahead_truth(recorded(ranges)) == pytest.approx((1.2, 1.4))
    ranges[17] = INF
    ranges[18] = 20.0
    assert range_ahead_truth(recorded(ranges)) == (10.0, 10.0)


def test_a_beam_on_a_shared_edge_is_in_either_region_and_the_last_beam_in_left():
    ranges = [5.0] * BEAMS
    ranges[21] = 1.0  # +17.99 deg: front or front-left
    ranges[35] = 0.5  # +89.95 deg: left only
    truths = region_truths(recorded(ranges))
    assert truths['front'] == (1.0, 5.0)
    assert truths['front_left'] == (1.0, 5.0)
    assert truths['left'] == (0.5, 0.5)
    assert truths['right'] == (5.0, 5.0)


@pytest.mark.parametrize('kind, node_line', [
    ('range_ahead', lambda truth: range_ahead_line(truth, 10.0)),
    ('regions', lambda truth: regions_line(truth.regions(10.0))),
    ('closest', closest_line),
])
def test_the_lab_nodes_own_lines_score_no_more_than_their_rounding(kind, node_line):
    rng = np.random.default_rng(3)
    scans, lines = [], []
    for index in range(20):
        ranges = rng.uniform(0.3, 9.0, BEAMS)
        ranges[rng.integers(0, BEAMS, 5)] = INF
        snap = snapshot(ranges, 0.1 * index)
        scans.append(snap)
        lines.append(line(snap.time, node_line(scan(snap.ranges))))
    scored = score_printed(kind, scans, lines)
    assert (scored['lines'], scored['missed']) == (20, 0)
    assert scored['worst_error_m'] <= 0.005 + 1e-6  # printed to the centimetre
    assert judge_printed(kind, scored, max_error_m=0.01, min_matched_fraction=1.0,
                         max_bearing_error_deg=0.1)[0]
    if kind == 'closest':
        assert scored['worst_bearing_error_deg'] < 0.06  # printed to 0.1 deg


def scans_and_truth(count=10):
    scans = []
    for index in range(count):
        ranges = [3.0] * BEAMS
        ranges[17] = ranges[18] = 1.0 + 0.1 * index
        ranges[0] = INF
        scans.append(snapshot(ranges, 0.1 * index))
    return scans


def test_a_constant_fails_with_the_worst_line_quoted():
    scans = scans_and_truth()
    lines = [line(snap.time, 'Range ahead: 42', node='scan_ahead') for snap in scans]
    scored = score_printed('range_ahead', scans, lines)
    assert scored['worst_error_m'] == pytest.approx(10.0 - 1.0)  # 42 is capped at 10 m
    passed, why = judge_printed('range_ahead', scored, max_error_m=0.05,
                                min_matched_fraction=0.9)
    assert not passed
    assert why == ('scan_ahead: range ahead printed 42 at t=0.0 s, truth 1.00 m: '
                   "'Range ahead: 42' (worst of 10 lines; 0 of 10 scans with no line)")


def test_reading_beam_0_fails_and_inf_for_no_return_is_right():
    scans = scans_and_truth()
    lines = [line(snap.time, f'Range ahead: {float(snap.ranges[0])}') for snap in scans]
    scored = score_printed('range_ahead', scans, lines)
    assert scored['worst_error_m'] == pytest.approx(9.0)
    open_space = [snapshot([INF] * BEAMS, 0.0)]
    assert score_printed('range_ahead', open_space,
                         [line(0.0, 'Range ahead: inf')])['worst_error_m'] == 0.0


def test_printing_nothing_misses_every_scan():
    scored = score_printed('range_ahead', scans_and_truth(), [line(0.0, 'Node started')])
    assert scored['missed'] == 10
    assert judge_printed('range_ahead', scored, max_error_m=0.05, min_matched_fraction=0.9) \
        == (False, 'no line printed the range ahead (10 scans)')


def test_a_line_is_about_the_last_scan_at_or_before_it():
    scans = scans_and_truth(3)  # ahead: 1.0 at 0.0 s, 1.1 at 0.1 s, 1.2 at 0.2 s
    lines = [line(0.0, '1.0'), line(0.15, '1.1'), line(0.2, '1.2'), line(-0.1, '5.0')]
    scored = score_printed('range_ahead', scans, lines)
    assert (scored['lines'], scored['missed']) == (3, 0)
    assert scored['worst_error_m'] == pytest.approx(0.0, abs=1e-6)  # float32 ranges
    late = score_printed('range_ahead', scans, [line(0.1, '1.0'), line(0.2, '1.2')])
    assert late['missed'] == 1
    assert late['worst_error_m'] == pytest.approx(0.1)


def test_some_scans_missed_fail_on_the_fraction():
    scans = scans_and_truth()
    lines = [line(snap.time, f'{snap.ranges[17]:.2f}') for snap in scans[::2]]
    scored = score_printed('range_ahead', scans, lines)
    assert scored['matched_fraction'] == 0.5
    passed, why = judge_printed('range_ahead', scored, max_error_m=0.05,
                                min_matched_fraction=0.9)
    assert not passed
    assert why.startswith('reader: 5 of 10 scans with no line giving the range ahead (50 % '
                          'printed, 90 % wanted')


def test_stderr_and_the_simulator_are_not_what_a_node_prints():
    scans = scans_and_truth(1)
    lines = [line(0.0, 'File "scan_ahead.py", line 23', level='STDERR'),
             line(0.0, 'cmd_vel: 5', node='sim_bridge'), line(0.0, '1.0')]
    scored = score_printed('range_ahead', scans, lines, ignore_nodes={'sim_bridge'})
    assert (scored['lines'], scored['worst_error_m']) == (1, 0.0)


def test_the_handouts_five_labelled_lines_make_one_scan():
    scans = [snapshot([2.0] * BEAMS, 0.0)]
    names = ('ahead', 'right', 'front-right', 'front-left', 'left')  # its order and words
    scored = score_printed('regions', scans, [line(0.0, f'Range {name}: 2.0') for name in names])
    assert (scored['lines'], scored['missed'], scored['unprinted']) == (5, 0, [])


def test_five_lines_per_scan_make_one_scan_and_a_missing_region_is_named():
    scans = [snapshot([2.0] * BEAMS, 0.0), snapshot([2.0] * BEAMS, 0.1)]
    names = ('Right', 'Front-Right', 'Front', 'Front-Left', 'Left')
    lines = [line(0.0, f'{name}: 2.00') for name in names]
    lines += [line(0.1, f'{name}: 2.00') for name in names[:4]]
    scored = score_printed('regions', scans, lines)
    assert (scored['lines'], scored['missed'], scored['worst_error_m']) == (9, 1, 0.0)
    assert scored['unprinted'] == []


def test_the_lab_handouts_regions_drop_beam_35():
    ranges = [5.0] * BEAMS
    ranges[35] = 0.6  # something abeam on the left, only the last beam sees it
    snap = snapshot(ranges)
    handout = np.array(snap.ranges, dtype=float)
    regions = [min(handout[0:7]), min(handout[7:14]), min(handout[14:21]),
               min(handout[21:28]), min(handout[28:35])]
    text = ' | '.join(f'{name}: {value:.2f}' for name, value in zip(
        ('right', 'front-right', 'front', 'front-left', 'left'), regions))
    scored = score_printed('regions', [snap], [line(4.2, text, node='scan_around')])
    passed, why = judge_printed('regions', scored, max_error_m=0.05, min_matched_fraction=0.9)
    assert not passed
    assert why.startswith('scan_around: left printed 5.00 at t=4.2 s, truth 0.60 m: ')
    fixed = text[:text.rindex('5.00')] + f'{min(handout[28:36]):.2f}'
    assert judge_printed('regions', score_printed('regions', [snap], [line(0.0, fixed)]),
                         max_error_m=0.05, min_matched_fraction=0.9)[0]


def test_a_wrong_bearing_fails_a_closest_criterion_that_checks_it():
    ranges = [5.0] * BEAMS
    ranges[10] = 0.9  # -1.57 + 10 * increment: -38.6 deg
    snap = snapshot(ranges)
    assert closest_truth(recorded(snap.ranges))[0] == pytest.approx(0.9)
    scored = score_printed('closest', [snap], [line(0.0, 'Closest: 0.90 m at 38.6 deg')])
    assert scored['worst_error_m'] < 1e-6
    passed, why = judge_printed('closest', scored, max_error_m=0.05, min_matched_fraction=0.9,
                                max_bearing_error_deg=6.0)
    assert not passed
    assert why == ("reader: closest obstacle's bearing 'Closest: 0.90 m at 38.6 deg' at "
                   't=0.0 s, truth -38.6 deg (error 77.2 deg, worst of 1 lines with a bearing)')
    assert judge_printed('closest', scored, max_error_m=0.05, min_matched_fraction=0.9)[0]


def test_nothing_in_range_is_right_when_nothing_is():
    snap = snapshot([INF] * BEAMS)
    scored = score_printed('closest', [snap], [line(0.0, 'No valid obstacle readings.')])
    assert (scored['lines'], scored['worst_error_m']) == (1, 0.0)
    near = snapshot([0.5] * BEAMS)
    scored = score_printed('closest', [near], [line(0.0, 'No valid obstacle readings.')])
    assert scored['worst_error_m'] == pytest.approx(9.5)


def test_a_long_line_is_quoted_around_the_value_read():
    text = ("{'right': 10.0, 'fright': 10.0, 'front': 2.243856430053711, 'fleft': 10.0, "
            "'left': 10.0}")
    quoted = excerpt(text, text.rindex('10.0'))
    assert len(quoted) == 70
    assert quoted.startswith('...') and quoted.endswith("'left': 10.0}")
    assert excerpt(text, 1).startswith("{'right': 10.0") and excerpt(text, 1).endswith('...')
    assert excerpt('Range ahead: 1.23 m', 13) == 'Range ahead: 1.23 m'


def test_a_line_is_about_the_last_scan_at_or_before_its_time():
    scans = scans_and_truth(6)  # ahead: 1.0 at 0.0 s ... 1.5 at 0.5 s
    lines = [line(0.1, '1.10'), line(0.45, '1.40'), line(0.5, '1.50'), line(0.3, '1.20')]
    scored = score_printed('range_ahead', scans, lines)
    assert scored['worst_error_m'] == pytest.approx(0.1, abs=1e-6)  # 1.20 about 1.3 at 0.3 s
    assert (scored['lines'], scored['missed']) == (4, 2)  # no line at 0.0 s nor 0.2 s


@pytest.mark.parametrize('text', ['Range ahead: out of range', 'Range ahead: nan', 'Front: None',
                                  'out of range', 'No obstacle ahead', 'front: nothing'])
def test_a_word_for_no_return_reads_as_inf(text):
    assert read_range_ahead(text).value == INF


def test_a_word_for_no_return_reads_as_inf_in_a_region():
    assert {name: number.value for name, number in read_regions(
        'R: 0.88 FR: 1.2 F: out of range FL: nan L: none')} == {
        'right': 0.88, 'front_right': 1.2, 'front': INF, 'front_left': INF, 'left': INF}


#: The range straight ahead over a drive: near, beyond 3.5 m and 5 m, no return.
AHEAD = (1.0, 2.0, 3.2, 4.2, 6.5, 8.0, INF, INF, 0.6, INF)


def scans_ahead(range_max=RANGE_MAX):
    """Return scans of AHEAD straight ahead, no return beyond ``range_max`` (m) as a lidar."""
    scans = []
    for index, ahead in enumerate(AHEAD):
        ranges = [INF] * BEAMS
        ranges[17] = ranges[18] = ahead if ahead <= range_max else INF
        scans.append(ScanSnapshot(0.1 * index, (0.0, 0.0, 0.0), np.array(ranges, np.float32),
                                  ANGLE_MIN, INCREMENT, RANGE_MIN, range_max))
    return scans


def capped_at(cap):
    """Return a student's line for a range ahead, capped at ``cap`` (inf: not capped)."""
    return lambda ahead: f'Range ahead: {min(ahead, cap):.2f}'


def beyond_as(word):
    """Return a student's line that prints ``word`` for no return and the range otherwise."""
    return lambda ahead: f'Front: {word}' if ahead == INF else f'Front: {ahead:.2f} m'


@pytest.mark.parametrize('style, cap', [
    (capped_at(10.0), 10.0), (capped_at(3.5), 3.5), (capped_at(5.0), 5.0),
    (capped_at(12.0), 10.0), (capped_at(INF), 10.0), (beyond_as('out of range'), 10.0),
    (beyond_as('nan'), 10.0), (beyond_as('no obstacle'), 10.0)])
def test_a_range_ahead_capped_as_the_node_caps_it_is_right(style, cap):
    scans = scans_ahead()
    scored = score_printed('range_ahead', scans, [line(s.time, style(AHEAD[index]))
                                                  for index, s in enumerate(scans)])
    assert scored['cap_m'] == cap
    assert scored['worst_error_m'] < 0.005
    passed, why = judge_printed('range_ahead', scored, max_error_m=0.06,
                                min_matched_fraction=0.9)
    assert passed, why
    assert ('its own cap' in why) == (cap != 10.0)


@pytest.mark.parametrize('cap', [3.5, 10.0, INF])
def test_the_turtlebot3_range_max_is_a_cap_and_so_is_the_labs(cap):
    scans = scans_ahead(range_max=3.5)
    lines = [line(snap.time, capped_at(cap)(float(snap.ranges[18]))) for snap in scans]
    assert score_printed('range_ahead', scans, lines)['worst_error_m'] < 0.005


@pytest.mark.parametrize('printed, worst', [
    # Capped at 2 m: shorter than any lidar's range, so 2.00 for 4.2 m is wrong.
    (lambda ahead: f'{min(ahead, 2.0):.2f}', 8.0),
    # Its "cap" for no return, 3.5, but 6.50 printed for 6.5 m: not a cap it keeps.
    (lambda ahead: '3.5' if ahead == INF else f'{ahead:.2f}', 6.5),
    # Garbage: a finite number unrelated to the range ahead.
    (lambda ahead: f'{7.0 - ahead if ahead < 7.0 else 1.0:.2f}', 9.0),
])
def test_a_wrong_finite_number_is_wrong_whatever_the_cap(printed, worst):
    scans = scans_ahead()
    scored = score_printed('range_ahead', scans, [line(s.time, printed(AHEAD[index]))
                                                  for index, s in enumerate(scans)])
    assert scored['worst_error_m'] == pytest.approx(worst, abs=0.01)
    passed, why = judge_printed('range_ahead', scored, max_error_m=0.06,
                                min_matched_fraction=0.9)
    assert not passed
    assert '\n' not in why and why.startswith('reader: range ahead printed ')


def test_five_regions_capped_at_the_nodes_own_cap_are_right():
    scans = scans_ahead()
    lines = []
    for snap in scans:
        regions = scan(snap.ranges).regions(10.0).values()
        text = ' | '.join(f'{name}: {min(value, 5.0):.2f}' for name, value in zip(
            ('right', 'front-right', 'front', 'front-left', 'left'), regions))
        lines.append(line(snap.time, text))
    scored = score_printed('regions', scans, lines)
    assert (scored['cap_m'], scored['missed']) == (5.0, 0)
    assert scored['worst_error_m'] < 0.005
