"""
Score a run from its trace: laps, wall distance, turns, stationary time, coverage, clearance.

And, when asked, what the nodes printed against the scans they received
(:mod:`sim_bridge.scoring.printed_values`).

Each score is a plain function of numpy arrays (units in its docstring); ``compute_metrics``
assembles them into the JSON-ready dict the runner writes as ``metrics.json`` and the grader's
criteria read. The world's obstacles count as the robot could hit them: their slice through the
robot's height band (``World.footprints``). Pure: numpy, contourpy and shapely (through the
footprints), no rclpy, no pybullet.
"""

import math
import re
from typing import Any, Iterable, Mapping, Sequence

import contourpy
import numpy as np
from sim_bridge.scoring.printed_values import KINDS as PRINTED_KINDS, scan_of, score_printed
from sim_bridge.scoring.run_trace import Trace
from sim_bridge.simulation.geometry import Footprint, signed_distance

# A stop-and-turn manoeuvre: turning faster than this (rad/s) ...
TURN_MIN_ANGULAR = 0.1
# ... and, at some moment of it, driving slower than this (m/s).
TURN_MAX_LINEAR = 0.02
# Turning pauses shorter than this (s) belong to the same manoeuvre (a controller re-planning).
TURN_MAX_GAP = 0.25
# Moving less than this (m) from where a pause began counts as standing still.
STATIONARY_RADIUS = 0.05
# More than the rounding error (m) of a run's path length summed step by step.
PATH_ROUNDING = 1e-6
# Side (m) of the square cells of the coverage grid.
COVERAGE_CELL = 0.5
# Most cells along a side of a grid laid over a world (coverage, offset path): what a grid
# holds is bounded, whatever the extent of the world, so a huge one costs coarser cells, not
# memory (1000 x 1000 cells: a few 8 MB arrays).
MAX_GRID_SIDE = 1000
OFFSET_GRID_SIDE = 2000
#: The handout's wanderbot stops when something is this close ahead (m).
STOP_DISTANCE = 0.7
#: Half the cone (rad) a stop's obstacle may be in: students look ahead with one beam or a
#: few, the kit's wanderbot along a corridor as wide as the robot.
STOP_CONE = math.radians(30.0)
#: Driving on (m/s) while the range straight ahead is under STOP_DISTANCE minus this (m) ...
BRAKING_MARGIN = 0.2
#: ... for longer than this (s) is not stopping.
MAX_BLOCKED_DRIVING_S = 0.5
#: Forward driving: faster than this (m/s); straight: turning slower than this (rad/s).
DRIVING_SPEED = 0.05
STRAIGHT_ANGULAR = 0.1
#: A turn is followed by driving on within this long (s) when the robot resumes ...
RESUME_WINDOW_S = 3.0
#: ... for at least this far (m) before its next turn.
RESUME_DISTANCE = 0.2
#: The robot has reached its wall distance once within this (m) of it ...
WALL_SETTLED = 0.1
#: A wall distance (m) a student may choose: nearer scrapes the wall, farther is not following.
WALL_BAND = (0.2, 1.5)
#: A parameter names the wall distance when a word of its name is one of these ...
WALL_DISTANCE_WORD = re.compile(r'dist\w*|d|wall|setpoint|target|desired')
#: ... and no word of it names a speed, a gain, an angle, a time or a tolerance.
OTHER_QUANTITY_WORD = re.compile(r'(?:speed|vel|lin|ang|gain|rate|time|tol)\w*|k[pid]?')
#: The directions a wall follower loops in, by the sign of its winding (+1 counter-clockwise).
DIRECTIONS = {1: 'counterclockwise', -1: 'clockwise'}

#: What a node error in the metrics holds: the node's name, what it raised and where, and
#: the traceback when there is one.
NODE_ERROR_KEYS = ('node', 'error', 'traceback')
#: The scores of each printed value (see printed_values.score_printed) and its worst line.
_WORST_LINE = {'t': 'number', 'node': 'text', 'text': 'text', 'what': 'text', 'printed': 'text',
               'printed_m': 'number', 'truth_m': 'list'}
_PRINTED_SCORES = {'scans': 'number', 'not_run': 'number', 'last_scan_s': 'number',
                   'lines': 'number', 'missed': 'number', 'matched_fraction': 'number',
                   'right': 'number', 'right_fraction': 'number', 'parts_right': 'number',
                   'cap_m': 'number', 'mae_m': 'number', 'worst_error_m': 'number',
                   'worst': _WORST_LINE, 'matches': 'list'}
#: What ``compute_metrics`` returns: each key's kind ('number', 'list', 'text') or, for a
#: nested dict, the kinds of its keys. Scenario criteria are checked against it.
METRIC_KINDS = {
    'sim_time_s': 'number', 'wall_time_s': 'number', 'real_time_factor': 'number',
    'collisions': 'number', 'collision_events': 'list', 'min_clearance_m': 'number',
    'distance_m': 'number', 'laps': 'number', 'lap_times_s': 'list',
    'wall_distance_m': {'mean': 'number', 'mae': 'number', 'rms': 'number',
                        'setpoint': 'number'},
    'turns_deg': 'list', 'max_stationary_s': 'number', 'coverage': 'number',
    'node_errors': 'list',
    'wander': {'distance_m': 'number', 'straight_m': 'number', 'blocked_driving_s': 'number',
               'turns': 'list'},
    'wall_follow': {'laps': 'number', 'direction': 'text', 'winding': 'number',
                    'distance_m': 'number', 'chosen_m': 'number', 'declared_m': 'number',
                    'following': 'number',
                    'mae_m': 'number'},
    'printed': {'range_ahead': _PRINTED_SCORES,
                'regions': {**_PRINTED_SCORES, 'unprinted': 'list'},
                'closest': {**_PRINTED_SCORES, 'bearing_lines': 'number',
                            'bearing_mae_deg': 'number', 'worst_bearing_error_deg': 'number',
                            'worst_bearing': {**_WORST_LINE, 'truth_deg': 'number'}}},
}


def finite_or_none(value: float | None) -> float | None:
    """Return ``value`` as a plain float, or None when it is missing, NaN or infinite."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def path_length(x: np.ndarray, y: np.ndarray) -> float:
    """Return the length (m) of the polyline through the points (``x``, ``y``) (m)."""
    if len(x) < 2:
        return 0.0
    return float(np.hypot(np.diff(x), np.diff(y)).sum())


def laps_around(time: np.ndarray, x: np.ndarray, y: np.ndarray,
                inside: Sequence[tuple[float, float]]) -> tuple[int, list[float]]:
    """
    Count the robot's completed loops around a body and time each of them.

    ``inside`` are points (x m, y m) inside the body, e.g. one per footprint's centre: the
    robot's centre can never reach them, and a loop round the whole body, whatever its shape
    (concave, thin, its centroid outside it), winds once round each of them. The angle of the
    robot's position (m) about each point is unwrapped over the run; its net angle divided by
    2π and truncated toward zero is that point's winding count. The lap count is the smallest
    in magnitude of the points' counts when all have the same sign (positive
    counter-clockwise), else 0: a lap goes round every point. Lap k ends when the last of
    the points is first wound k·2π in that direction; the second value lists each lap's
    duration (s), the first lap counted from the first sample.
    """
    points = np.asarray(inside, dtype=float).reshape(-1, 2)
    if len(time) < 2 or not len(points):
        return 0, []
    turned = np.unwrap(np.arctan2(y[:, np.newaxis] - points[:, 1],
                                  x[:, np.newaxis] - points[:, 0]), axis=0)
    turned -= turned[0]
    windings = np.trunc(turned[-1] / (2.0 * math.pi)).astype(int)
    if not (np.all(windings > 0) or np.all(windings < 0)):
        return 0, []
    direction = int(np.sign(windings[0]))
    laps = direction * int(np.abs(windings).min())
    ends = [time[0]]
    for lap in range(1, abs(laps) + 1):
        reached = direction * turned >= lap * 2.0 * math.pi
        ends.append(time[int(np.argmax(reached, axis=0).max())])
    return laps, [float(end - start) for start, end in zip(ends, ends[1:])]


def distance_stats(distances: np.ndarray, setpoint: float | None) -> dict[str, float | None]:
    """Summarise distances (m): their mean, and their MAE and RMS error against ``setpoint``."""
    stats = {'mean': None, 'mae': None, 'rms': None, 'setpoint': finite_or_none(setpoint)}
    if len(distances) == 0:
        return stats
    stats['mean'] = finite_or_none(distances.mean())
    if setpoint is not None:
        error = distances - setpoint
        stats['mae'] = finite_or_none(np.abs(error).mean())
        stats['rms'] = finite_or_none(np.sqrt(np.square(error).mean()))
    return stats


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Return the (first, last) indices, inclusive, of each maximal run of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1).tolist(),
                    (np.flatnonzero(edges == -1) - 1).tolist()))


def stop_and_turn_periods(time: np.ndarray, linear: np.ndarray,
                          angular: np.ndarray) -> list[tuple[int, int]]:
    """
    Return the (first, last) sample indices, inclusive, of each stop-and-turn manoeuvre.

    A manoeuvre is a maximal period of turning faster than ``TURN_MIN_ANGULAR`` (rad/s), with
    pauses shorter than ``TURN_MAX_GAP`` (s) bridged, during which the robot at some moment
    drives slower than ``TURN_MAX_LINEAR`` (m/s). Counting the whole turning period, not only
    its stopped part, keeps the rotation made while the robot was still braking (velocity and
    acceleration limits) in the manoeuvre. A manoeuvre still open when the run ends (turning
    at the last sample, or paused for no longer than ``TURN_MAX_GAP`` before it) is left out:
    its final angle is unknown, and scoring the part done so far would report a short turn
    that the robot never made. ``time`` in s, ``linear`` m/s, ``angular`` rad/s.
    """
    merged: list[list[int]] = []
    for first, last in true_runs(np.abs(angular) > TURN_MIN_ANGULAR):
        if merged and time[first] - time[merged[-1][1]] <= TURN_MAX_GAP:
            merged[-1][1] = last
        else:
            merged.append([first, last])
    if merged and time[-1] - time[merged[-1][1]] <= TURN_MAX_GAP:
        merged.pop()
    slow = np.abs(linear) < TURN_MAX_LINEAR
    return [(first, last) for first, last in merged if slow[first:last + 1].any()]


def turn_angle(yaw: np.ndarray, first: int, last: int) -> float:
    """Return the heading change (deg, absolute) from before sample ``first`` to ``last``."""
    heading = np.unwrap(yaw[max(first - 1, 0):last + 1])
    return math.degrees(abs(heading[-1] - heading[0]))


def stop_and_turn_angles(time: np.ndarray, linear: np.ndarray, angular: np.ndarray,
                         yaw: np.ndarray) -> list[float]:
    """
    Return the heading change (deg, absolute) of each stop-and-turn manoeuvre.

    The manoeuvres are :func:`stop_and_turn_periods`'; ``time`` in s, ``linear`` m/s,
    ``angular`` rad/s, ``yaw`` rad.
    """
    return [turn_angle(yaw, first, last)
            for first, last in stop_and_turn_periods(time, linear, angular)]


def longest_stationary(time: np.ndarray, x: np.ndarray, y: np.ndarray,
                       radius: float = STATIONARY_RADIUS) -> float:
    """
    Return the longest time (s) the robot stayed within ``radius`` (m) of where it paused.

    A pause starts at a sample and lasts while the following positions (m) stay within the
    radius of it; the next pause starts at the first sample outside. Turning in place is
    standing still.
    """
    count = len(time)
    if count < 2:
        return 0.0
    # A sample less than ``radius`` along the path from a pause's start is less than that from
    # it in a straight line too: where the robot leaves is sought from the first sample beyond
    # (less a margin for the rounding of the path's running sum).
    travelled = np.concatenate(([0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))))
    beyond = np.minimum(np.searchsorted(travelled, travelled + (radius - PATH_ROUNDING),
                                        side='right'), count - 1)
    outside = (np.hypot(x[beyond] - x, y[beyond] - y) > radius).tolist()
    beyond = beyond.tolist()
    longest = 0.0
    start = 0
    while start < count - 1:
        leave = beyond[start] if outside[start] else first_outside(x, y, start, beyond[start],
                                                                   radius)
        longest = max(longest, float(time[leave - 1] - time[start]))
        start = leave
    return longest


def first_outside(x: np.ndarray, y: np.ndarray, start: int, first: int, radius: float) -> int:
    """Return the first sample from ``first`` on farther than ``radius`` (m) from ``start``."""
    count = len(x)
    window = 64
    while True:
        stop = min(count, first + window)
        away = np.hypot(x[first:stop] - x[start], y[first:stop] - y[start]) > radius
        if away.any():
            return first + int(np.argmax(away))
        if stop == count:
            return count
        window *= 2


def coverage(x: np.ndarray, y: np.ndarray, bounds: tuple[float, float, float, float],
             obstacles: Sequence[Footprint], robot_radius: float,
             cell: float = COVERAGE_CELL) -> float | None:
    """
    Return the fraction of free grid cells the robot's centre visited, or None if none is free.

    The grid of ``cell``-sided squares (m) starts at the lower corner of ``bounds`` (xmin, ymin,
    xmax, ymax, m); a cell is free when its centre lies farther than ``robot_radius`` (m, the
    radius of the circle about the robot's origin holding its outline) from every obstacle
    footprint, i.e. the robot could stand there, whatever its heading. Bounds wider than
    MAX_GRID_SIDE cells get larger cells, as many as fit along their longer side.
    """
    xmin, ymin, xmax, ymax = bounds
    cell = max(cell, max(xmax - xmin, ymax - ymin) / MAX_GRID_SIDE)
    columns = max(1, math.ceil((xmax - xmin) / cell - 1e-9))
    rows = max(1, math.ceil((ymax - ymin) / cell - 1e-9))
    column, row = np.meshgrid(np.arange(columns), np.arange(rows), indexing='ij')
    centres = np.column_stack((xmin + (column.ravel() + 0.5) * cell,
                               ymin + (row.ravel() + 0.5) * cell))
    inside = (centres[:, 0] <= xmax) & (centres[:, 1] <= ymax)
    free = inside.copy()
    if obstacles:
        free &= signed_distance(centres, obstacles) > robot_radius
    if not free.any():
        return None
    visited = np.zeros(columns * rows, dtype=bool)
    ix = np.floor((np.asarray(x) - xmin) / cell).astype(int)
    iy = np.floor((np.asarray(y) - ymin) / cell).astype(int)
    on_grid = (ix >= 0) & (ix < columns) & (iy >= 0) & (iy < rows)
    visited[ix[on_grid] * rows + iy[on_grid]] = True
    return float((visited & free).sum() / free.sum())


def offset_path_length(footprints: Sequence[Footprint], distance: float,
                       resolution: float = 0.005) -> float:
    """
    Return the length (m) of the loop at ``distance`` (m) from the footprints' surface.

    This is the path a perfect wall follower drives around the footprints. The loop is traced
    as the level line of the signed distance on a grid of ``resolution`` (m), coarser when
    that takes more than OFFSET_GRID_SIDE points along a side; the longest line is the outer
    loop.
    """
    reach = distance + max(footprint.reach() for footprint in footprints)
    extent = 2.0 * reach + max(max(f.x for f in footprints) - min(f.x for f in footprints),
                               max(f.y for f in footprints) - min(f.y for f in footprints))
    resolution = max(resolution, extent / (OFFSET_GRID_SIDE - 4))
    reach += 2.0 * resolution
    xs = np.arange(min(f.x for f in footprints) - reach,
                   max(f.x for f in footprints) + reach, resolution)
    ys = np.arange(min(f.y for f in footprints) - reach,
                   max(f.y for f in footprints) + reach, resolution)
    grid_x, grid_y = np.meshgrid(xs, ys)
    distances = signed_distance(np.column_stack((grid_x.ravel(), grid_y.ravel())),
                                footprints).reshape(grid_x.shape)
    lines = contourpy.contour_generator(xs, ys, distances).lines(distance)
    return max(path_length(line[:, 0], line[:, 1]) for line in lines)


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
        ahead.append(scan.range_at(0.0, 0.0, max_range=10.0))
        cone.append(scan.range_at(0.0, STOP_CONE, max_range=10.0))
    return np.array(times, dtype=float), np.array(ahead), np.array(cone)


def _at(times: np.ndarray, values: np.ndarray, when: np.ndarray | float) -> Any:
    """Return the value of the last scan at or before ``when`` (s); the first before any."""
    index = np.clip(np.searchsorted(times, when, side='right') - 1, 0, len(times) - 1)
    return values[index]


def wander_evidence(trace: Any) -> dict[str, Any]:
    """
    Return what a wandering run shows, JSON-ready (the points are judged from it).

    ``trace`` is a run's ``Trace`` (time s, x y m, yaw rad, linear m/s, angular rad/s, scans).
    Keys: ``distance_m`` (path length), ``straight_m`` (driven forward faster than
    DRIVING_SPEED while turning slower than STRAIGHT_ANGULAR), ``blocked_driving_s`` (time
    driving forward while the range straight ahead was under STOP_DISTANCE - BRAKING_MARGIN),
    ``turns``: each stop-and-turn (``t`` s at its start, ``deg`` turned, ``ahead_m`` the
    nearest return in the cone ahead when it began, ``resumed``: drove on RESUME_DISTANCE
    within RESUME_WINDOW_S of its end, None when the run ended before that could be seen).
    """
    time, linear, angular = (trace.array(name) for name in ('time', 'linear', 'angular'))
    x, y, yaw = trace.array('x'), trace.array('y'), trace.array('yaw')
    evidence: dict[str, Any] = {'distance_m': path_length(x, y), 'straight_m': 0.0,
                                'blocked_driving_s': 0.0, 'turns': []}
    if len(time) < 2:
        return evidence
    step = np.hypot(np.diff(x), np.diff(y))
    forward = linear[1:] > DRIVING_SPEED
    straight = forward & (np.abs(angular[1:]) < STRAIGHT_ANGULAR)
    evidence['straight_m'] = float(step[straight].sum())
    scan_times, ahead, cone = _ahead_profile(trace.scans)
    if len(scan_times):
        blocked = _at(scan_times, ahead, time[1:]) < STOP_DISTANCE - BRAKING_MARGIN
        evidence['blocked_driving_s'] = float(np.diff(time)[forward & blocked].sum())
    travelled = np.concatenate(([0.0], np.cumsum(step)))
    periods = stop_and_turn_periods(time, linear, angular)
    for number, (first, last) in enumerate(periods):
        following = periods[number + 1][0] if number + 1 < len(periods) else len(time) - 1
        evidence['turns'].append({
            't': float(time[first]), 'deg': turn_angle(yaw, first, last),
            'ahead_m': float(_at(scan_times, cone, time[first])) if len(scan_times) else None,
            'resumed': _resumed(time, linear, travelled, last, following)})
    return evidence


def _resumed(time: np.ndarray, linear: np.ndarray, travelled: np.ndarray, last: int,
             following: int) -> bool | None:
    """Return whether the robot drove on after a turn ending at sample ``last`` (see above)."""
    window = np.flatnonzero((time > time[last]) & (time <= time[last] + RESUME_WINDOW_S)
                            & (linear > DRIVING_SPEED))
    if not len(window):
        return None if time[-1] - time[last] < RESUME_WINDOW_S else False
    return bool(travelled[following] - travelled[window[0]] >= RESUME_DISTANCE)


def _name_words(name: str) -> list[str]:
    """Return the words of a parameter's name, lower case: 'wallDist_m' gives wall, dist, m."""
    return [word.lower() for word in re.findall(r'[A-Z]?[a-z]+|[A-Z]+(?![a-z])|\d+', name)]


def declared_wall_distance(nodes_values: Iterable[Mapping[str, float]]) -> float | None:
    """
    Return the wall distance (m) a node declares as a parameter, or None when it declares none.

    ``nodes_values`` holds each node's numeric parameters by name. The distance is the value of
    the parameter whose name says it, a number within WALL_BAND: a word of its name (split at
    '_', '-', '.' and capitals) is a WALL_DISTANCE_WORD and none an OTHER_QUANTITY_WORD
    (``distance``, ``wall_distance``, ``desired_distance``, ``target_dist``, ``d``,
    ``setpoint``, ``followDistance``; not ``target_speed``, ``wall_gain``); exactly one such
    parameter, or several of one value. None when there is none, or several of different
    values: the run's behaviour then tells the distance the node chose.
    """
    low, high = WALL_BAND
    values = set()
    for node_values in nodes_values:
        for name, value in node_values.items():
            words = _name_words(name)
            if (low <= value <= high and any(map(WALL_DISTANCE_WORD.fullmatch, words))
                    and not any(map(OTHER_QUANTITY_WORD.fullmatch, words))):
                values.add(float(value))
    return values.pop() if len(values) == 1 else None


def wall_follow_evidence(time: np.ndarray, x: np.ndarray, y: np.ndarray, laps: int,
                         inside: Sequence[tuple[float, float]], distances: np.ndarray,
                         declared: float | None) -> dict[str, Any]:
    """
    Return what a wall-following run shows, JSON-ready (the points are judged from it).

    ``time`` (s), ``x``/``y`` (m) the robot's path; ``laps`` and ``inside`` (points inside
    the object, m) as for :func:`laps_around`; ``distances`` (m) from the robot's centre to
    the object's surface at each sample; ``declared`` the distance (m) the node says it keeps (its
    parameter), else None: then the distance it chose is its behaviour's, the median of the
    last two thirds of the run (the first third may be the way to the wall). Keys: ``laps``
    (signed, + counter-clockwise), ``direction`` (DIRECTIONS, '' without a loop),
    ``winding`` (net turns round the object, signed), ``distance_m`` (driven), ``chosen_m``
    and ``declared_m`` (None when not declared), ``following`` (share of the run from the
    first sample within WALL_SETTLED of it), ``mae_m`` (mean error from there on; over the
    whole run when it never came that near).
    """
    evidence: dict[str, Any] = {
        'laps': laps, 'direction': DIRECTIONS.get(int(np.sign(laps)), ''), 'winding': 0.0,
        'distance_m': path_length(x, y), 'chosen_m': None, 'declared_m': declared,
        'following': 0.0, 'mae_m': None}
    if len(time) < 2 or not len(inside):
        return evidence
    centre = np.asarray(inside, dtype=float).reshape(-1, 2)[0]
    turned = np.unwrap(np.arctan2(y - centre[1], x - centre[0]))
    evidence['winding'] = float((turned[-1] - turned[0]) / (2.0 * math.pi))
    chosen = declared if declared is not None else float(
        np.median(distances[len(distances) // 3:]))
    evidence['chosen_m'] = chosen
    near = np.flatnonzero(np.abs(distances - chosen) <= WALL_SETTLED)
    following = distances[near[0]:] if len(near) else distances
    evidence['following'] = len(following) / len(distances) if len(near) else 0.0
    evidence['mae_m'] = float(np.abs(following - chosen).mean())
    return evidence


def compute_metrics(trace: Trace, world: Any, *, setpoint: float | None = None,
                    wall_time_s: float,
                    node_errors: Iterable[Mapping[str, str]] = (),
                    log_lines: Sequence[Mapping[str, Any]] = (), printed: Iterable[str] = (),
                    runner_nodes: Iterable[str] = (),
                    duration_s: float | None = None) -> dict[str, Any]:
    """
    Score a run; return a JSON-serialisable dict (plain floats and ints, None for no value).

    ``world`` is the run's ``World`` (obstacles, target, bounds); every score reads what the
    robot could hit, the world's slice through its height band (``World.footprints``), and the
    target's part of it (or, when the target lies wholly above or below the robot, its whole
    outline, the only one a robot could circle); ``setpoint`` (m) the wall
    distance the node aims for, if it has one; ``wall_time_s`` (s) how long the run took;
    ``node_errors`` the failures to report, each a mapping with ``node``, ``error`` and
    optionally ``traceback``; ``log_lines`` what the nodes printed (dicts with ``t`` s,
    ``node``, ``level``, ``text``, ``line``), scored for the ``printed`` values (of
    printed_values.KINDS) against the trace's scans, the lines of ``runner_nodes`` (the
    simulator's own) left out (see printed_values.score_printed), over the scenario's
    ``duration_s`` (s) when given: the scans of a run that stopped before it are scans missed.
    """
    time, x, y = trace.array('time'), trace.array('x'), trace.array('y')
    sim_time = float(time[-1]) if len(time) else 0.0
    clearance = trace.array('clearance')
    clearance = clearance[np.isfinite(clearance)]
    laps, lap_times = 0, []
    wall_distance = distance_stats(np.empty(0), None)
    wall_follow = None
    if world.target is not None and len(time):
        target = (world.obstacle_footprints(world.target)
                  or world.obstacle(world.target).footprints)
        # Each footprint's centre lies inside the target, where the robot's centre never goes
        # (a polygon's centre is a point inside it).
        inside = [(fp.x, fp.y) for fp in target]
        laps, lap_times = laps_around(time, x, y, inside)
        distances = signed_distance(np.column_stack((x, y)), target)
        wall_distance = distance_stats(distances, setpoint)
        wall_follow = wall_follow_evidence(time, x, y, laps, inside, distances,
                                           setpoint)
    obstacles = world.footprints()
    printed = set(printed)
    return {
        'sim_time_s': sim_time,
        'wall_time_s': finite_or_none(wall_time_s),
        'real_time_factor': finite_or_none(sim_time / wall_time_s) if wall_time_s > 0 else None,
        'collisions': len(trace.collisions),
        'collision_events': [
            {'time': float(event.time), 'x': float(event.x), 'y': float(event.y),
             'obstacle': str(event.obstacle)} for event in trace.collisions],
        'min_clearance_m': finite_or_none(clearance.min()) if len(clearance) else None,
        'distance_m': path_length(x, y),
        'laps': laps,
        'lap_times_s': lap_times,
        'wall_distance_m': wall_distance,
        'turns_deg': stop_and_turn_angles(time, trace.array('linear'), trace.array('angular'),
                                          trace.array('yaw')),
        'max_stationary_s': longest_stationary(time, x, y),
        'coverage': coverage(x, y, world.bounds, obstacles, trace.robot_radius),
        'wander': wander_evidence(trace),
        'wall_follow': wall_follow,
        'node_errors': [{key: str(error[key]) for key in NODE_ERROR_KEYS if key in error}
                        for error in node_errors],
        'printed': {kind: score_printed(kind, trace.scans, log_lines, ignore_nodes=runner_nodes,
                                        not_run_s=max((duration_s or 0.0) - sim_time, 0.0),
                                        scan_period_s=trace.scan_period_s)
                    for kind in PRINTED_KINDS if kind in printed},
    }
