"""Tests of scan_pkg.report: what read_scan warns about, and the exact log lines of the nodes."""

import array
import inspect
import math
from types import SimpleNamespace

import pytest

from scan_pkg.laser import Scan
from scan_pkg.report import (
    closest_line, format_range, NO_OBSTACLE, positive_parameter, range_ahead_line, read_scan,
    regions_line, WARNING_PERIOD_S)

# The lab's scanner: 36 beams from -1.57 to +1.57 rad; beams 17 and 18 are the two nearest
# straight ahead (+-2.6 deg), beam 0 points right (-90 deg) and beam 35 left (+90 deg).
BEAMS, ANGLE_MIN, ANGLE_MAX = 36, -1.57, 1.57
INCREMENT = (ANGLE_MAX - ANGLE_MIN) / (BEAMS - 1)
RANGE_MIN, RANGE_MAX = 0.12, 10.0
INF, NAN = math.inf, math.nan


class FakeLogger:
    """Records every call as an rclpy logger receives it: (level, text, keyword options)."""

    def __init__(self):
        self.calls = []

    def _record(self, level, message, **options):
        assert isinstance(message, str), 'rclpy loggers take str messages only'
        self.calls.append((level, message, options))
        return True

    def info(self, message, **options):
        return self._record('INFO', message, **options)

    def warn(self, message, **options):
        return self._record('WARN', message, **options)

    def warning(self, message, **options):
        return self._record('WARN', message, **options)

    def error(self, message, **options):
        return self._record('ERROR', message, **options)

    def texts(self, level='WARN'):
        return [text for call_level, text, _ in self.calls if call_level == level]


def laser_msg(ranges, **fields):
    """Return a stand-in for sensor_msgs/msg/LaserScan from the lab's scanner."""
    message = {'angle_min': ANGLE_MIN, 'angle_max': ANGLE_MAX, 'angle_increment': INCREMENT,
               'range_min': RANGE_MIN, 'range_max': RANGE_MAX, 'ranges': ranges}
    message.update(fields)
    return SimpleNamespace(**message)


def reference_ranges():
    """Return ranges (m): an obstacle 1.23 m ahead, 0.80 m right, 2.50 m left; nothing else."""
    ranges = [INF] * BEAMS
    ranges[17] = ranges[18] = 1.23
    ranges[0] = 0.8
    ranges[35] = 2.5
    return ranges


def lab_scan(ranges):
    return Scan(ranges, ANGLE_MIN, INCREMENT, RANGE_MIN, RANGE_MAX)


# --- read_scan ---------------------------------------------------------------------------------

def test_read_scan_returns_a_good_scan_without_logging():
    logger = FakeLogger()
    scan = read_scan(laser_msg(reference_ranges()), logger)
    assert len(scan) == BEAMS
    assert scan.ranges[17] == 1.23
    assert logger.calls == []


def test_read_scan_takes_float32_ranges_as_a_real_message_holds_them():
    logger = FakeLogger()
    scan = read_scan(laser_msg(array.array('f', reference_ranges())), logger)
    assert format_range(scan.ranges[17]) == '1.23 m'
    assert logger.calls == []


@pytest.mark.parametrize('message, words', [
    (SimpleNamespace(ranges=[1.0]), ('not a LaserScan', 'angle_max')),
    (laser_msg([1.0] * BEAMS, angle_min=NAN), ('angle_min', 'finite', 'nan')),
    (laser_msg([1.0] * BEAMS, angle_max=INF), ('angle_max', 'finite', 'inf')),
    (laser_msg([1.0] * BEAMS, angle_increment=0.0), ('angle_increment', '> 0', '36 beams')),
    (laser_msg([1.0] * BEAMS, angle_increment=-INCREMENT), ('angle_increment', '> 0')),
    (laser_msg([1.0] * BEAMS, range_max=0.1), ('range_max', 'greater than range_min')),
    (laser_msg([1.0] * BEAMS, range_max=NAN), ('range_max',)),
    (laser_msg(['far'] * BEAMS), ('ranges', 'numbers')),
    (laser_msg([[1.0, 2.0]] * BEAMS), ('ranges', '1-D')),
    (laser_msg([1.0] * BEAMS, range_min='0.12'), ('range_min', 'must be a number')),
], ids=['no-fields', 'nan-angle-min', 'inf-angle-max', 'zero-increment', 'negative-increment',
        'range-max-below-min', 'nan-range-max', 'text-ranges', 'nested-ranges', 'text-range-min'])
def test_read_scan_warns_of_a_malformed_message_and_returns_none(message, words):
    logger = FakeLogger()
    assert read_scan(message, logger) is None
    [warning] = logger.texts()
    assert warning.startswith('ignoring malformed scan: ')
    for word in words:
        assert word in warning
    assert logger.texts('INFO') == []


def test_read_scan_warns_of_an_empty_scan_and_returns_none():
    logger = FakeLogger()
    assert read_scan(laser_msg([]), logger) is None
    assert logger.texts() == ['ignoring scan with no ranges']


def test_an_empty_scan_with_zero_increment_is_still_just_empty():
    # A scan of one beam or none has no step between beams to check.
    logger = FakeLogger()
    assert read_scan(laser_msg([], angle_increment=0.0), logger) is None
    assert logger.texts() == ['ignoring scan with no ranges']


@pytest.mark.parametrize('ranges', [[INF] * BEAMS, [12.0] * BEAMS, [INF] * 18 + [11.0] * 18],
                         ids=['all-inf', 'all-beyond-range-max', 'inf-and-beyond'])
def test_open_space_is_not_a_fault(ranges):
    logger = FakeLogger()
    scan = read_scan(laser_msg(ranges), logger)
    assert len(scan) == BEAMS
    assert logger.calls == []


@pytest.mark.parametrize('ranges, found', [
    ([-INF] * BEAMS, '36 -inf (too close)'),
    ([-1.0] * BEAMS, '36 outside [0.12, 10] m'),
    ([0.05] * BEAMS, '36 outside [0.12, 10] m'),
    ([NAN] * 10 + [INF] * 10 + [-INF] * 10 + [-0.5] * 3 + [0.0] * 3,
     '10 NaN, 10 +inf (no return), 10 -inf (too close), 6 outside [0.12, 10] m'),
], ids=['all-minus-inf', 'negative', 'below-range-min', 'mix'])
def test_a_scan_without_a_valid_reading_is_returned_with_a_warning_counting_each_kind(
        ranges, found):
    # Such readings still tell something (an obstacle too close, free space): a controller
    # must see them.
    logger = FakeLogger()
    scan = read_scan(laser_msg(ranges), logger)
    assert len(scan) == BEAMS
    assert logger.texts() == [f'no valid reading among 36 beams ({found})']


def test_an_all_nan_scan_is_warned_of_and_not_returned_as_it_tells_nothing():
    logger = FakeLogger()
    assert read_scan(laser_msg([NAN] * BEAMS), logger) is None
    assert logger.texts() == ['no valid reading among 36 beams (36 NaN)']


def test_one_valid_reading_among_bad_ones_is_enough_for_no_warning():
    logger = FakeLogger()
    read_scan(laser_msg([NAN] * 10 + [-INF] * 10 + [-1.0] * 15 + [2.0]), logger)
    assert logger.calls == []


def test_warnings_are_throttled_so_a_stream_of_bad_scans_does_not_flood_the_log():
    logger = FakeLogger()
    read_scan(laser_msg([]), logger)
    read_scan(laser_msg([NAN] * BEAMS), logger)
    read_scan(laser_msg([1.0] * BEAMS, angle_min=NAN), logger)
    assert [options for _, _, options in logger.calls] == [
        {'throttle_duration_sec': WARNING_PERIOD_S}] * 3


def test_a_scan_of_100_000_beams_is_read_without_warning():
    logger = FakeLogger()
    beams = 100_000
    ranges = array.array('f', [2.0] * beams)
    scan = read_scan(laser_msg(ranges, angle_increment=(ANGLE_MAX - ANGLE_MIN) / (beams - 1)),
                     logger)
    assert len(scan) == beams
    assert range_ahead_line(scan, 10.0) == 'Range ahead: 2.00 m'
    assert logger.calls == []


# --- the log lines -----------------------------------------------------------------------------

@pytest.mark.parametrize('range_m, text', [
    (None, 'n/a'), (1.234, '1.23 m'), (1.235001, '1.24 m'), (0.0, '0.00 m'), (10.0, '10.00 m')])
def test_format_range_gives_centimetres_or_n_a(range_m, text):
    assert format_range(range_m) == text


def test_range_ahead_line_reads_the_nearer_of_the_two_beams_around_straight_ahead():
    ranges = reference_ranges()
    ranges[18] = 1.5
    assert range_ahead_line(lab_scan(ranges), 10.0) == 'Range ahead: 1.23 m'


@pytest.mark.parametrize('ahead, max_range, line', [
    (1.23, 10.0, 'Range ahead: 1.23 m'),
    (1.23, 1.0, 'Range ahead: 1.00 m'),
    (INF, 10.0, 'Range ahead: 10.00 m'),
    (INF, 3.5, 'Range ahead: 3.50 m'),
    (-INF, 10.0, 'Range ahead: 0.12 m'),
    (0.01, 10.0, 'Range ahead: 0.12 m'),
], ids=['wall', 'capped', 'open', 'open-capped', 'too-close', 'below-range-min'])
def test_range_ahead_line(ahead, max_range, line):
    ranges = reference_ranges()
    ranges[17] = ranges[18] = ahead
    assert range_ahead_line(lab_scan(ranges), max_range) == line


def test_regions_line_lists_the_five_regions_right_to_left():
    assert regions_line(lab_scan(reference_ranges()).regions(10.0)) == (
        'right: 0.80 m | front-right: 10.00 m | front: 1.23 m | front-left: 10.00 m | '
        'left: 2.50 m')


def test_regions_line_caps_at_max_range():
    assert regions_line(lab_scan(reference_ranges()).regions(1.0)) == (
        'right: 0.80 m | front-right: 1.00 m | front: 1.00 m | front-left: 1.00 m | '
        'left: 1.00 m')


def test_regions_line_shows_a_region_without_beams_as_n_a():
    # A scanner looking from 40 to 86 deg has beams in the front-left and left bands only.
    scan = Scan([1.0] * 10, math.radians(40.0), math.radians(5.0), RANGE_MIN, RANGE_MAX)
    assert regions_line(scan.regions(10.0)) == (
        'right: n/a | front-right: n/a | front: n/a | front-left: 1.00 m | left: 1.00 m')


def test_regions_line_formats_any_mapping_in_its_order():
    assert regions_line({'front_left': None, 'right': 0.5}) == 'front-left: n/a | right: 0.50 m'


@pytest.mark.parametrize('index, range_m, line', [
    (0, 0.8, 'Closest obstacle: 0.80 m at -90.0 deg'),
    (35, 0.5, 'Closest obstacle: 0.50 m at +90.0 deg'),
    (18, 0.3, 'Closest obstacle: 0.30 m at +2.6 deg'),
], ids=['right', 'left', 'ahead'])
def test_closest_line_gives_distance_and_bearing_in_degrees(index, range_m, line):
    ranges = [INF] * BEAMS
    ranges[index] = range_m
    assert closest_line(lab_scan(ranges)) == line


def test_closest_line_of_a_beam_straight_ahead_is_at_plus_zero_degrees():
    scan = Scan([INF, 0.7, INF], -0.1, 0.1, RANGE_MIN, RANGE_MAX)
    assert closest_line(scan) == 'Closest obstacle: 0.70 m at +0.0 deg'


def test_closest_line_ignores_invalid_readings():
    ranges = reference_ranges()
    ranges[1:5] = [NAN, -INF, -1.0, 0.05]
    assert closest_line(lab_scan(ranges)) == 'Closest obstacle: 0.80 m at -90.0 deg'


@pytest.mark.parametrize('ranges', [
    [INF] * BEAMS, [NAN] * BEAMS, [-INF] * BEAMS, [-1.0] * BEAMS, [11.0] * BEAMS],
    ids=['all-inf', 'all-nan', 'all-minus-inf', 'negative', 'beyond-range-max'])
def test_closest_line_says_so_when_no_reading_is_valid(ranges):
    assert closest_line(lab_scan(ranges)) == NO_OBSTACLE == 'No valid obstacle readings.'


class CallSiteThrottlingLogger(FakeLogger):
    """A logger that, like rclpy's, throttles each call site (file and line) on its own."""

    def __init__(self):
        super().__init__()
        self.sites_seen = set()

    def warning(self, message, **options):
        caller = inspect.stack()[1]
        site = (caller.filename, caller.lineno)
        if options.get('throttle_duration_sec') and site in self.sites_seen:
            return
        self.sites_seen.add(site)
        super().warning(message, **options)


def test_one_kind_of_fault_does_not_throttle_the_warning_of_another():
    logger = CallSiteThrottlingLogger()
    read_scan(laser_msg([math.nan] * 36), logger)
    read_scan(laser_msg([]), logger)
    read_scan(laser_msg([1.0] * 36, angle_increment=0.0), logger)
    warnings = logger.texts()
    assert len(warnings) == 3
    assert 'NaN' in warnings[0]
    assert 'no ranges' in warnings[1]
    assert 'angle_increment' in warnings[2]


@pytest.mark.parametrize('value', [0.0, -5.0, math.nan, math.inf])
def test_a_cap_that_cannot_be_a_range_is_refused_naming_the_parameter(value):
    with pytest.raises(ValueError, match="parameter 'max_range' must be a positive finite"):
        positive_parameter('max_range', value)
    assert positive_parameter('max_range', 3.5) == 3.5
