"""
Task 2's and task 4's points judged on synthetic runs of nodes written to game them.

Each point is evidence that the node did the thing it names, over the whole run: a wanderbot
that turns on a timer, never reads the lidar, stops for good or turns exactly 90 degrees, and a
wall follower that parks or crashes after a metre, earn only what a TA gives them; an honest
one keeps every point. The runs are simulated here, in a square room, by plain functions of
the range ahead (a node's decision), so each behaviour is known by construction.
"""

import math

import numpy as np
import pytest

from sim_bridge.grading.task_points import judge_points, TURN_MARGIN_DEG
from sim_bridge.scoring.motion_evidence import wall_follow_evidence, wander_evidence
from sim_bridge.scoring.run_trace import CollisionEvent, ScanSnapshot, Trace

STEP = 0.01  # s, the runner's physics step
SCAN_EVERY = 10  # steps: the lab robot's 10 Hz lidar
HALF_ROOM = 3.0  # m, walls at x = +-3 and y = +-3
RADIUS = 0.15  # m, the robot's
BEAMS = -1.57 + np.arange(36) * (3.14 / 35)  # rad, the lab lidar's beams


def wall_range(x, y, heading):
    """Return the range (m) from (x, y) (m) along ``heading`` (rad) to the room's walls."""
    reach = []
    for position, direction in ((x, math.cos(heading)), (y, math.sin(heading))):
        if abs(direction) > 1e-9:
            reach.append((math.copysign(HALF_ROOM, direction) - position) / direction)
    return min(reach)


def room_run(node, duration, start=(0.0, -0.5, 0.0)):
    """
    Return the trace of ``node`` driving the robot in the square room for ``duration`` (s).

    ``node(t, ahead, memory)`` returns (linear m/s, angular rad/s) from the time (s) and the
    last scan's range straight ahead (m); ``memory`` is a dict it may keep state in. A move
    that would bring the robot's body to a wall is not made (the robot is pinned there, its
    achieved speed 0), and each new contact is a collision.
    """
    trace = Trace(robot_radius=RADIUS)
    x, y, yaw = start
    ahead, memory, touching = wall_range(x, y, yaw), {}, False
    for step in range(1, round(duration / STEP) + 1):
        time = step * STEP
        linear, angular = node(time, ahead, memory)
        yaw = math.atan2(math.sin(yaw + angular * STEP), math.cos(yaw + angular * STEP))
        nx, ny = x + linear * math.cos(yaw) * STEP, y + linear * math.sin(yaw) * STEP
        blocked = HALF_ROOM - max(abs(nx), abs(ny)) <= RADIUS
        if blocked and not touching:
            trace.collisions.append(CollisionEvent(time, x, y, 'room'))
        touching = blocked
        if not blocked:
            x, y = nx, ny
        trace.append(time, x, y, yaw, 0.0 if blocked else linear, angular,
                     HALF_ROOM - max(abs(x), abs(y)) - RADIUS)
        if step % SCAN_EVERY == 0:
            ranges = np.array([wall_range(x, y, yaw + beam) for beam in BEAMS], np.float32)
            trace.scans.append(ScanSnapshot(time, (x, y, yaw), ranges, -1.57, 3.14 / 35,
                                            0.12, 10.0))
            ahead = float(ranges[18])
    return trace


def wanderer(turn_deg=(110.0, 135.0, 160.0), turn_rate=1.0, stop_for_good_after=None):
    """
    Return a node that stops within 0.7 m of what is ahead, turns, and drives on (0.3 m/s).

    Its turns take the angles ``turn_deg`` (deg) in turn, timed at ``turn_rate`` (rad/s) to
    the step, as a node on a fast timer does; with ``stop_for_good_after`` turns, it stops at
    the next obstacle and never turns again (a counter never set back).
    """
    def node(time, ahead, memory):
        turns = memory.setdefault('turns', 0)
        if time < memory.get('turn_until', 0.0):
            return 0.0, turn_rate
        if ahead >= 0.7:
            return 0.3, 0.0
        if stop_for_good_after is not None and turns >= stop_for_good_after:
            return 0.0, 0.0
        angle = math.radians(turn_deg[turns % len(turn_deg)])
        memory['turns'] = turns + 1
        memory['turn_until'] = time + math.ceil(angle / turn_rate / STEP) * STEP
        return 0.0, turn_rate
    return node


def timed_shuttle(leg_s):
    """Return a node that never reads the lidar: ``leg_s`` (s) at 0.5 m/s, a half turn, again."""
    half_turn = math.pi / 0.8

    def node(time, ahead, memory):
        return (0.5, 0.0) if time % (leg_s + half_turn) < leg_s else (0.0, 0.8)
    return node


def points_of(point_set, metrics):
    return {point.point: point for point in judge_points(point_set, metrics)}


def wander_marks(trace):
    """Return the task 2 marks (of 3) a run earns, and its points by name."""
    points = points_of('wander', {'wander': wander_evidence(trace),
                                  'collisions': len(trace.collisions)})
    return sum(0.5 for point in points.values() if point.earned), points


def test_an_honest_wanderbot_keeps_every_point():
    marks, points = wander_marks(room_run(wanderer(), 180.0))
    assert marks == 3.0, {name: point.reason for name, point in points.items()}


@pytest.mark.parametrize('leg_s', [5.0, 9.0])
def test_a_timed_shuttle_that_never_reads_the_lidar_earns_no_stop_turn_resume_or_repeat(leg_s):
    # 5 s legs turn in mid-room and never collide; 9 s legs end against a wall each time.
    trace = room_run(timed_shuttle(leg_s), 180.0)
    marks, points = wander_marks(trace)
    assert not any(points[name].earned for name in (
        'stops when something is within 0.7 m ahead', 'turns more than 90 degrees',
        'resumes driving straight after a turn', 'repeats the sequence'))
    assert 'not caused by an obstacle ahead' in points['turns more than 90 degrees'].reason
    assert points['drives straight'].earned
    assert marks == (1.0 if not trace.collisions else 0.5)


def test_a_wanderbot_that_stops_for_good_at_its_second_obstacle_keeps_the_stop_only():
    marks, points = wander_marks(room_run(wanderer(stop_for_good_after=1), 180.0))
    assert [name for name, point in points.items() if point.earned] == [
        'stops when something is within 0.7 m ahead']
    assert 'stuck for most of the run' in points['repeats the sequence'].reason
    assert '1 stop(s) that never turned' in points['turns more than 90 degrees'].reason
    assert marks == 0.5


def test_a_robot_pinned_on_a_wall_for_most_of_the_run_earns_nothing():
    def pinned(time, ahead, memory):  # looks at the rightmost beam only: never sees the wall
        return (0.4, 0.0) if time > 2.0 else (0.0, 0.5)
    marks, points = wander_marks(room_run(pinned, 180.0))
    assert marks == 0.0
    assert 'stuck for most of the run' in points['drives straight'].reason


def test_a_timed_turn_of_exactly_90_degrees_is_not_more_than_90():
    trace = room_run(wanderer(turn_deg=(90.0,), turn_rate=0.5), 180.0)
    turns = wander_evidence(trace)['turns']
    assert all(90.0 < turn['deg'] < 90.0 + TURN_MARGIN_DEG for turn in turns)  # 90 + a step
    marks, points = wander_marks(trace)
    assert [name for name, point in points.items() if not point.earned] == [
        'turns more than 90 degrees']
    assert marks == 2.5


def test_a_turn_clearly_above_90_degrees_is_more_than_90():
    marks, points = wander_marks(room_run(wanderer(turn_deg=(95.0,), turn_rate=0.5), 180.0))
    assert marks == 3.0, {name: point.reason for name, point in points.items()}


def along_then(stop_after_m, then, duration=60.0, steps=3000, side=0.7):
    """
    Return (time, x, y, distances) of a robot that follows a 2 m x 1 m box's north face.

    It starts ``side`` (m) from the face, heading east at 0.3 m/s, and after ``stop_after_m``
    (m): ``'park'`` stays put, ``'crash'`` steers right into the face.
    """
    time = np.linspace(0.0, duration, steps)
    x = np.minimum(-1.0 + 0.3 * time, -1.0 + stop_after_m)
    y = np.full(steps, 0.5 + side)
    if then == 'crash':
        after = np.clip(0.3 * time - stop_after_m, 0.0, side - RADIUS)
        y = y - after
    distances = y - 0.5
    return time, x, y, distances


@pytest.mark.parametrize('then', ['park', 'crash'])
def test_a_follower_that_parks_or_crashes_after_a_metre_gets_none_of_the_three(then):
    time, x, y, distances = along_then(1.2, then)
    evidence = wall_follow_evidence(time, x, y, 0, [(0.0, 0.0)], distances, None)
    points = points_of('wall_follow', {'wall_follow': evidence,
                                       'collisions': int(then == 'crash')})
    assert not any(point.earned for point in points.values())
    assert 'not following it' in points['keeps the wall at the distance it chose'].reason


def test_every_motion_point_states_its_rule_with_the_handouts_sentence_and_margin():
    nothing = {'wander': wander_evidence(Trace(RADIUS)), 'wall_follow': wall_follow_evidence(
        np.zeros(0), np.zeros(0), np.zeros(0), 0, [], np.zeros(0), None)}
    rules = {(point_set, point.point): point.rule for point_set in ('wander', 'wall_follow')
             for point in judge_points(point_set, nothing)}
    assert all(rule.startswith('"') and rule.count('"') == 2 for rule in rules.values()), rules
    assert f'{90 + TURN_MARGIN_DEG:g}°' in rules['wander', 'turns more than 90 degrees']
    assert '50 % of the run' in rules['wander', 'no collision']
    assert '0.75 of a loop' in rules['wall_follow', 'keeps the wall at the distance it chose']
    assert '0.15 m' in rules['wall_follow', 'keeps the wall at the distance it chose']
