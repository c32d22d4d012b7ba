"""Tests of the wanderbot controller on synthetic 36-beam scans ray-cast against obstacles."""

import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from scan_pkg.behaviors.wander import (clear_turn, corridor_distance, obstacle_points,
                                       open_side, WanderConfig, Wanderer, yaw_from_quaternion)
from scan_pkg.laser import normalize_angle, Scan

SPEED = WanderConfig().speed
TURN_SPEED = WanderConfig().turn_speed
STEP = 0.05
"""Control period (s) of the simulated loops."""


def quaternion(yaw):
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)


def blocked_left_open(shapes):
    """Scan of a wall 0.5 m ahead with a box on the right: the left is the open side."""
    return shapes.cast_scan([((0.5, -3.0), (0.5, 3.0))] + shapes.box_segments(0.3, -1.0, 0.2, 0.5))


def start_turn(wanderer, scan, time=0.0):
    wanderer.update_scan(scan, time)
    return wanderer.command(time)


def turn_with_odometry(wanderer, yaw, time=0.0, odom_until=math.inf):
    """
    Step the robot as commanded, feeding odometry yaw (rad) until ``odom_until`` (s).

    Returns the time (s) at which the turn ended and the final unwrapped yaw (rad).
    """
    angular = wanderer.command(time)[1]
    while wanderer.state == 'turning' and time < 20.0:
        time += STEP
        yaw += angular * STEP
        if time <= odom_until:
            wanderer.update_odom(normalize_angle(yaw), time)
        angular = wanderer.command(time)[1]
    return time, yaw


@pytest.mark.parametrize('yaw', [0.0, 1.0, -2.5, math.pi, -math.pi + 1e-9, 3 * math.pi / 4])
def test_yaw_from_quaternion_recovers_the_yaw(yaw):
    assert yaw_from_quaternion(*quaternion(yaw)) == pytest.approx(normalize_angle(yaw), abs=1e-12)


def test_yaw_from_quaternion_accepts_an_unnormalised_quaternion():
    x, y, z, w = quaternion(1.2)
    assert yaw_from_quaternion(2 * x, 2 * y, 2 * z, 2 * w) == pytest.approx(1.2)


def test_clear_path_drives_straight_at_speed(shapes):
    wanderer = Wanderer()
    wanderer.update_scan(shapes.cast_scan([((2.0, -3.0), (2.0, 3.0))]), 0.0)
    command = wanderer.command(0.0)
    assert command == (SPEED, 0.0)
    assert all(type(value) is float for value in command)


def test_open_space_with_no_return_at_all_drives(shapes):
    wanderer = Wanderer()
    wanderer.update_scan(shapes.cast_scan(), 0.0)
    assert wanderer.command(0.0) == (SPEED, 0.0)


@pytest.mark.parametrize('centre', [(0.5, 0.0), (0.55, 0.1), (0.4, -0.2), (0.65, 0.22)])
def test_small_obstacle_in_the_corridor_stops_and_turns(shapes, centre):
    scan = shapes.cast_scan(circles=[(centre, 0.05)])
    wanderer = Wanderer()
    linear, angular = start_turn(wanderer, scan)
    assert wanderer.state == 'turning'
    assert linear == 0.0 and abs(angular) == TURN_SPEED


def test_obstacle_between_the_front_beams_is_seen_where_one_beam_is_not(shapes):
    # The two beams nearest the heading are at +-2.6 deg; a thin post off-centre hides between
    # them and the next ones, where a lab-style "range ahead" check sees nothing.
    scan = shapes.cast_scan(circles=[((0.5, 0.07), 0.02)])
    assert scan.range_at(0.0) > 0.7
    wanderer = Wanderer()
    assert start_turn(wanderer, scan)[0] == 0.0
    assert wanderer.state == 'turning'


@pytest.mark.parametrize('segment', [
    ((0.1, -0.3), (3.0, -0.3)),      # a wall alongside on the right
    ((0.1, 0.3), (3.0, 0.3)),        # and on the left
    ((0.75, -1.0), (0.75, 1.0)),     # a wall ahead, beyond obstacle_distance
    ((0.3, 0.35), (0.6, 0.6)),       # a wall ahead-left, outside the corridor
])
def test_obstacle_outside_the_corridor_keeps_driving(shapes, segment):
    wanderer = Wanderer()
    assert start_turn(wanderer, shapes.cast_scan([segment])) == (SPEED, 0.0)


def test_too_close_readings_block_the_way():
    ranges = [math.inf] * 36
    ranges[17] = -math.inf
    wanderer = Wanderer()
    start_turn(wanderer, Scan(ranges, -1.57, 3.14 / 35, 0.12, 10.0))
    assert wanderer.state == 'turning'


def test_corridor_distance_is_the_nearest_x_inside_the_corridor(shapes):
    scan = shapes.cast_scan([((0.6, -0.1), (0.4, 0.1)), ((0.2, 0.5), (2.0, 0.5))])
    points = obstacle_points(scan)
    assert corridor_distance(points, 0.7, 0.15, 0.1) == pytest.approx(0.4, abs=0.03)
    assert corridor_distance(points, 0.3, 0.15, 0.1) is None


def test_corridor_margin_tapers_to_nothing_beside_the_robot():
    # A wall passing 0.2 m beside the robot's centre does not block; 0.2 m off the heading
    # line one robot radius ahead and beyond it does.
    beside = np.array([[0.02, 0.2], [0.05, -0.2]])
    ahead = np.array([[0.5, 0.2]])
    assert corridor_distance(beside, 0.7, 0.15, 0.1) is None
    assert corridor_distance(ahead, 0.7, 0.15, 0.1) == 0.5


def test_turn_goes_towards_the_more_open_side(shapes):
    scan = blocked_left_open(shapes)
    assert open_side(scan) == 1
    assert open_side(shapes.mirrored(scan)) == -1
    for scene, sign in ((scan, 1), (shapes.mirrored(scan), -1)):
        assert start_turn(Wanderer(), scene)[1] == sign * TURN_SPEED


@pytest.mark.parametrize('start_yaw', [3.0, -3.0, math.pi])
def test_turn_ends_when_odometry_yaw_has_turned_the_target_across_the_wrap(shapes, start_yaw):
    wanderer = Wanderer(WanderConfig(turn_mode='constant', turn_deg=150.0))
    wanderer.update_odom(start_yaw, 0.0)
    start_turn(wanderer, blocked_left_open(shapes))
    end_time, end_yaw = turn_with_odometry(wanderer, start_yaw)
    turned = math.degrees(end_yaw - start_yaw)
    assert 150.0 <= turned <= 150.0 + math.degrees(TURN_SPEED * STEP) + 1e-9
    assert wanderer.turns_deg == [pytest.approx(turned)]
    assert wanderer.state == 'settling'


def test_turn_follows_odometry_not_the_commanded_rate(shapes):
    # The robot turns at half the commanded rate (a slow base): the turn must go on until
    # odometry shows the angle, twice what the commands add up to.
    wanderer = Wanderer(WanderConfig(turn_mode='constant', turn_deg=120.0))
    wanderer.update_odom(0.0, 0.0)
    angular = start_turn(wanderer, blocked_left_open(shapes))[1]
    time, yaw, commanded = 0.0, 0.0, 0.0
    while wanderer.state == 'turning' and time < 20.0:
        time += STEP
        yaw += 0.5 * angular * STEP
        commanded += angular * STEP
        wanderer.update_odom(normalize_angle(yaw), time)
        angular = wanderer.command(time)[1]
    assert math.degrees(yaw) == pytest.approx(120.0, abs=math.degrees(TURN_SPEED * STEP))
    assert commanded == pytest.approx(2.0 * yaw, abs=TURN_SPEED * STEP)


def test_turn_slows_down_before_its_end(shapes):
    wanderer = Wanderer(WanderConfig(turn_mode='constant', turn_deg=150.0))
    wanderer.update_odom(0.0, 0.0)
    start_turn(wanderer, blocked_left_open(shapes))
    rates, time, yaw = [], 0.0, 0.0
    while wanderer.state == 'turning' and time < 20.0:
        rate = wanderer.command(time)[1]
        rates.append(rate)
        time += STEP
        yaw += rate * STEP
        wanderer.update_odom(yaw, time)
    assert max(rates) == TURN_SPEED
    assert 0.0 < rates[-2] < 0.5 * TURN_SPEED


def test_without_odometry_the_turn_integrates_the_commanded_rate(shapes):
    events = []
    wanderer = Wanderer(WanderConfig(turn_mode='constant', turn_deg=120.0), on_event=events.append)
    angular = start_turn(wanderer, blocked_left_open(shapes))[1]
    time, commanded = 0.0, 0.0
    while wanderer.state == 'turning' and time < 20.0:
        time += STEP
        commanded += angular * STEP
        angular = wanderer.command(time)[1]
    assert math.degrees(commanded) == pytest.approx(120.0, abs=math.degrees(TURN_SPEED * STEP))
    assert wanderer.turns_deg == [pytest.approx(math.degrees(commanded))]
    assert time >= math.radians(120.0) / TURN_SPEED
    assert any('no odometry' in event for event in events)


def test_odometry_lost_mid_turn_continues_by_the_commanded_rate_from_its_last_message(shapes):
    def turn_end(odom_until):
        wanderer = Wanderer(WanderConfig(turn_mode='constant', turn_deg=150.0))
        wanderer.update_odom(0.0, 0.0)
        start_turn(wanderer, blocked_left_open(shapes))
        return turn_with_odometry(wanderer, 0.0, odom_until=odom_until)

    # The simulated robot turns exactly as commanded, so odometry and integration agree.
    with_odometry = turn_end(math.inf)
    assert turn_end(0.5) == pytest.approx(with_odometry, abs=1e-9)
    assert turn_end(0.2) == pytest.approx(with_odometry, abs=1e-9)


def test_random_turns_exceed_90_deg_and_repeat_for_a_seed(shapes):
    def first_turn(seed):
        wanderer = Wanderer(WanderConfig(seed=seed))
        start_turn(wanderer, blocked_left_open(shapes))
        turn_with_odometry(wanderer, 0.0)
        return wanderer.turns_deg[0]

    turns = [first_turn(seed) for seed in range(40)]
    assert all(100.0 <= turn <= 180.0 + math.degrees(TURN_SPEED * STEP) for turn in turns)
    assert turns == [first_turn(seed) for seed in range(40)]
    assert max(turns) - min(turns) > 40.0


def test_after_a_turn_waits_for_a_fresh_scan_then_drives(shapes):
    wanderer = Wanderer()
    start_turn(wanderer, blocked_left_open(shapes))
    end_time, _ = turn_with_odometry(wanderer, 0.0)
    assert wanderer.command(end_time + STEP) == (0.0, 0.0)
    wanderer.update_scan(shapes.cast_scan(), end_time + 2 * STEP)
    assert wanderer.command(end_time + 2 * STEP) == (SPEED, 0.0)
    assert wanderer.state == 'driving'


def test_still_blocked_after_a_turn_turns_again_the_same_way(shapes):
    # Inside a ring 0.5 m round the robot every heading is blocked.
    ring = shapes.cast_scan(circles=[((0.0, 0.0), 0.5)])
    events = []
    wanderer = Wanderer(on_event=events.append)
    direction = start_turn(wanderer, ring)[1]
    end_time, _ = turn_with_odometry(wanderer, 0.0)
    wanderer.update_scan(ring, end_time + STEP)
    assert wanderer.command(end_time + STEP) == (0.0, direction)
    assert wanderer.state == 'turning'
    turn_with_odometry(wanderer, 0.0, time=end_time + STEP)
    assert len(wanderer.turns_deg) == 2
    assert any(event.startswith('still blocked') for event in events)


def test_clear_turn_is_the_smallest_turn_to_an_empty_corridor(shapes):
    # A wall across the way that ends 0.3 m left of the heading line.
    points = obstacle_points(shapes.cast_scan([((0.5, -3.0), (0.5, 0.3))]))
    turn = clear_turn(points, 1, 0.8, 0.15, 0.1, math.pi)
    assert 0.0 < turn < math.pi / 2

    def blocked_after(angle):
        cos, sin = math.cos(angle), math.sin(angle)
        return corridor_distance(points @ np.array([[cos, -sin], [sin, cos]]), 0.8, 0.15, 0.1)

    assert blocked_after(turn) is None
    assert blocked_after(turn - math.radians(5.0)) is not None
    assert clear_turn(points, -1, 0.8, 0.15, 0.1, math.radians(60.0)) is None


def test_still_blocked_after_a_turn_turns_on_only_to_the_first_clear_heading(shapes):
    wanderer = Wanderer(WanderConfig(turn_mode='constant', turn_deg=150.0))
    start_turn(wanderer, blocked_left_open(shapes))
    end_time, _ = turn_with_odometry(wanderer, 0.0)
    wanderer.update_scan(shapes.cast_scan([((0.5, -3.0), (0.5, 0.3))]), end_time + STEP)
    wanderer.command(end_time + STEP)
    turn_with_odometry(wanderer, 0.0, time=end_time + STEP)
    first, second = wanderer.turns_deg
    assert first >= 150.0
    assert 0.0 < second < 90.0


def test_a_turn_right_after_another_keeps_its_direction(shapes):
    wanderer = Wanderer()
    direction = start_turn(wanderer, blocked_left_open(shapes))[1]
    end_time, _ = turn_with_odometry(wanderer, 0.0)
    wanderer.update_scan(shapes.cast_scan(), end_time + STEP)
    assert wanderer.command(end_time + STEP) == (SPEED, 0.0)
    # Blocked again at once, with the other side more open: an observer would see one
    # manoeuvre, so turning back would undo it.
    wanderer.update_scan(shapes.mirrored(blocked_left_open(shapes)), end_time + 3 * STEP)
    assert wanderer.command(end_time + 3 * STEP)[1] == direction
    later = Wanderer()
    start_turn(later, blocked_left_open(shapes))
    end_time, _ = turn_with_odometry(later, 0.0)
    later.update_scan(shapes.cast_scan(), end_time + STEP)
    later.command(end_time + STEP)
    later.update_scan(shapes.mirrored(blocked_left_open(shapes)), end_time + 1.0)
    assert later.command(end_time + 1.0)[1] == -direction


def test_leaving_a_turn_needs_a_longer_clear_corridor_than_driving_on(shapes):
    # A wall 0.75 m ahead: far enough to drive on, too near to drive off after a turn.
    wall = shapes.cast_scan([((0.75, -3.0), (0.75, 3.0))])
    assert start_turn(Wanderer(), wall) == (SPEED, 0.0)
    wanderer = Wanderer()
    start_turn(wanderer, blocked_left_open(shapes))
    end_time, _ = turn_with_odometry(wanderer, 0.0)
    wanderer.update_scan(wall, end_time + STEP)
    assert wanderer.command(end_time + STEP)[0] == 0.0
    assert wanderer.state == 'turning'


def test_stale_scans_stop_the_robot(shapes):
    wanderer = Wanderer()
    wanderer.update_scan(shapes.cast_scan(), 0.0)
    assert wanderer.command(0.4) == (SPEED, 0.0)
    assert wanderer.command(0.6) == (0.0, 0.0)


@pytest.mark.parametrize('ranges', [[], [math.nan] * 36])
def test_blind_scans_are_ignored_and_never_drive(ranges):
    wanderer = Wanderer()
    wanderer.update_scan(Scan(ranges, -1.57, 3.14 / 35, 0.12, 10.0), 0.0)
    assert wanderer.command(0.0) == (0.0, 0.0)


@pytest.mark.parametrize('ranges', [[math.inf] * 36, [-math.inf] * 36, [0.05] * 36,
                                    [1e9] * 36, [math.nan] * 35 + [0.3]])
def test_bad_scans_never_raise_and_give_float_commands(ranges):
    wanderer = Wanderer()
    wanderer.update_scan(Scan(ranges, -1.57, 3.14 / 35, 0.12, 10.0), 0.0)
    linear, angular = wanderer.command(0.0)
    assert type(linear) is float and type(angular) is float
    assert math.isfinite(linear) and math.isfinite(angular)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                          st.floats(0.0, 12.0)), max_size=50))
def test_any_ranges_give_finite_float_commands(ranges):
    wanderer = Wanderer()
    for step in range(3):
        wanderer.update_scan(Scan(ranges, -1.57, 3.14 / 35, 0.12, 10.0), 0.05 * step)
        linear, angular = wanderer.command(0.05 * step)
        assert type(linear) is float and type(angular) is float
        assert linear in (0.0, SPEED) and abs(angular) <= TURN_SPEED


@pytest.mark.parametrize('field, value', [('turn_mode', 'spin'), ('min_turn_deg', 0.0),
                                          ('max_turn_deg', 50.0), ('turn_speed', -1.0),
                                          ('speed', math.nan), ('control_rate', 0.0)])
def test_config_rejects_values_that_cannot_work(field, value):
    with pytest.raises(ValueError, match=field):
        WanderConfig(**{field: value})


def test_params_file_lists_every_parameter_with_its_default(shapes):
    shapes.check_params_file('wanderbot', WanderConfig, {'stamped': False})
