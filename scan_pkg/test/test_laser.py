"""Tests of scan_pkg.laser: hand-computed cases, then properties over random scans."""

import array
import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from scan_pkg.laser import ANGLE_TOLERANCE, normalize_angle, REGION_NAMES, Scan

# The lab's scanner: 36 beams from -1.57 to +1.57 rad, the TurtleBot3 LDS range limits.
LAB_MIN, LAB_MAX, LAB_BEAMS = -1.57, 1.57, 36
LAB_STEP = (LAB_MAX - LAB_MIN) / (LAB_BEAMS - 1)
RANGE_MIN, RANGE_MAX = 0.12, 3.5
DEG = math.pi / 180.0


def lab_scan(ranges, **geometry):
    fields = {'angle_min': LAB_MIN, 'angle_increment': LAB_STEP, 'range_min': RANGE_MIN,
              'range_max': RANGE_MAX}
    fields.update(geometry)
    return Scan(ranges, **fields)


def planted(beams, index, value=0.5, background=3.0):
    ranges = [background] * beams
    ranges[index] = value
    return ranges


class Message:
    """Stands in for sensor_msgs/msg/LaserScan: only the fields Scan.from_msg reads."""

    def __init__(self, ranges, angle_min=LAB_MIN, angle_max=LAB_MAX, angle_increment=LAB_STEP,
                 range_min=RANGE_MIN, range_max=RANGE_MAX):
        self.ranges = ranges
        self.angle_min = angle_min
        self.angle_max = angle_max
        self.angle_increment = angle_increment
        self.range_min = range_min
        self.range_max = range_max


# --- construction -------------------------------------------------------------------------------

@pytest.mark.parametrize('ranges', [
    [1.0, 2.0, 3.0], (1.0, 2.0, 3.0), array.array('f', [1.0, 2.0, 3.0]),
    array.array('d', [1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0], dtype=np.float32), [1, 2, 3],
])
def test_from_msg_accepts_every_sequence_type_a_laser_scan_may_hold(ranges):
    scan = Scan.from_msg(Message(ranges))
    assert scan.ranges.dtype == np.float64
    assert scan.ranges.tolist() == [1.0, 2.0, 3.0]
    assert len(scan) == 3
    assert (scan.angle_min, scan.angle_increment) == (LAB_MIN, LAB_STEP)
    assert (scan.range_min, scan.range_max) == (RANGE_MIN, RANGE_MAX)


def test_from_msg_lets_the_beam_count_win_over_an_inconsistent_angle_max():
    scan = Scan.from_msg(Message([1.0] * 10, angle_max=3.0))
    assert len(scan) == 10
    assert scan.angle_max == pytest.approx(LAB_MIN + 9 * LAB_STEP)


def test_float32_message_fields_are_read_as_floats():
    message = Message([1.0, 2.0], angle_min=np.float32(-0.5), angle_increment=np.float32(0.5),
                      range_min=np.float32(0.1), range_max=np.float32(4.0))
    scan = Scan.from_msg(message)
    assert type(scan.angle_min) is float
    assert scan.angles().tolist() == [-0.5, 0.0]


@pytest.mark.parametrize('field, value', [
    ('angle_min', math.nan), ('angle_min', math.inf), ('angle_max', math.nan),
    ('angle_increment', math.nan), ('angle_increment', -math.inf), ('angle_increment', 0.0),
    ('angle_increment', -0.1), ('range_min', math.nan), ('range_min', -math.inf),
    ('range_max', math.nan), ('range_max', RANGE_MIN), ('range_max', 0.0),
    ('angle_min', 'left'), ('range_max', None), ('angle_increment', True),
])
def test_geometry_that_cannot_be_a_scan_is_refused_naming_the_field(field, value):
    message = Message([1.0, 2.0])
    setattr(message, field, value)
    with pytest.raises(ValueError, match=field):
        Scan.from_msg(message)


@pytest.mark.parametrize('increment', [0.0, -0.1])
def test_a_single_beam_needs_no_positive_increment(increment):
    scan = Scan([1.0], 0.3, increment, RANGE_MIN, RANGE_MAX)
    assert scan.angles().tolist() == [0.3]
    assert scan.index_at(0.3) == 0


def test_range_max_may_be_infinite():
    scan = Scan([1.0, math.inf, 50.0], 0.0, 0.1, 0.0, math.inf)
    assert scan.valid().tolist() == [True, False, True]
    assert scan.closest()[0] == 1.0


@pytest.mark.parametrize('ranges', [
    'abc', [None, 1.0], ['1.0', '2.0'], [[1.0, 2.0], [3.0, 4.0]], [True, False], 3.0,
    [1.0, 'x'], [1j], {'a': 1.0}, (r for r in [1.0]),
])
def test_ranges_that_are_not_a_sequence_of_numbers_are_refused(ranges):
    with pytest.raises(ValueError, match='ranges'):
        Scan.from_msg(Message(ranges))


def test_a_message_without_laser_scan_fields_is_refused():
    with pytest.raises(ValueError, match='not a LaserScan'):
        Scan.from_msg(object())


def test_scan_is_immutable_and_independent_of_the_message():
    ranges = [1.0, 2.0, 3.0]
    source = np.array(ranges)
    from_list, from_array = lab_scan(ranges), lab_scan(source)
    ranges[0] = 9.0
    source[0] = 9.0
    assert from_list.ranges[0] == from_array.ranges[0] == 1.0
    for values in (from_list.ranges, from_list.angles(), from_list.valid(), from_list.capped()):
        with pytest.raises(ValueError):
            values[0] = 0.0
    with pytest.raises(AttributeError):
        from_list.angle_min = 0.0
    with pytest.raises(AttributeError):
        from_list.extra = 1


# --- per-beam arrays ----------------------------------------------------------------------------

def test_angles_are_angle_min_plus_index_times_increment():
    scan = Scan([1.0] * 4, -0.3, 0.2, RANGE_MIN, RANGE_MAX)
    assert scan.angles() == pytest.approx([-0.3, -0.1, 0.1, 0.3])
    assert scan.angle_max == pytest.approx(0.3)


MIXED = [math.inf, -math.inf, math.nan, 0.05, 5.0, 1.0, RANGE_MIN, RANGE_MAX]


def test_valid_follows_rep_117_with_inclusive_limits():
    assert lab_scan(MIXED).valid().tolist() == [
        False, False, False, False, False, True, True, True]


def test_capped_at_range_max_by_default():
    capped = lab_scan(MIXED).capped()
    assert capped.tolist()[:2] + capped.tolist()[3:] == [
        RANGE_MAX, RANGE_MIN, RANGE_MIN, RANGE_MAX, 1.0, RANGE_MIN, RANGE_MAX]
    assert math.isnan(capped[2])


def test_capped_at_a_larger_cap_keeps_readings_beyond_range_max():
    capped = lab_scan(MIXED).capped(10.0)
    assert capped.tolist()[:2] + capped.tolist()[3:] == [
        10.0, RANGE_MIN, RANGE_MIN, 5.0, 1.0, RANGE_MIN, RANGE_MAX]
    assert math.isnan(capped[2])


def test_capped_at_a_smaller_cap_caps_valid_readings():
    assert lab_scan([0.5, 2.0, math.inf]).capped(1.0).tolist() == [0.5, 1.0, 1.0]


@pytest.mark.parametrize('max_range', [0.0, -1.0, math.nan, 'far'])
def test_a_cap_that_is_not_a_positive_number_is_refused(max_range):
    scan = lab_scan([1.0, 2.0])
    for query in (scan.capped, scan.regions, lambda cap: scan.range_at(0.0, max_range=cap)):
        with pytest.raises(ValueError, match='max_range'):
            query(max_range)


def test_directions_are_the_unit_vectors_of_the_angles_shared_by_one_geometry():
    scan = lab_scan([1.0] * LAB_BEAMS)
    angles = scan.angles()
    assert np.array_equal(scan.directions(), np.column_stack((np.cos(angles), np.sin(angles))))
    assert lab_scan([2.0] * LAB_BEAMS).directions() is scan.directions()
    assert not scan.directions().flags.writeable


@pytest.mark.parametrize('ranges, blind', [
    ([math.nan, math.nan], True), ([], True), ([math.nan, math.inf], False),
    ([math.nan, -math.inf], False), ([math.nan, 0.01], False), ([math.inf, math.inf], False),
])
def test_a_scan_is_blind_when_no_beam_holds_any_information(ranges, blind):
    assert lab_scan(ranges).is_blind() is blind


def test_points_place_valid_returns_as_project_laser_does():
    scan = Scan([1.0, 2.0, math.inf, 0.01, 3.0], -math.pi / 2, math.pi / 4, 0.1, 10.0)
    points = scan.points()
    half = math.sqrt(0.5)
    assert points.shape == (3, 2)
    assert points == pytest.approx(np.array([[0.0, -1.0], [2 * half, -2 * half], [0.0, 3.0]]),
                                   abs=1e-12)


# --- index_at and range_at ----------------------------------------------------------------------

def test_index_at_finds_the_nearest_beam_of_the_lab_scanner():
    scan = lab_scan([1.0] * LAB_BEAMS)
    assert scan.index_at(LAB_MIN) == 0
    assert scan.index_at(LAB_MIN + 5 * LAB_STEP + 0.4 * LAB_STEP) == 5
    assert scan.index_at(LAB_MIN + 5 * LAB_STEP + 0.6 * LAB_STEP) == 6
    assert scan.index_at(LAB_MAX) == 35
    # 0 rad is halfway between beams 17 and 18: the lower index.
    assert scan.index_at(0.0) == 17


def test_index_at_reaches_half_an_increment_beyond_the_field_of_view():
    scan = lab_scan([1.0] * LAB_BEAMS)
    assert scan.index_at(LAB_MIN - 0.49 * LAB_STEP) == 0
    assert scan.index_at(LAB_MAX + 0.49 * LAB_STEP) == 35
    assert scan.index_at(LAB_MIN - 0.51 * LAB_STEP) is None
    assert scan.index_at(LAB_MAX + 0.51 * LAB_STEP) is None
    assert scan.index_at(math.pi) is None


def test_index_at_normalises_the_angle():
    scan = lab_scan([1.0] * LAB_BEAMS)
    assert scan.index_at(2 * math.pi + LAB_MIN) == 0
    assert scan.index_at(-4 * math.pi + LAB_MAX) == 35


@pytest.mark.parametrize('angle_min', [0.0, -math.pi])
def test_index_at_on_a_full_circle_scanner_compares_bearings_modulo_two_pi(angle_min):
    scan = Scan([1.0] * 360, angle_min, DEG, RANGE_MIN, RANGE_MAX)

    def index(degrees):
        return round((degrees - math.degrees(angle_min)) % 360.0)

    assert scan.index_at(-math.pi / 2) == index(270)
    assert scan.index_at(math.pi) == index(180)
    assert scan.index_at(-0.4 * DEG) == index(0)
    assert scan.index_at(-0.6 * DEG) == index(359)
    # Halfway between the last beam and the first one, seen round the circle.
    assert scan.index_at(math.radians(math.degrees(angle_min) - 0.5)) == 0


@pytest.mark.parametrize('angle', [math.nan, math.inf, 'ahead', None])
def test_a_bearing_that_is_not_a_finite_number_is_refused(angle):
    scan = lab_scan([1.0] * LAB_BEAMS)
    with pytest.raises(ValueError, match='angle'):
        scan.index_at(angle)
    with pytest.raises(ValueError, match='angle'):
        scan.range_at(angle)


@pytest.mark.parametrize('smaller', [17, 18])
def test_range_ahead_of_the_lab_scanner_is_the_smaller_of_the_two_middle_beams(smaller):
    ranges = [2.0] * LAB_BEAMS
    ranges[17], ranges[18] = 1.5, 1.5
    ranges[smaller] = 1.0
    assert lab_scan(ranges).range_at(0.0) == 1.0


def test_range_at_a_beam_reads_that_beam_capped():
    ranges = [float(i) for i in range(LAB_BEAMS)]
    scan = lab_scan(ranges)
    assert scan.range_at(LAB_MIN + 2 * LAB_STEP) == 2.0
    assert scan.range_at(LAB_MIN + 2 * LAB_STEP, max_range=10.0) == 2.0
    assert scan.range_at(LAB_MIN + 20 * LAB_STEP) == RANGE_MAX
    assert scan.range_at(LAB_MIN + 20 * LAB_STEP, max_range=10.0) == 10.0
    assert scan.range_at(LAB_MIN) == RANGE_MIN


def test_range_at_with_a_half_width_takes_the_minimum_over_the_window():
    ranges = [3.0] * LAB_BEAMS
    ranges[10], ranges[14] = 1.0, 0.5
    scan = lab_scan(ranges)
    centre = LAB_MIN + 12 * LAB_STEP
    assert scan.range_at(centre) == 3.0
    assert scan.range_at(centre, half_width=1.9 * LAB_STEP) == 3.0
    assert scan.range_at(centre, half_width=2.0 * LAB_STEP) == 0.5
    assert scan.range_at(centre, half_width=2.0 * LAB_STEP, max_range=0.8) == 0.5
    assert scan.range_at(centre, half_width=math.pi) == 0.5


def test_range_at_with_a_narrow_window_still_reads_the_nearest_beam():
    ranges = [3.0] * LAB_BEAMS
    ranges[12] = 1.0
    scan = lab_scan(ranges)
    assert scan.range_at(LAB_MIN + 12.3 * LAB_STEP, half_width=0.1 * LAB_STEP) == 1.0


def test_range_at_ignores_nan_and_answers_the_cap_without_a_usable_beam():
    ranges = [3.0] * LAB_BEAMS
    ranges[17], ranges[18] = math.nan, 2.0
    scan = lab_scan(ranges)
    assert scan.range_at(0.0) == 2.0
    assert lab_scan([math.nan] * LAB_BEAMS).range_at(0.0, max_range=10.0) == 10.0
    assert scan.range_at(math.pi, max_range=10.0) == 10.0


def test_range_at_reads_each_scan_of_one_geometry_afresh():
    first, second = lab_scan(planted(LAB_BEAMS, 3, 1.0)), lab_scan(planted(LAB_BEAMS, 3, 2.0))
    bearing = LAB_MIN + 3 * LAB_STEP
    assert (first.range_at(bearing), second.range_at(bearing)) == (1.0, 2.0)
    assert (first.range_at(bearing, 0.2), second.range_at(bearing, 0.2)) == (1.0, 2.0)


def test_range_at_stays_right_over_a_sweep_of_many_bearings():
    ranges = [0.2 + 0.05 * index for index in range(LAB_BEAMS)]
    scan = lab_scan(ranges)
    for sweep in range(5):
        for index in range(LAB_BEAMS):
            bearing = LAB_MIN + (index + 0.1 * sweep) * LAB_STEP
            assert scan.range_at(bearing) == ranges[index]
            assert scan.index_at(bearing) == index


def test_range_at_refuses_a_negative_half_width():
    with pytest.raises(ValueError, match='half_width'):
        lab_scan([1.0] * LAB_BEAMS).range_at(0.0, half_width=-0.1)


# --- regions ------------------------------------------------------------------------------------

# Beam i of the lab scanner points at -89.954 + 5.1403 i deg: the band edges at -54, -18, 18
# and 54 deg fall at i = 6.995, 13.998, 21.002 and 28.005, so the front band has eight beams.
LAB_BANDS = {'right': range(0, 7), 'front_right': range(7, 14), 'front': range(14, 22),
             'front_left': range(22, 29), 'left': range(29, 36)}


def test_regions_are_ordered_right_to_left():
    assert tuple(lab_scan([1.0] * LAB_BEAMS).regions()) == REGION_NAMES


@pytest.mark.parametrize('index', range(LAB_BEAMS))
def test_regions_split_all_36_lab_beams_into_five_bands(index):
    regions = lab_scan(planted(LAB_BEAMS, index)).regions()
    assert [name for name, value in regions.items() if value == 0.5] == [
        name for name, beams in LAB_BANDS.items() if index in beams]


def test_regions_cap_at_ten_metres_by_default():
    regions = lab_scan([math.inf] * LAB_BEAMS).regions()
    assert list(regions.values()) == [10.0] * 5
    assert list(lab_scan([math.inf] * LAB_BEAMS).regions(None).values()) == [RANGE_MAX] * 5
    assert list(lab_scan([-math.inf] * LAB_BEAMS).regions().values()) == [RANGE_MIN] * 5


EDGE_BANDS = [(-90, 'right'), (-54, 'front_right'), (-18, 'front'), (18, 'front'),
              (54, 'front_left'), (90, 'left')]


# Scanners with beams on every band edge; rounding puts some of these beams a few 1e-16 rad
# outside their band, which the tolerance absorbs.
@pytest.mark.parametrize('beams, angle_min, increment', [
    (181, -math.pi / 2, DEG), (100, 0.0, math.pi / 50), (100, -math.pi, math.pi / 50),
    (600, 0.0, math.pi / 300), (600, -math.pi, math.pi / 300)])
def test_a_beam_on_a_band_edge_belongs_to_the_band_nearer_the_front(beams, angle_min, increment):
    for degrees, band in EDGE_BANDS:
        index = round((math.radians(degrees) - angle_min) / increment) % beams
        regions = Scan(planted(beams, index), angle_min, increment, RANGE_MIN,
                       RANGE_MAX).regions()
        assert [name for name, value in regions.items() if value == 0.5] == [band], degrees


def test_a_band_without_beams_is_none_and_one_of_all_nan_beams_is_the_cap():
    ranges = [math.nan] * 11
    ranges[5] = 1.0
    narrow = Scan(ranges, -30 * DEG, 6 * DEG, RANGE_MIN, RANGE_MAX)
    assert narrow.regions() == {'right': None, 'front_right': 10.0, 'front': 1.0,
                                'front_left': 10.0, 'left': None}


def test_regions_of_a_full_circle_scanner_ignore_the_beams_behind():
    ranges = [0.2] * 360
    for degrees in range(-90, 91):
        ranges[degrees % 360] = 2.0
    ranges[350] = 1.0
    scan = Scan(ranges, 0.0, DEG, RANGE_MIN, RANGE_MAX)
    assert scan.regions() == {'right': 2.0, 'front_right': 2.0, 'front': 1.0,
                              'front_left': 2.0, 'left': 2.0}


# --- closest ------------------------------------------------------------------------------------

def test_closest_skips_invalid_readings_and_prefers_the_lowest_index():
    ranges = [2.0, math.nan, -math.inf, 0.05, 0.9, 5.0, 0.9, math.inf]
    range_m, angle, index = lab_scan(ranges).closest()
    assert (range_m, index) == (0.9, 4)
    assert angle == pytest.approx(LAB_MIN + 4 * LAB_STEP)


def test_closest_is_none_without_a_valid_reading():
    for ranges in ([math.inf] * 5, [math.nan] * 5, [-math.inf, 0.01, 7.0], [5.0, 4.0]):
        assert lab_scan(ranges).closest() is None


def test_closest_bearing_is_normalised():
    ranges = [3.0] * 360
    ranges[350] = 1.0
    range_m, angle, index = Scan(ranges, 0.0, DEG, RANGE_MIN, RANGE_MAX).closest()
    assert (range_m, index) == (1.0, 350)
    assert angle == pytest.approx(-10 * DEG)


# --- scans the nodes must survive ---------------------------------------------------------------

def test_an_empty_scan_answers_everything_without_a_beam():
    scan = Scan.from_msg(Message([]))
    assert len(scan) == 0
    assert scan.angles().shape == scan.valid().shape == scan.capped().shape == (0,)
    assert scan.points().shape == (0, 2)
    assert scan.angle_max == scan.angle_min
    assert scan.index_at(0.0) is None
    assert scan.closest() is None
    assert scan.range_at(0.0, half_width=0.5) == RANGE_MAX
    assert scan.regions() == dict.fromkeys(REGION_NAMES)


def test_a_scan_of_100000_beams_is_handled():
    ranges = np.full(100_000, math.inf, dtype=np.float32)
    # Beam 62000 points at -pi + 0.62 * 2 pi rad = 43.2 deg.
    ranges[62_000] = 1.0
    scan = Scan.from_msg(Message(ranges, angle_min=-math.pi, angle_increment=2 * math.pi / 1e5))
    assert scan.closest()[2] == 62_000
    assert scan.regions()['front_left'] == 1.0
    assert scan.range_at(0.0) == RANGE_MAX


def test_normalize_angle_wraps_into_minus_pi_exclusive_to_pi_inclusive():
    assert normalize_angle(math.pi) == math.pi
    assert normalize_angle(-math.pi) == math.pi
    assert normalize_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert normalize_angle(-1e-300) == -1e-300


# --- properties ---------------------------------------------------------------------------------

PROPERTIES = settings(derandomize=True, database=None, deadline=None, max_examples=100)


@st.composite
def scans(draw):
    """
    Draw a scan: 1..20000 beams over any field of view up to 2 pi, any mix of readings.

    Some scans sweep several turns (an angle_increment inconsistent with angle_max): they are
    still scans, whose beams overlap.
    """
    beams = draw(st.one_of(st.integers(1, 40), st.integers(1, 20_000)))
    kind = draw(st.sampled_from(
        ['arc', 'lab', 'zero_to_two_pi', 'minus_pi_to_pi', 'several_turns']))
    if kind == 'several_turns':
        angle_min = draw(st.floats(-math.pi, math.pi))
        field_of_view = (beams - 1) * draw(st.floats(0.01, 3.0))
    elif kind == 'lab':
        angle_min, field_of_view = LAB_MIN, LAB_MAX - LAB_MIN
    elif kind == 'arc':
        angle_min = draw(st.floats(-2 * math.pi, 2 * math.pi))
        field_of_view = draw(st.floats(0.0, 2 * math.pi))
    else:
        angle_min = 0.0 if kind == 'zero_to_two_pi' else -math.pi
        field_of_view = 2 * math.pi * (beams - 1) / beams
    increment = field_of_view / (beams - 1) if beams > 1 else draw(st.floats(0.0, 0.1))
    if beams > 1 and increment <= 0.0:
        increment = 1e-3
    range_min = draw(st.sampled_from([0.0, 0.12, 0.5]))
    range_max = draw(st.sampled_from([3.5, 12.0, math.inf]))
    # Weights of ordinary readings, +inf, -inf, NaN, below range_min, above range_max.
    weights = np.array(draw(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))) + 1e-3
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    finite_max = min(range_max, 20.0)
    choices = [rng.uniform(range_min, finite_max, beams), np.full(beams, math.inf),
               np.full(beams, -math.inf), np.full(beams, math.nan),
               rng.uniform(-1.0, range_min, beams), rng.uniform(finite_max, 30.0, beams)]
    pick = rng.choice(len(choices), size=beams, p=weights / weights.sum())
    ranges = np.choose(pick, choices).astype(np.float32)
    return Scan(ranges, angle_min, increment, range_min, range_max)


bearings = st.floats(-3 * math.pi, 3 * math.pi)


def distances_to(scan, angle):
    """Return the angular distance (rad) of every beam to ``angle``, from first principles."""
    difference = scan.angles() - angle
    return np.abs(np.arctan2(np.sin(difference), np.cos(difference)))


def nearest_beams(scan, angle):
    """Return the indices of the beams nearest to ``angle``, and whether they are near enough."""
    distances = distances_to(scan, angle)
    if not len(distances):
        return np.array([], dtype=int), False
    nearest = distances.min()
    within = nearest <= abs(scan.angle_increment) / 2 + ANGLE_TOLERANCE
    return np.flatnonzero(distances <= nearest + ANGLE_TOLERANCE), within


def expected_min(scan, mask, cap):
    readings = scan.ranges[mask]
    readings = readings[~np.isnan(readings)]
    if not len(readings):
        return cap
    return min(max(float(readings.min()), scan.range_min), cap)


@PROPERTIES
@given(scans())
def test_valid_capped_and_points_agree_with_their_definitions(scan):
    ranges = scan.ranges
    valid = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
    assert np.array_equal(scan.valid(), valid)
    capped = scan.capped(10.0)
    assert np.array_equal(np.isnan(capped), np.isnan(ranges))
    assert np.all(capped[np.isposinf(ranges) | (ranges > 10.0)] == 10.0)
    assert np.all(capped[ranges < scan.range_min] == scan.range_min)
    kept = (ranges >= scan.range_min) & (ranges <= 10.0)
    assert np.array_equal(capped[kept], ranges[kept])
    points = scan.points()
    assert points.shape == (valid.sum(), 2)
    assert np.allclose(np.hypot(points[:, 0], points[:, 1]), ranges[valid])
    directions = np.arctan2(points[:, 1], points[:, 0]) - scan.angles()[valid]
    assert np.allclose(np.sin(directions), 0.0, atol=1e-9)
    assert np.all(np.cos(directions) > 0.0)


@PROPERTIES
@given(scans(), bearings)
def test_index_at_is_a_nearest_beam_within_half_an_increment(scan, angle):
    candidates, within = nearest_beams(scan, angle)
    index = scan.index_at(angle)
    if within:
        assert index == candidates[0]
    else:
        assert index is None


@PROPERTIES
@given(scans(), bearings, st.floats(0.0, 4.0))
def test_range_at_is_the_capped_minimum_over_the_window_and_nearest_beams(
        scan, angle, half_width):
    candidates, within = nearest_beams(scan, angle)
    window = distances_to(scan, angle) <= half_width + ANGLE_TOLERANCE
    if within:
        window[candidates] = True
    assert scan.range_at(angle, half_width, max_range=10.0) == expected_min(scan, window, 10.0)
    assert scan.range_at(angle, half_width / 2, 10.0) >= scan.range_at(angle, half_width, 10.0)


@PROPERTIES
@given(scans())
def test_regions_are_the_capped_minima_of_the_bearing_bands(scan):
    bearings_deg = np.degrees(np.arctan2(np.sin(scan.angles()), np.cos(scan.angles())))
    tolerance_deg = math.degrees(ANGLE_TOLERANCE)
    regions = scan.regions()
    for name, centre in zip(REGION_NAMES, (-72, -36, 0, 36, 72)):
        inner = max(abs(centre) - 18, 0)
        on_side = np.sign(bearings_deg) == np.sign(centre)
        in_band = (np.abs(bearings_deg) <= abs(centre) + 18 + tolerance_deg) & (
            (np.abs(bearings_deg) > inner + tolerance_deg) & on_side if centre else True)
        expected = expected_min(scan, in_band, 10.0) if in_band.any() else None
        assert regions[name] == expected, name


@PROPERTIES
@given(scans(), st.data())
def test_every_beam_counts_in_one_band_at_most(scan, data):
    index = data.draw(st.integers(0, len(scan) - 1))
    ranges = np.full(len(scan), 5.0)
    ranges[index] = 1.0
    marked = Scan(ranges, scan.angle_min, scan.angle_increment, 0.1, 10.0)
    bearing = normalize_angle(float(marked.angles()[index]))
    holding = [name for name, value in marked.regions().items() if value == 1.0]
    if abs(bearing) < math.pi / 2 - ANGLE_TOLERANCE:
        assert len(holding) == 1
    else:
        assert len(holding) <= 1


@PROPERTIES
@given(scans(), bearings)
def test_a_mirrored_scan_gives_mirrored_answers(scan, angle):
    mirror = Scan(scan.ranges[::-1], -scan.angle_max, scan.angle_increment, scan.range_min,
                  scan.range_max)
    regions, mirrored = scan.regions(), mirror.regions()
    assert [regions[name] for name in REGION_NAMES] == [
        mirrored[name] for name in reversed(REGION_NAMES)]
    assert scan.range_at(angle, max_range=10.0) == mirror.range_at(-angle, max_range=10.0)


@PROPERTIES
@given(scans())
def test_closest_is_the_smallest_valid_reading(scan):
    valid = scan.valid()
    closest = scan.closest()
    if not valid.any():
        assert closest is None
        return
    range_m, angle, index = closest
    assert range_m == scan.ranges[valid].min()
    assert index == np.flatnonzero(valid & (scan.ranges == range_m))[0]
    assert -math.pi < angle <= math.pi
    assert math.cos(angle - scan.angles()[index]) == pytest.approx(1.0)
