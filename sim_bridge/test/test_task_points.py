"""The handout's points of each task, judged on synthetic runs whose behaviour is known."""

import math

import numpy as np
import pytest

from sim_bridge.grading.task_points import judge_points
from sim_bridge.scoring.metrics import wall_follow_evidence, wander_evidence
from sim_bridge.scoring.run_trace import ScanSnapshot, Trace

STEP = 0.01  # s, the runner's physics step
SCAN_PERIOD = 0.1  # s, the lab robot's lidar
WALL_X = 3.0  # m, walls at x = +-3 across the robot's line of travel


def corridor_run(segments):
    """
    Return the trace of a robot driving along x between walls at +-WALL_X, and its scans.

    ``segments`` are (linear m/s, angular rad/s, duration s); the turns are half turns, so the
    robot always heads along +x or -x, and every beam of a scan sees the wall ahead.
    """
    trace = Trace(robot_radius=0.15)
    time = x = yaw = 0.0
    for linear, angular, duration in segments:
        for _ in range(round(duration / STEP)):
            time += STEP
            yaw += angular * STEP
            x += linear * math.cos(yaw) * STEP
            trace.append(time, x, 0.0, math.atan2(math.sin(yaw), math.cos(yaw)), linear,
                         angular, 1.0)
            if round(time / STEP) % round(SCAN_PERIOD / STEP) == 0:
                ahead = WALL_X - x if math.cos(yaw) > 0 else WALL_X + x
                trace.scans.append(ScanSnapshot(time, (x, 0.0, yaw),
                                                np.full(36, ahead, dtype=np.float32),
                                                -1.57, 3.14 / 35, 0.12, 10.0))
    return trace


def wander_cycles(count, stop_at=0.65, speed=0.5, turn_deg=180.0):
    """Drive to ``stop_at`` (m) from the wall ahead, stop, turn, and again, ``count`` times."""
    segments = [(speed, 0.0, (WALL_X - stop_at) / speed)]
    turn = (math.pi / 2, 0.0)
    for _ in range(count):
        segments += [(0.0, turn[0], math.radians(turn_deg) / turn[0]),
                     (speed, 0.0, 2.0 * (WALL_X - stop_at) / speed)]
    return segments


def points_of(point_set, metrics):
    return {point.point: point for point in judge_points(point_set, metrics)}


def test_a_wanderbot_that_does_what_the_handout_asks_earns_every_point():
    trace = corridor_run(wander_cycles(4))
    points = points_of('wander', {'wander': wander_evidence(trace), 'collisions': 0})
    assert all(point.earned for point in points.values()), points
    assert len(points) == 6


def test_driving_into_the_wall_costs_the_stop_and_collision_points_only():
    trace = corridor_run(wander_cycles(4, stop_at=0.2))
    points = points_of('wander', {'wander': wander_evidence(trace), 'collisions': 1})
    lost = {name for name, point in points.items() if not point.earned}
    assert lost == {'stops when something is within 0.7 m ahead', 'no collision'}
    assert 'drove on for' in points['stops when something is within 0.7 m ahead'].reason


def test_each_turn_is_measured_and_resumed():
    evidence = wander_evidence(corridor_run(wander_cycles(3)))
    assert [turn['deg'] for turn in evidence['turns']] == pytest.approx([180.0] * 3, abs=1.0)
    assert [turn['resumed'] for turn in evidence['turns']] == [True] * 3
    assert [turn['ahead_m'] for turn in evidence['turns']] == pytest.approx([0.65] * 3, abs=0.06)
    assert evidence['straight_m'] == pytest.approx(evidence['distance_m'])


GOOD_WANDER = {'duration_s': 180.0, 'moving_s': 160.0, 'distance_m': 40.0, 'straight_m': 38.0,
               'blocked_driving_s': 0.0, 'stalls': [],
               'turns': [{'t': 5.0 * n, 'deg': 130.0, 'ahead_m': 0.65, 'caused': True,
                          'resumed': True} for n in range(6)]}


def test_a_wanderbot_turning_45_degrees_loses_that_point_only():
    turns = [{**turn, 'deg': 45.0} for turn in GOOD_WANDER['turns']]
    points = points_of('wander', {'wander': {**GOOD_WANDER, 'turns': turns}, 'collisions': 0})
    lost = [point for point in points.values() if not point.earned]
    assert [point.point for point in lost] == ['turns more than 90 degrees']
    assert lost[0].reason == '6 of 6 stops without a turn of 92° or more (smallest 45.0°)'


def test_a_collision_costs_its_point_not_the_task():
    points = points_of('wander', {'wander': GOOD_WANDER, 'collisions': 2})
    assert [name for name, point in points.items() if not point.earned] == ['no collision']
    assert points['no collision'].reason == '2 collision(s)'


def test_a_wanderbot_that_does_nothing_earns_nothing_not_even_no_collision():
    still = {'distance_m': 0.0, 'straight_m': 0.0, 'blocked_driving_s': 0.0, 'turns': []}
    points = points_of('wander', {'wander': still, 'collisions': 0})
    assert not any(point.earned for point in points.values())
    assert all(point.reason for point in points.values())


def circle_around(turns, radius, steps=2000):
    angles = np.linspace(0.0, -2.0 * math.pi * turns, steps)
    time = np.linspace(0.0, 60.0, steps)
    return time, radius * np.cos(angles), radius * np.sin(angles)


@pytest.mark.parametrize('declared', [0.7, None])
def test_a_careful_one_direction_follower_at_its_own_distance_earns_every_point(declared):
    time, x, y = circle_around(1.2, radius=1.0 + 0.7)
    distances = np.hypot(x, y) - 1.0
    evidence = wall_follow_evidence(time, x, y, -1, [(0.0, 0.0)], distances, declared)
    assert evidence['direction'] == 'clockwise'
    assert evidence['chosen_m'] == pytest.approx(0.7)
    points = points_of('wall_follow', {'wall_follow': evidence, 'collisions': 0})
    assert all(point.earned for point in points.values()), points


def test_a_follower_far_from_the_wall_without_a_loop_shows_none_of_the_three():
    time, x, y = circle_around(0.3, radius=1.0 + 2.4)
    evidence = wall_follow_evidence(time, x, y, 0, [(0.0, 0.0)], np.hypot(x, y) - 1.0, None)
    points = points_of('wall_follow', {'wall_follow': evidence, 'collisions': 0})
    assert not any(point.earned for point in points.values())
    assert points['loops the object in one direction'].reason == (
        'went 0.30 of the way round the object: no full loop')
    assert points['keeps the wall at the distance it chose'].reason == (
        'moved along the object for 0.00 of a loop only (0.75 wanted): not following it')


def test_a_wavering_wall_distance_loses_that_point_with_its_error():
    time, x, y = circle_around(1.2, radius=1.7)
    distances = 0.7 + 0.3 * np.sin(np.linspace(0.0, 40.0, len(time)))
    evidence = wall_follow_evidence(time, x, y, -1, [(0.0, 0.0)], distances, 0.7)
    point = points_of('wall_follow', {'wall_follow': evidence, 'collisions': 0})[
        'keeps the wall at the distance it chose']
    assert not point.earned
    assert point.reason.startswith('wall distance off 0.70 m (its parameter) by 0.19 m')


def scored(fraction, worst_error, unprinted=()):
    right = round(100 * fraction) - (worst_error > 0.06)
    return {'scans': 100, 'lines': 500, 'missed': round(100 * (1 - fraction)),
            'matched_fraction': fraction, 'mae_m': worst_error / 2, 'right': right,
            'right_fraction': right / 100, 'parts_right': min(right, 10), 'not_run': 0,
            'worst_error_m': worst_error, 'unprinted': list(unprinted),
            'worst': {'t': 18.1, 'node': 'scan_around', 'text': 'Range left: 10',
                      'what': 'left', 'printed': '10', 'printed_m': 10.0,
                      'truth_m': [1.19, 1.19]}}


def test_a_reading_task_earns_each_point_on_its_own():
    points = points_of('regions', {'printed': {'regions': scored(1.0, 8.81)}})
    assert [point.earned for point in points.values()] == [True, False]
    assert 'left printed 10 at t=18.1 s, truth 1.19 m' in list(points.values())[1].reason
    points = points_of('regions', {'printed': {'regions': scored(0.0, 0.0, ['front'])}})
    assert [point.earned for point in points.values()] == [False, False]
    assert all('(front never printed)' in point.reason for point in points.values())


def test_a_reading_node_that_printed_nothing_earns_nothing():
    points = judge_points('range_ahead', {'printed': {}})
    assert [point.earned for point in points] == [False, False]
    assert all(point.reason for point in points)
