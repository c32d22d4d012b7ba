"""Tests of the wall follower on synthetic 36-beam scans ray-cast against walls and obstacles."""

import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from scan_pkg.behaviors.wall_follow import estimate_wall, WallFollowConfig, WallFollower
from scan_pkg.laser import Scan

SETPOINT = WallFollowConfig().distance
SPEED = WallFollowConfig().speed
FIT_RADIUS = WallFollowConfig().fit_radius
EXTRAPOLATION = WallFollowConfig().extrapolation


def right_wall(shapes, offset, angle=0.0, start=-3.0, end=3.0):
    """
    Scan of a straight wall on the right, ``offset`` m from the robot, rotated by ``angle``.

    ``angle`` (rad) > 0 turns the wall anticlockwise about the robot's foot on it, so the robot
    heads into the wall; ``start`` and ``end`` bound the wall along it (m).
    """
    along = np.array([math.cos(angle), math.sin(angle)])
    foot = np.array([math.sin(angle), -math.cos(angle)]) * offset
    return shapes.cast_scan([(foot + start * along, foot + end * along)])


def command_for(scan, time=0.0, **config):
    follower = WallFollower(WallFollowConfig(**config))
    follower.update_scan(scan, time)
    return follower.command(time), follower


def test_wall_at_the_set_distance_and_parallel_gives_full_speed_and_no_turn(shapes):
    (linear, angular), follower = command_for(right_wall(shapes, SETPOINT))
    assert follower.mode == 'following'
    assert linear == pytest.approx(SPEED, rel=0.01)
    assert abs(angular) < 0.02


def test_commands_are_python_floats(shapes):
    (linear, angular), _ = command_for(right_wall(shapes, 0.6, angle=0.2))
    assert type(linear) is float and type(angular) is float


@pytest.mark.parametrize('offset', [0.3, 0.4, 0.45])
def test_too_close_to_the_wall_steers_away(shapes, offset):
    (_, angular), _ = command_for(right_wall(shapes, offset))
    assert angular > 0.1


@pytest.mark.parametrize('offset', [0.55, 0.7, 0.9])
def test_too_far_from_the_wall_steers_towards_it(shapes, offset):
    (_, angular), _ = command_for(right_wall(shapes, offset))
    assert angular < -0.1


def test_steering_grows_with_the_distance_error(shapes):
    rates = [command_for(right_wall(shapes, offset))[0][1] for offset in (0.3, 0.4, 0.5, 0.6)]
    assert rates == sorted(rates, reverse=True)


@pytest.mark.parametrize('angle, turn', [(0.3, 1), (-0.3, -1)])
def test_heading_into_or_away_from_the_wall_turns_back_parallel(shapes, angle, turn):
    (_, angular), _ = command_for(right_wall(shapes, SETPOINT, angle=angle))
    assert angular * turn > 0.3


@pytest.mark.parametrize('angle', [-0.1, 0.0, 0.2, 0.4])
@pytest.mark.parametrize('offset', [0.3, 0.5, 0.8])
def test_estimate_of_a_straight_wall_is_its_distance_and_direction(shapes, offset, angle):
    scan = right_wall(shapes, offset, angle=angle)
    wall = estimate_wall(scan.points(), FIT_RADIUS, EXTRAPOLATION)
    assert wall.distance == pytest.approx(offset, abs=1e-6)
    assert wall.direction == pytest.approx(angle, abs=1e-6)
    assert not wall.corner


def test_wall_heading_away_beyond_the_extrapolation_is_taken_for_a_corner(shapes):
    # The robot's foot on the wall is 0.5 tan(0.4) = 0.21 m behind the last beam's return.
    scan = right_wall(shapes, SETPOINT, angle=-0.4)
    wall = estimate_wall(scan.points(), FIT_RADIUS, EXTRAPOLATION)
    assert wall.corner
    assert wall.distance == pytest.approx(SETPOINT / math.cos(0.4), abs=0.01)


def test_estimate_of_a_noisy_wall_is_within_a_centimetre(shapes):
    errors = []
    for seed in range(20):
        foot, along = np.array([0.0, -SETPOINT]), np.array([1.0, 0.0])
        scan = shapes.cast_scan([(foot - 3 * along, foot + 3 * along)], noise=0.01, seed=seed)
        wall = estimate_wall(scan.points(), FIT_RADIUS, EXTRAPOLATION)
        errors.append((wall.distance - SETPOINT, wall.direction))
    distance_errors, direction_errors = np.abs(errors).T
    assert distance_errors.max() < 0.02 and direction_errors.mean() < 0.05


def test_estimate_of_a_cylinder_beside_the_robot_is_near_its_surface_distance(shapes):
    radius = 0.8
    scan = shapes.cast_scan(circles=[((0.0, -radius - SETPOINT), radius)])
    wall = estimate_wall(scan.points(), FIT_RADIUS, EXTRAPOLATION)
    assert wall.distance == pytest.approx(SETPOINT, abs=0.03)
    assert -0.3 < wall.direction < 0.0


def inside_corner(shapes, ahead):
    """Scan of a wall on the right at the setpoint meeting a wall ``ahead`` m in front."""
    return shapes.cast_scan([((-3.0, -SETPOINT), (ahead, -SETPOINT)),
                             ((ahead, -SETPOINT), (ahead, 3.0))])


def test_wall_ahead_slows_the_robot_before_the_inside_corner(shapes):
    (linear, _), _ = command_for(inside_corner(shapes, 0.6))
    assert 0.0 < linear < 0.8 * SPEED


def test_wall_ahead_nearer_than_the_setpoint_turns_away_almost_in_place(shapes):
    (linear, angular), _ = command_for(inside_corner(shapes, 0.45))
    assert angular > 1.0
    assert linear < 0.2 * SPEED


def test_wall_ahead_and_close_stops_and_turns_in_place(shapes):
    scan = shapes.cast_scan([((0.25, -3.0), (0.25, 3.0))])
    (linear, angular), _ = command_for(scan)
    assert linear == 0.0
    assert angular > 0.5


def test_outside_corner_just_passed_arcs_towards_the_wall_side(shapes):
    follower = WallFollower()
    follower.update_scan(right_wall(shapes, SETPOINT), 0.0)
    follower.command(0.0)
    # The wall ended just behind the laser: a +-90 deg scanner sees nothing of it.
    follower.update_scan(shapes.cast_scan([((-3.0, -SETPOINT), (-0.05, -SETPOINT))]), 0.1)
    linear, angular = follower.command(0.1)
    assert follower.mode == 'cornering'
    assert linear > 0.0
    assert angular == pytest.approx(-linear / SETPOINT, rel=0.05)


def corner_scan(shapes, arc_angle):
    """
    Scan of a robot ``arc_angle`` (rad) into a clockwise arc at the setpoint round a corner.

    The box's corner is on the robot's right at the setpoint; the face the robot came along is
    behind it, the next face ahead-right.
    """
    corner = SETPOINT * np.array([-math.sin(arc_angle), -math.cos(arc_angle)])
    box = shapes.box_segments(corner[0] - 1.0, corner[1] - 1.0, 1.0, 1.0)
    return shapes.cast_scan(box, pose=(0.0, 0.0, -arc_angle))


@pytest.mark.parametrize('arc_angle', [0.2, 0.5, 0.8, 1.1])
def test_outside_corner_point_in_view_is_circled_at_the_setpoint(shapes, arc_angle):
    (linear, angular), follower = command_for(corner_scan(shapes, arc_angle))
    assert follower.wall.corner
    assert follower.wall.distance == pytest.approx(SETPOINT, abs=0.02)
    assert linear > 0.5 * SPEED
    assert angular == pytest.approx(-linear / SETPOINT, abs=0.1)


def test_lost_wall_turns_to_searching_after_a_full_circle(shapes):
    follower = WallFollower()
    follower.update_scan(right_wall(shapes, SETPOINT), 0.0)
    follower.command(0.0)
    empty = shapes.cast_scan()
    time, turned = 0.0, 0.0
    while follower.mode != 'searching' and time < 100.0:
        time += 0.1
        follower.update_scan(empty, time)
        turned += abs(follower.command(time)[1]) * 0.1
    assert follower.mode == 'searching'
    assert turned == pytest.approx(2.0 * math.pi, abs=0.5)


def test_nothing_in_sight_looks_behind_then_drives_straight(shapes):
    follower = WallFollower()
    empty = shapes.cast_scan()
    commands = []
    for step in range(60):
        follower.update_scan(empty, step * 0.1)
        commands.append(follower.command(step * 0.1))
    assert follower.mode == 'searching'
    assert commands[0][0] == 0.0 and commands[0][1] != 0.0
    assert commands[-1] == (SPEED, 0.0)


def test_searching_heads_for_the_nearest_obstacle(shapes):
    scan = shapes.cast_scan(circles=[((2.0, 2.0), 0.3)])
    (linear, angular), follower = command_for(scan)
    assert follower.mode == 'searching'
    assert angular > 0.3 and linear > 0.0


def test_obstacle_on_the_wrong_side_turns_the_robot_round(shapes):
    scan = shapes.cast_scan([((-3.0, SETPOINT), (3.0, SETPOINT))])
    (linear, angular), _ = command_for(scan)
    assert linear == 0.0
    assert abs(angular) == pytest.approx(WallFollowConfig().max_angular)


@pytest.mark.parametrize('scene', ['parallel', 'too_close', 'angled', 'inside_corner', 'corner',
                                   'cylinder', 'nothing'])
def test_side_left_gives_the_mirror_image_of_side_right(shapes, scene):
    scans = {
        'parallel': right_wall(shapes, SETPOINT),
        'too_close': right_wall(shapes, 0.35),
        'angled': right_wall(shapes, 0.6, angle=0.3),
        'inside_corner': inside_corner(shapes, 0.45),
        'corner': corner_scan(shapes, 0.5),
        'cylinder': shapes.cast_scan(circles=[((0.3, -1.2), 0.8)], noise=0.01),
        'nothing': shapes.cast_scan(),
    }
    scan = scans[scene]
    right = command_for(scan)[0]
    left = command_for(shapes.mirrored(scan), side='left')[0]
    assert left == pytest.approx((right[0], -right[1]), abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(offset=st.floats(0.15, 2.0), angle=st.floats(-1.2, 1.2), ahead=st.floats(0.2, 3.0),
       gap=st.floats(0.0, 1.0), seed=st.integers(0, 1000))
def test_mirrored_scenes_give_mirrored_commands(shapes, offset, angle, ahead, gap, seed):
    # A wall on the right at any distance and angle, with a gap, and a wall across ahead.
    along = np.array([math.cos(angle), math.sin(angle)])
    foot = np.array([math.sin(angle), -math.cos(angle)]) * offset
    segments = [(foot - 3.0 * along, foot - gap * along), (foot, foot + 3.0 * along),
                ((ahead, -3.0), (ahead, 3.0))]
    scan = shapes.cast_scan(segments, noise=0.01, seed=seed)
    right = command_for(scan)[0]
    left = command_for(shapes.mirrored(scan), side='left')[0]
    assert left == pytest.approx((right[0], -right[1]), abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                          st.floats(0.0, 12.0)), max_size=50))
def test_any_ranges_give_finite_float_commands(ranges):
    follower = WallFollower()
    for step in range(3):
        follower.update_scan(Scan(ranges, -1.57, 3.14 / 35, 0.12, 10.0), 0.1 * step)
        linear, angular = follower.command(0.1 * step)
        assert type(linear) is float and type(angular) is float
        assert math.isfinite(linear) and math.isfinite(angular)
        assert 0.0 <= linear <= SPEED


@pytest.mark.parametrize('ranges', [[], [math.nan] * 36, [math.inf] * 36, [-math.inf] * 36,
                                    [0.05] * 36, [1e9] * 36])
def test_bad_scans_never_raise_and_give_float_commands(ranges):
    follower = WallFollower()
    follower.update_scan(Scan(ranges, -1.57, 3.14 / 35, 0.12, 10.0), 0.0)
    linear, angular = follower.command(0.0)
    assert type(linear) is float and type(angular) is float
    assert math.isfinite(linear) and math.isfinite(angular)


@pytest.mark.parametrize('reading', [0.0, -math.inf])
def test_a_return_at_the_laser_of_a_pointlike_robot_gives_finite_commands(reading):
    # robot_radius 0 is allowed; a scanner with range_min 0 can see a corner at distance 0.
    follower = WallFollower(WallFollowConfig(robot_radius=0.0))
    follower.update_scan(Scan([math.inf] * 17 + [reading] + [math.inf] * 18, -1.57, 3.14 / 35,
                              0.0, 10.0), 0.0)
    linear, angular = follower.command(0.0)
    assert math.isfinite(linear) and math.isfinite(angular)


def test_blind_scans_stop_the_robot_once_the_last_scan_is_stale(shapes):
    follower = WallFollower()
    follower.update_scan(right_wall(shapes, SETPOINT), 0.0)
    blind = Scan([math.nan] * 36, -1.57, 3.14 / 35, 0.12, 10.0)
    follower.update_scan(blind, 0.1)
    assert follower.command(0.1)[0] > 0.0
    follower.update_scan(blind, 1.0)
    assert follower.command(1.0) == (0.0, 0.0)


def test_no_scan_yet_means_stand_still():
    assert WallFollower().command(0.0) == (0.0, 0.0)


@pytest.mark.parametrize('field, value', [('side', 'up'), ('distance', 0.0), ('speed', -0.1),
                                          ('lost_margin', 0.0), ('heading_gain', math.nan)])
def test_config_rejects_values_that_cannot_work(field, value):
    with pytest.raises(ValueError, match=field):
        WallFollowConfig(**{field: value})


def test_params_file_lists_every_parameter_with_its_default(shapes):
    shapes.check_params_file('wall_follow', WallFollowConfig, {'stamped': False})
