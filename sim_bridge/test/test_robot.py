"""Tests of sim_bridge.simulation.robot: exact arcs, limits, and rejected or clamped commands."""

import math

import pytest

from sim_bridge.simulation.robot import check_command, DiffDrive, DriveLimits, integrate_arc, ramp

INSTANT = DriveLimits(max_linear_accel=math.inf, max_angular_accel=math.inf)


def test_straight_line_along_the_heading():
    x, y, yaw = integrate_arc((1.0, 2.0, math.pi / 6), 0.5, 0.0, 4.0)
    assert (x, y, yaw) == pytest.approx((1.0 + 2.0 * math.cos(math.pi / 6),
                                         2.0 + 2.0 * math.sin(math.pi / 6), math.pi / 6))


def test_positive_turn_rate_drives_a_counter_clockwise_arc_to_the_left():
    # Radius v / w = 2 m; a quarter circle from the origin heading +x ends at (2, 2), facing +y.
    pose = integrate_arc((0.0, 0.0, 0.0), 1.0, 0.5, math.pi)
    assert pose == pytest.approx((2.0, 2.0, math.pi / 2))
    # Turning right (w < 0) mirrors it.
    assert integrate_arc((0.0, 0.0, 0.0), 1.0, -0.5, math.pi) == pytest.approx(
        (2.0, -2.0, -math.pi / 2))


def test_driving_backwards_and_turning_in_place():
    assert integrate_arc((0.0, 0.0, 0.0), -0.5, 0.0, 2.0) == pytest.approx((-1.0, 0.0, 0.0))
    assert integrate_arc((1.0, 1.0, 0.0), 0.0, 1.0, 1.0) == pytest.approx((1.0, 1.0, 1.0))


def test_many_small_steps_follow_the_exact_circle():
    drive = DiffDrive((0.0, 0.0, 0.0), INSTANT)
    drive.set_command(0.3, 0.6)
    radius = 0.5
    for step in range(1, 1001):
        x, y, yaw = drive.step(0.01)
        t = 0.01 * step
        assert (x, y) == pytest.approx((radius * math.sin(0.6 * t),
                                        radius * (1.0 - math.cos(0.6 * t))), abs=1e-12)
    assert yaw == pytest.approx(math.remainder(6.0, 2 * math.pi))
    assert drive.velocity == (0.3, 0.6)


def test_a_full_circle_comes_back_to_the_start():
    pose = integrate_arc((3.0, -1.0, 2.0), 0.4, 0.8, 2 * math.pi / 0.8)
    assert pose == pytest.approx((3.0, -1.0, 2.0), abs=1e-12)


def test_acceleration_limits_ramp_the_velocity_and_the_distance():
    drive = DiffDrive(limits=DriveLimits(max_linear_accel=2.5, max_angular_accel=5.0))
    drive.set_command(0.5, 1.0)
    drive.step(0.1)
    assert drive.velocity == pytest.approx((0.25, 0.5))
    assert drive.pose[2] == pytest.approx(0.5 * 5.0 * 0.1 ** 2)
    for _ in range(9):
        drive.step(0.01)
    assert drive.velocity == pytest.approx((0.475, 0.95))
    drive.set_command(0.5, 0.0)
    drive.step(0.01)
    assert drive.velocity == pytest.approx((0.5, 0.9))
    # Ramp from rest to 0.5 m/s in 0.2 s covers 0.05 m (a t^2 / 2), then 0.5 m/s.
    straight = DiffDrive(limits=DriveLimits(max_linear_accel=2.5))
    straight.set_command(0.5, 0.0)
    for _ in range(100):
        straight.step(0.01)
    assert straight.pose[0] == pytest.approx(0.05 + 0.5 * 0.8)


def test_ramp_changes_by_at_most_the_acceleration_and_returns_the_mean():
    assert ramp(0.0, 1.0, 3.0, 0.1) == pytest.approx((0.3, 0.15))
    assert ramp(0.0, -1.0, 3.0, 0.1) == pytest.approx((-0.3, -0.15))
    # Reaches 1.0 after 0.05 s of the 0.1 s step: 0.0125 + 0.05 = 0.0625 m covered.
    assert ramp(0.85, 1.0, 3.0, 0.1) == pytest.approx((1.0, 0.9625))
    assert ramp(0.0, 1.0, math.inf, 0.1) == (1.0, 1.0)


@pytest.mark.parametrize('linear, angular', [
    (math.nan, 0.0), (0.2, math.nan), (math.inf, 0.0), (0.0, -math.inf), ('fast', 0.0),
    (None, 1.0)])
def test_a_command_that_is_not_finite_is_rejected_and_stops_the_robot(linear, angular):
    assert check_command(linear, angular, DriveLimits())[:2] == (0.0, 0.0)
    drive = DiffDrive(limits=INSTANT)
    drive.set_command(0.3, 0.2)
    drive.step(0.1)
    warning = drive.set_command(linear, angular)
    assert warning.startswith('rejected command') and 'stopping' in warning
    drive.step(0.1)
    assert drive.velocity == (0.0, 0.0)


def test_commands_beyond_the_limits_are_clamped_with_a_warning():
    limits = DriveLimits()
    linear, angular, warning = check_command(1e9, -1e9, limits)
    assert (linear, angular) == (limits.max_linear_speed, -limits.max_angular_speed)
    assert warning.startswith('clamped command (linear 1e+09 m/s, angular -1e+09 rad/s)')
    assert check_command(-0.3, 0.5, limits) == (-0.3, 0.5, None)


def test_halt_stops_forward_motion_but_not_turning():
    drive = DiffDrive(limits=INSTANT)
    drive.set_command(0.5, 0.3)
    drive.step(0.1)
    drive.halt()
    assert drive.velocity == (0.0, 0.3)


def test_drive_limits_must_be_positive():
    for bad in ({'max_linear_speed': 0.0}, {'max_angular_speed': math.inf},
                {'max_linear_accel': -1.0}, {'max_angular_accel': math.nan}):
        with pytest.raises(ValueError):
            DriveLimits(**bad)
