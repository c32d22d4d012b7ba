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
from sim_bridge.scoring.motion_evidence import WALL_BAND, wall_follow_evidence, wander_evidence
from sim_bridge.scoring.printed_values import KINDS as PRINTED_KINDS, score_printed
from sim_bridge.scoring.run_trace import Trace
from sim_bridge.scoring.turns import path_length, stop_and_turn_angles
from sim_bridge.simulation.geometry import Footprint, signed_distance

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
#: A parameter names the wall distance when a word of its name is one of these ...
WALL_DISTANCE_WORD = re.compile(r'dist\w*|d|wall|setpoint|target|desired')
#: ... and no word of it names a speed, a gain, an angle, a time or a tolerance.
OTHER_QUANTITY_WORD = re.compile(r'(?:speed|vel|lin|ang|gain|rate|time|tol)\w*|k[pid]?')

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
    'wander': {'duration_s': 'number', 'moving_s': 'number', 'distance_m': 'number',
               'straight_m': 'number', 'blocked_driving_s': 'number', 'turns': 'list',
               'stalls': 'list'},
    'wall_follow': {'laps': 'number', 'direction': 'text', 'winding': 'number',
                    'distance_m': 'number', 'along_turns': 'number', 'chosen_m': 'number',
                    'declared_m': 'number', 'mae_m': 'number'},
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
