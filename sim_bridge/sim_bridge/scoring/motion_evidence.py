"""
What a run of a motion task shows: the evidence its handout points are judged on.

Task 2 (wanderbot, :func:`wander_evidence`): how far and how straight the robot drove, how long
it moved at all, each stop-and-turn (its angle, what was ahead as it began, whether an obstacle
ahead caused it, whether the robot drove on after it) and each stall (standing still facing an
obstacle without turning). Task 4 (wall follower, :func:`wall_follow_evidence`): the loop, and
the robot's distance to the object while it moves along it. The points
(:mod:`sim_bridge.grading.task_points`) are judged from this evidence alone; it is kept in
``metrics.json``. Plain functions of a run's ground truth, units in each docstring. Pure:
numpy, no rclpy.
"""

import math
from typing import Any, Sequence

import numpy as np
from sim_bridge.scoring.printed_values import scan_of
from sim_bridge.scoring.turns import (
    path_length, stop_and_turn_periods, true_runs, turn_angle, TURN_MIN_ANGULAR)

#: The handout's wanderbot stops when something is this close ahead (m).
STOP_DISTANCE = 0.7
#: Half the cone (rad) a stop's obstacle may be in: students look ahead with one beam or a
#: few, the kit's wanderbot along a corridor as wide as the robot.
STOP_CONE = math.radians(30.0)
#: An obstacle caused a stop-and-turn when something was this close (m) in the cone ahead as
#: it began: the handout's 0.7 m and what braking and a controller's margin add.
CAUSE_DISTANCE = 0.9
#: Driving on (m/s) while the range straight ahead is under STOP_DISTANCE minus this (m) ...
BRAKING_MARGIN = 0.2
#: ... for longer than this (s) is not stopping.
MAX_BLOCKED_DRIVING_S = 0.5
#: Forward driving: faster than this (m/s); straight: turning slower than this (rad/s). Moving:
#: the robot's centre going faster than DRIVING_SPEED over the ground (a robot pinned against a
#: wall, its wheels turning, is not moving).
DRIVING_SPEED = 0.05
STRAIGHT_ANGULAR = 0.1
#: A turn is followed by driving on within this long (s) when the robot resumes ...
RESUME_WINDOW_S = 3.0
#: ... for at least this far (m) before its next turn.
RESUME_DISTANCE = 0.2
#: Standing still (neither moving nor turning faster than TURN_MIN_ANGULAR) this long (s) with
#: something within CAUSE_DISTANCE in the cone ahead is a stop that never turned.
STALL_S = 5.0
#: The robot has reached its wall distance once within this (m) of it ...
WALL_SETTLED = 0.1
#: A wall distance (m) a student may choose: nearer scrapes the wall, farther is not following.
#: A robot moves along the object when it moves within the farther of them of its surface.
WALL_BAND = (0.2, 1.5)
#: The directions a wall follower loops in, by the sign of its winding (+1 counter-clockwise).
DIRECTIONS = {1: 'counterclockwise', -1: 'clockwise'}


def _ahead_profile(scans: Sequence[Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return each scan's time (s), range straight ahead and nearest return in the cone (m).

    Straight ahead is the nearest beam (both when two are equally near); the cone is
    STOP_CONE either side. Ranges are capped at the sensor's range_max (no return: the cap).
    """
    times, ahead, cone = [], [], []
    for snapshot in scans:
        scan = scan_of(snapshot)
        if not len(scan):
            continue
        times.append(snapshot.time)
        ahead.append(scan.range_ahead(0.0, 10.0))
        cone.append(scan.range_ahead(STOP_CONE, 10.0))
    return np.array(times, dtype=float), np.array(ahead), np.array(cone)


def _at(times: np.ndarray, values: np.ndarray, when: np.ndarray | float) -> Any:
    """Return the value of the last scan at or before ``when`` (s); the first before any."""
    index = np.clip(np.searchsorted(times, when, side='right') - 1, 0, len(times) - 1)
    return values[index]


def wander_evidence(trace: Any) -> dict[str, Any]:
    """
    Return what a wandering run shows, JSON-ready (the points are judged from it).

    ``trace`` is a run's ``Trace`` (time s, x y m, yaw rad, linear m/s, angular rad/s, scans,
    collisions). Keys: ``duration_s`` (the run's), ``moving_s`` (time moving, see
    DRIVING_SPEED), ``distance_m`` (path length), ``straight_m`` (driven forward faster than
    DRIVING_SPEED while turning slower than STRAIGHT_ANGULAR), ``blocked_driving_s`` (time
    driving forward while the range straight ahead was under STOP_DISTANCE - BRAKING_MARGIN),
    ``turns``: each stop-and-turn (``t`` s at its start, ``deg`` turned, ``ahead_m`` the
    nearest return in the cone ahead when it began, ``caused``: an obstacle ahead caused it,
    see :func:`_caused`; ``resumed``: drove on RESUME_DISTANCE within RESUME_WINDOW_S of its
    end, None when the run ended before that could be seen), ``stalls``: each stop that never
    turned (``t`` s, ``s`` long, ``ahead_m``; see STALL_S).
    """
    time, linear, angular = (trace.array(name) for name in ('time', 'linear', 'angular'))
    x, y, yaw = trace.array('x'), trace.array('y'), trace.array('yaw')
    evidence: dict[str, Any] = {'duration_s': 0.0, 'moving_s': 0.0,
                                'distance_m': path_length(x, y), 'straight_m': 0.0,
                                'blocked_driving_s': 0.0, 'turns': [], 'stalls': []}
    if len(time) < 2:
        return evidence
    steps = np.diff(time)
    step = np.hypot(np.diff(x), np.diff(y))
    moving = step > DRIVING_SPEED * steps
    forward = linear[1:] > DRIVING_SPEED
    straight = forward & (np.abs(angular[1:]) < STRAIGHT_ANGULAR)
    evidence.update(duration_s=float(time[-1] - time[0]), moving_s=float(steps[moving].sum()),
                    straight_m=float(step[straight].sum()))
    scan_times, ahead, cone = _ahead_profile(trace.scans)
    if len(scan_times):
        blocked = forward & (_at(scan_times, ahead, time[1:]) < STOP_DISTANCE - BRAKING_MARGIN)
        evidence['blocked_driving_s'] = float(steps[blocked].sum())
    touched = np.array(sorted(event.time for event in trace.collisions), dtype=float)
    travelled = np.concatenate(([0.0], np.cumsum(step)))
    periods = stop_and_turn_periods(time, linear, angular)
    approach = 0
    for number, (first, last) in enumerate(periods):
        following = periods[number + 1][0] if number + 1 < len(periods) else len(time) - 1
        ahead_m = float(_at(scan_times, cone, time[first])) if len(scan_times) else None
        evidence['turns'].append({
            't': float(time[first]), 'deg': turn_angle(yaw, first, last), 'ahead_m': ahead_m,
            'caused': _caused(ahead_m, touched, time[approach], time[first]),
            'resumed': _resumed(time, linear, travelled, last, following)})
        approach = last
    still = ~moving & (np.abs(angular[1:]) < TURN_MIN_ANGULAR)
    for first, last in true_runs(still):
        ahead_m = float(_at(scan_times, cone, time[first])) if len(scan_times) else None
        if time[last + 1] - time[first] >= STALL_S and ahead_m is not None \
                and ahead_m <= CAUSE_DISTANCE:
            evidence['stalls'].append({'t': float(time[first]), 'ahead_m': ahead_m,
                                       's': float(time[last + 1] - time[first])})
    return evidence


def _caused(ahead_m: float | None, touched: np.ndarray, since: float, until: float) -> bool:
    """
    Return whether an obstacle ahead caused a stop-and-turn that began at ``until`` (s).

    Something was within CAUSE_DISTANCE (m) in the cone ahead as it began (``ahead_m``), and
    on the way there, from ``since`` (s, the previous turn's end or the run's start), the
    robot touched nothing (``touched``: the collisions' start times, s): a turn made after
    hitting a wall (a timer's, say) was not caused by what the lidar saw.
    """
    return bool(ahead_m is not None and ahead_m <= CAUSE_DISTANCE
                and not ((touched > since) & (touched <= until)).any())


def _resumed(time: np.ndarray, linear: np.ndarray, travelled: np.ndarray, last: int,
             following: int) -> bool | None:
    """Return whether the robot drove on after a turn ending at sample ``last`` (see above)."""
    window = np.flatnonzero((time > time[last]) & (time <= time[last] + RESUME_WINDOW_S)
                            & (linear > DRIVING_SPEED))
    if not len(window):
        return None if time[-1] - time[last] < RESUME_WINDOW_S else False
    return bool(travelled[following] - travelled[window[0]] >= RESUME_DISTANCE)


def wall_follow_evidence(time: np.ndarray, x: np.ndarray, y: np.ndarray, laps: int,
                         inside: Sequence[tuple[float, float]], distances: np.ndarray,
                         declared: float | None) -> dict[str, Any]:
    """
    Return what a wall-following run shows, JSON-ready (the points are judged from it).

    ``time`` (s), ``x``/``y`` (m) the robot's path; ``laps`` and ``inside`` (points inside
    the object, m) as for ``metrics.laps_around``; ``distances`` (m) from the robot's centre
    to the object's surface at each sample; ``declared`` the distance (m) the node says it
    keeps (its parameter), else None. The robot moves along the object while it moves (see
    DRIVING_SPEED) within WALL_BAND's farther end of its surface. Keys: ``laps`` (signed, +
    counter-clockwise), ``direction`` (DIRECTIONS, '' without a loop), ``winding`` (net turns
    round the object, signed), ``distance_m`` (driven), ``along_turns`` (turns round the
    object made while moving along it, in the loop's direction, else the winding's),
    ``chosen_m`` (``declared``, else the median distance while moving along, its last two
    thirds: the first may be the way to the wall; None when it never moved along),
    ``declared_m``, ``mae_m`` (the mean error from ``chosen_m`` while moving along, from the
    first time within WALL_SETTLED of it; over all of it when never that near).
    """
    evidence: dict[str, Any] = {
        'laps': laps, 'direction': DIRECTIONS.get(int(np.sign(laps)), ''), 'winding': 0.0,
        'distance_m': path_length(x, y), 'along_turns': 0.0, 'chosen_m': None,
        'declared_m': declared, 'mae_m': None}
    if len(time) < 2 or not len(inside):
        return evidence
    centre = np.asarray(inside, dtype=float).reshape(-1, 2)[0]
    turned = np.unwrap(np.arctan2(y - centre[1], x - centre[0]))
    along = ((np.hypot(np.diff(x), np.diff(y)) > DRIVING_SPEED * np.diff(time))
             & (distances[1:] <= WALL_BAND[1]))
    along_turns = float(np.diff(turned)[along].sum() / (2.0 * math.pi))
    direction = int(np.sign(laps)) or (1 if along_turns >= 0.0 else -1)
    evidence.update(winding=float((turned[-1] - turned[0]) / (2.0 * math.pi)),
                    along_turns=direction * along_turns)
    kept = distances[1:][along]
    if not len(kept):
        return evidence
    chosen = declared if declared is not None else float(np.median(kept[len(kept) // 3:]))
    near = np.flatnonzero(np.abs(kept - chosen) <= WALL_SETTLED)
    following = kept[near[0]:] if len(near) else kept
    evidence.update(chosen_m=chosen, mae_m=float(np.abs(following - chosen).mean()))
    return evidence
