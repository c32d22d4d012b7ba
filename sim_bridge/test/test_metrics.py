"""Scores of synthetic runs whose laps, distances, turns and pauses are known by construction."""

from dataclasses import replace
import json
import math
import tracemalloc

import numpy as np
import pytest

from sim_bridge.scoring.metrics import (compute_metrics, coverage, laps_around, longest_stationary,
                                        METRIC_KINDS, offset_path_length, stop_and_turn_angles)
from sim_bridge.scoring.printed_values import KINDS as PRINTED_KINDS
from sim_bridge.scoring.run_trace import CollisionEvent, ScanSnapshot, Trace
from sim_bridge.simulation.geometry import Footprint, Shape, signed_distance
from sim_bridge.simulation.world import Obstacle, World

STEP = 0.01  # s, the runner's physics step


def make_world(obstacles, target=None, bounds=None, robot_pose=(4.0, -1.0, 0.0)):
    data = {'obstacles': obstacles, 'target': target, 'robot': {'pose': list(robot_pose)}}
    if bounds is not None:
        data['bounds'] = list(bounds)
    return World.from_dict(data, 'test world')


PILLAR = {'name': 'pillar', 'type': 'cylinder', 'radius': 1.0, 'length': 1.0, 'pose': [1.0, 2.0]}
PILLAR_WORLD = make_world([PILLAR], 'pillar', (-3.0, -2.0, 5.0, 6.0))


def make_trace(x, y, yaw=None, linear=None, angular=None, clearance=None, robot_radius=0.2):
    count = len(x)
    columns = {'time': STEP * np.arange(1, count + 1), 'x': x, 'y': y,
               'yaw': np.zeros(count) if yaw is None else yaw,
               'linear': np.zeros(count) if linear is None else linear,
               'angular': np.zeros(count) if angular is None else angular,
               'clearance': np.ones(count) if clearance is None else clearance}
    trace = Trace(robot_radius=robot_radius)
    for index in range(count):
        trace.append(**{name: values[index] for name, values in columns.items()})
    return trace


def circle_path(turns, radius=1.5, centre=(1.0, 2.0), steps_per_turn=600, start_angle=0.3):
    angles = start_angle + np.linspace(0.0, 2.0 * math.pi * turns,
                                       int(abs(turns) * steps_per_turn) + 1)
    return centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)


def drive(commands):
    """Integrate (linear m/s, angular rad/s, duration s) segments into a unicycle trace."""
    linear = np.concatenate([np.full(round(duration / STEP), v) for v, _, duration in commands])
    angular = np.concatenate([np.full(round(duration / STEP), w) for _, w, duration in commands])
    yaw = np.cumsum(angular) * STEP
    x = np.cumsum(linear * np.cos(yaw)) * STEP
    y = np.cumsum(linear * np.sin(yaw)) * STEP
    return make_trace(x, y, yaw=np.angle(np.exp(1j * yaw)), linear=linear, angular=angular)


def metrics_of(trace, world=PILLAR_WORLD, **kwargs):
    return compute_metrics(trace, world, wall_time_s=kwargs.pop('wall_time_s', 1.0), **kwargs)


@pytest.mark.parametrize('turns, laps', [(2.3, 2), (-2.3, -2), (1.05, 1), (-1.05, -1),
                                         (0.5, 0), (-0.97, 0)])
def test_laps_count_completed_loops_signed_by_direction(turns, laps):
    assert metrics_of(make_trace(*circle_path(turns)))['laps'] == laps


def test_each_lap_time_is_the_duration_of_that_loop():
    x, y = circle_path(-2.5, steps_per_turn=1000)
    laps, lap_times = laps_around(STEP * np.arange(len(x)), x, y, [(1.0, 2.0)])
    assert laps == -2
    assert lap_times == pytest.approx([10.0, 10.0], abs=2 * STEP)


def test_going_round_and_coming_back_is_no_lap():
    x_out, y_out = circle_path(0.8)
    x_back, y_back = circle_path(-0.8, start_angle=0.3 + 0.8 * 2 * math.pi)
    trace = make_trace(np.concatenate((x_out, x_back)), np.concatenate((y_out, y_back)))
    assert metrics_of(trace)['laps'] == 0


def polyline(vertices, speed=0.3, loops=1.0):
    """
    Sample the closed loop through ``vertices`` (m), from the first, once per STEP at ``speed``.

    ``loops`` times round (negative: backwards through the vertices). Returns x, y (m) and the
    loop's length (m).
    """
    vertices = np.asarray(vertices, dtype=float)
    if loops < 0:
        vertices = np.vstack((vertices[:1], vertices[:0:-1]))
    closed = np.vstack((vertices, vertices[:1]))
    along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))))
    length = along[-1]
    travelled = speed * STEP * np.arange(round(abs(loops) * length / (speed * STEP)) + 1)
    where = np.where(travelled > 0, np.mod(travelled, length), 0.0)
    where[(where == 0.0) & (travelled > 0)] = length
    return np.interp(where, along, closed[:, 0]), np.interp(where, along, closed[:, 1]), length


def there_and_back(x, y):
    """Return the path (``x``, ``y``) (m) followed by the same path driven back."""
    return np.concatenate((x, x[-2::-1])), np.concatenate((y, y[-2::-1]))


def rotated(points, yaw):
    """Return (x, y) points (m) turned by ``yaw`` (rad) about the origin."""
    cos, sin = math.cos(yaw), math.sin(yaw)
    return [(cos * x - sin * y, sin * x + cos * y) for x, y in points]


# Loops 0.5 m off the shipped wall-follow targets, clockwise from each world's start, with
# square corners outside the convex ones (0.71 m from them) and mitred at the concave ones.
# The U (walls 0.3 m thick, x from -1.3 to 1.3, y from -1.4 to 1.4, the notch between x = -1
# and 1 open towards +y) is circled into its notch down to 0.5 m above its bottom (y = -1.1).
U_LOOP = [(0.0, -1.9), (-1.8, -1.9), (-1.8, 1.9), (-0.5, 1.9), (-0.5, -0.6), (0.5, -0.6),
          (0.5, 1.9), (1.8, 1.9), (1.8, -1.9)]
# The U's area centroid, (0, -0.329): in the notch, outside the loop above.
U_CENTROID = (0.0, (2.6 * 0.3 * -1.25 + 2 * 0.3 * 2.5 * 0.15) / (2.6 * 0.3 + 2 * 0.3 * 2.5))
# The cross: two 3 m x 0.8 m bars crossing at the origin, concave corners at (+-0.4, +-0.4).
CROSS_LOOP = [(0.0, -2.0), (-0.9, -2.0), (-0.9, -0.9), (-2.0, -0.9), (-2.0, 0.9), (-0.9, 0.9),
              (-0.9, 2.0), (0.9, 2.0), (0.9, 0.9), (2.0, 0.9), (2.0, -0.9), (0.9, -0.9),
              (0.9, -2.0)]
# The thin wall: 3 m x 0.1 m along x at the origin.
THIN_WALL_LOOP = [(0.0, 0.55), (2.0, 0.55), (2.0, -0.55), (-2.0, -0.55), (-2.0, 0.55)]
# The 2 m x 1 m box turned 0.6 rad about the origin.
BOX_ROTATED_LOOP = rotated([(0.0, 1.0), (1.5, 1.0), (1.5, -1.0), (-1.5, -1.0), (-1.5, 1.0)],
                           0.6)
# The post of radius 0.1 m at the origin, circled at 0.5 m from its surface.
POST_LOOP = [(0.6 * math.sin(angle), 0.6 * math.cos(angle))
             for angle in np.linspace(0.0, 2.0 * math.pi, 120, endpoint=False)]
SHAPE_LOOPS = {'wall_follow_u_shape': U_LOOP, 'wall_follow_cross': CROSS_LOOP,
               'wall_follow_thin_wall': THIN_WALL_LOOP, 'wall_follow_post': POST_LOOP,
               'wall_follow_box_rotated': BOX_ROTATED_LOOP}


@pytest.mark.parametrize('world_name', SHAPE_LOOPS)
@pytest.mark.parametrize('loops', [-1, 1])
def test_one_loop_round_any_shape_is_one_lap_timed_by_its_length(world_name, loops):
    world = World.load(world_name)
    target = world.obstacle(world.target)
    x, y, length = polyline(SHAPE_LOOPS[world_name], loops=-1.05 * loops)
    # 0.5 m off, but for the post's 120-gon (0.2 mm inside the circle at its chords' middles).
    assert np.all(signed_distance(np.column_stack((x, y)), target.footprints) >= 0.4997)
    metrics = metrics_of(make_trace(x, y), world)
    assert metrics['laps'] == loops
    assert metrics['lap_times_s'] == pytest.approx([length / 0.3], abs=2 * STEP)


def test_a_loop_round_a_u_into_its_notch_is_a_lap_though_it_leaves_out_the_centroid():
    world = World.load('wall_follow_u_shape')
    x, y, _ = polyline(U_LOOP)
    # The loop winds 0 times about the U's centroid: the angle about it comes back unchanged.
    turned = np.unwrap(np.arctan2(y - U_CENTROID[1], x - U_CENTROID[0]))
    assert abs(turned[-1] - turned[0]) < 1e-9
    assert metrics_of(make_trace(*polyline(U_LOOP, loops=1.05)[:2]), world)['laps'] == -1


def test_circling_inside_the_notch_of_a_u_round_its_centroid_is_no_lap():
    world = World.load('wall_follow_u_shape')
    angles = np.linspace(0.0, 4.0 * math.pi, 1200)
    x = U_CENTROID[0] + 0.45 * np.cos(angles)
    y = U_CENTROID[1] + 0.45 * np.sin(angles)
    assert np.all(signed_distance(np.column_stack((x, y)),
                                  world.obstacle('u_shape').footprints) > 0.3)
    assert metrics_of(make_trace(x, y), world)['laps'] == 0


def test_two_loops_round_the_cross_are_two_laps_each_timed():
    world = World.load('wall_follow_cross')
    x, y, length = polyline(CROSS_LOOP, loops=-2.3)
    metrics = metrics_of(make_trace(x, y), world)
    assert metrics['laps'] == 2
    assert metrics['lap_times_s'] == pytest.approx([length / 0.3] * 2, abs=2 * STEP)


def test_three_quarters_round_the_cross_and_back_is_no_lap():
    world = World.load('wall_follow_cross')
    x, y, _ = polyline(CROSS_LOOP, loops=0.75)
    assert metrics_of(make_trace(*there_and_back(x, y)), world)['laps'] == 0


def test_back_and_forth_along_one_side_of_a_thin_wall_is_no_lap():
    world = World.load('wall_follow_thin_wall')
    x, y, _ = polyline([(-2.0, 0.55), (2.0, 0.55)], loops=5.0)
    metrics = metrics_of(make_trace(x, y), world)
    assert (metrics['laps'], metrics['lap_times_s']) == (0, [])


def test_a_loop_beside_a_post_not_round_it_is_no_lap():
    world = World.load('wall_follow_post')
    # Six loops of 0.5 m radius 1.2 m from its centre: the robot turns round six times.
    angles = np.linspace(0.0, 12.0 * math.pi, 3600)
    x, y = 1.2 + 0.5 * np.cos(angles), 0.5 * np.sin(angles)
    assert metrics_of(make_trace(x, y), world)['laps'] == 0


def test_laps_of_several_inside_points_are_the_fewest_and_end_with_the_last_point():
    # Once round (2, 0) alone (r 0.5, 10.47 s), out to (4, 0) (5 s), then once round both
    # points (r 4, 83.78 s): the first point is wound twice, the second once.
    small = np.linspace(0.0, 2.0 * math.pi, 1048)
    out = np.linspace(2.5, 4.0, 501)[1:]
    big = np.linspace(0.0, 2.0 * math.pi, 8378)[1:]
    x = np.concatenate((2.0 + 0.5 * np.cos(small), out, 4.0 * np.cos(big)))
    y = np.concatenate((0.5 * np.sin(small), np.zeros(len(out)), 4.0 * np.sin(big)))
    time = STEP * np.arange(len(x))
    laps, lap_times = laps_around(time, x, y, [(2.0, 0.0), (-2.0, 0.0)])
    assert laps == 1
    assert lap_times == pytest.approx([time[-1]], abs=2 * STEP)
    assert laps_around(time, x, y, [(2.0, 0.0)])[0] == 2


def test_inside_points_wound_in_opposite_directions_are_no_lap():
    # A figure of eight: counter-clockwise round (-1, 0), then clockwise round (1, 0).
    angles = np.linspace(0.0, 2.0 * math.pi, 600)
    x = np.concatenate((-1.0 + np.cos(angles), 1.0 - np.cos(angles)))
    y = np.concatenate((np.sin(angles), np.sin(angles)))
    time = STEP * np.arange(len(x))
    assert laps_around(time, x, y, [(-1.0, 0.0)])[0] == 1
    assert laps_around(time, x, y, [(1.0, 0.0)])[0] == -1
    assert laps_around(time, x, y, [(-1.0, 0.0), (1.0, 0.0)]) == (0, [])


def test_without_target_laps_are_zero_and_wall_distances_null():
    world = make_world([PILLAR], None, PILLAR_WORLD.bounds)
    metrics = metrics_of(make_trace(*circle_path(1.5)), world, setpoint=0.5)
    assert metrics['laps'] == 0
    assert metrics['lap_times_s'] == []
    assert metrics['wall_distance_m'] == {'mean': None, 'mae': None, 'rms': None,
                                          'setpoint': None}


def test_wall_distance_is_measured_from_the_robot_centre_to_the_target_surface():
    # Alternating 0.4 m and 0.6 m from the pillar's surface (radius 1).
    x, y = circle_path(1.0)
    radius = np.where(np.arange(len(x)) % 2 == 0, 1.4, 1.6)
    x, y = 1.0 + (x - 1.0) / 1.5 * radius, 2.0 + (y - 2.0) / 1.5 * radius
    stats = metrics_of(make_trace(x, y), setpoint=0.45)['wall_distance_m']
    errors = np.where(np.arange(len(x)) % 2 == 0, -0.05, 0.15)
    assert stats['mean'] == pytest.approx(0.5, abs=1e-3)
    assert stats['mae'] == pytest.approx(np.abs(errors).mean(), abs=1e-9)
    assert stats['rms'] == pytest.approx(math.sqrt(np.square(errors).mean()), abs=1e-9)
    assert stats['setpoint'] == 0.45


def test_wall_distance_errors_are_null_without_setpoint():
    stats = metrics_of(make_trace(*circle_path(1.0)))['wall_distance_m']
    assert stats['mean'] == pytest.approx(0.5)
    assert stats['mae'] is None and stats['rms'] is None and stats['setpoint'] is None


def test_stop_and_turn_manoeuvres_are_measured_in_degrees():
    trace = drive([(0.5, 0.0, 2.0), (0.0, 1.0, math.radians(120)), (0.5, 0.0, 2.0),
                   (0.0, -1.5, math.radians(200) / 1.5), (0.5, 0.0, 1.0)])
    assert metrics_of(trace)['turns_deg'] == pytest.approx([120.0, 200.0], abs=1.0)


def test_turning_while_driving_is_not_a_stop_and_turn():
    trace = drive([(0.3, 0.5, 6.0), (0.3, -0.5, 6.0)])
    assert metrics_of(trace)['turns_deg'] == []


def test_a_turn_includes_the_rotation_made_while_still_braking_and_short_pauses():
    trace = drive([(0.5, 0.0, 1.0), (0.2, 1.0, 0.3), (0.0, 1.0, 1.0), (0.0, 0.0, 0.1),
                   (0.0, 1.0, 0.5), (0.5, 0.0, 1.0)])
    turns = stop_and_turn_angles(trace.array('time'), trace.array('linear'),
                                 trace.array('angular'), trace.array('yaw'))
    assert turns == pytest.approx([math.degrees(1.8)], abs=1.0)


@pytest.mark.parametrize('tail, turns', [
    ([(0.0, 1.0, math.radians(22))], [120.0]),          # cut off by the end of the run
    ([(0.0, 1.0, 0.4), (0.0, 0.0, 0.2)], [120.0]),      # paused within the gap at the end
    ([(0.0, 1.0, 0.4), (0.0, 0.0, 0.5)], [120.0, math.degrees(0.4)]),  # paused longer: over
])
def test_a_turn_still_open_when_the_run_ends_is_not_scored(tail, turns):
    finished = [(0.5, 0.0, 1.0), (0.0, 1.0, math.radians(120)), (0.5, 0.0, 1.0)]
    assert metrics_of(drive(finished + tail))['turns_deg'] == pytest.approx(turns, abs=1.0)


def test_longest_stationary_period_counts_turning_in_place_as_standing_still():
    trace = drive([(0.0, 0.0, 3.0), (0.5, 0.0, 2.0), (0.0, 0.8, 7.0), (0.5, 0.0, 1.0)])
    # Driving at 0.5 m/s stays within the 0.05 m radius for up to 0.1 s before and after.
    assert 7.0 <= metrics_of(trace)['max_stationary_s'] <= 7.2


def test_jitter_smaller_than_the_radius_is_stationary():
    rng = np.random.default_rng(0)
    count = 1000
    x, y = rng.uniform(-0.02, 0.02, count), rng.uniform(-0.02, 0.02, count)
    assert longest_stationary(STEP * np.arange(count), x, y) == pytest.approx(STEP * (count - 1))


def longest_stationary_by_definition(time, x, y, radius=0.05):
    longest, start = 0.0, 0
    while start < len(time) - 1:
        leave = start + 1
        while leave < len(time) and math.hypot(x[leave] - x[start], y[leave] - y[start]) <= radius:
            leave += 1
        longest, start = max(longest, time[leave - 1] - time[start]), leave
    return longest


@pytest.mark.parametrize('step', [0.005, 0.0025, 0.01, 0.003])
def test_stationary_periods_are_exact_when_steps_add_up_to_the_radius(step):
    # Samples exactly the radius apart along a straight path: the boundary must not blur.
    count = 400
    rng = np.random.default_rng(1)
    moving = np.where(rng.random(count) < 0.8, step, 0.0)
    x = np.cumsum(moving)
    y = np.zeros(count)
    time = STEP * np.arange(count)
    assert longest_stationary(time, x, y) == longest_stationary_by_definition(time, x, y)


def test_a_robot_always_moving_is_never_stationary_long():
    trace = drive([(0.3, 0.2, 30.0)])
    assert metrics_of(trace)['max_stationary_s'] < 0.2


def test_coverage_is_the_share_of_free_cells_visited():
    # 8 x 4 cells of 0.5 m; the box makes 4 cells not free; the path visits the bottom row.
    box = {'name': 'box', 'type': 'cube', 'size': [1.0, 1.0, 1.0], 'pose': [3.0, 1.5]}
    world = make_world([box], None, (0.0, 0.0, 4.0, 2.0), robot_pose=(0.5, 0.5, 0.0))
    x = np.linspace(0.01, 3.99, 400)
    trace = make_trace(x, np.full_like(x, 0.25), robot_radius=0.2)
    assert metrics_of(trace, world)['coverage'] == pytest.approx(8 / 28)


def test_cells_too_close_to_an_obstacle_for_the_robot_are_not_free():
    wall = [Footprint('box', 1.0, 0.5, half_x=1.0, half_y=0.05)]
    centres_row = np.array([0.25, 0.75, 1.25, 1.75])
    low = coverage(centres_row, np.full(4, 0.25), (0.0, 0.0, 2.0, 1.0), wall, 0.1)
    blocked = coverage(centres_row, np.full(4, 0.25), (0.0, 0.0, 2.0, 1.0), wall, 0.25)
    assert low == pytest.approx(0.5)
    assert blocked is None


def peak_allocated(function, *args):
    """Return what ``function(*args)`` returns and the most memory (bytes) it held at once."""
    tracemalloc.start()  # numpy reports its arrays to tracemalloc
    try:
        return function(*args), tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize('bounds', [
    (-1.0e300, -1.0e300, 1.0e300, 1.0e300),  # accepted before worlds had limits
    (-5000.0, -4000.0, 5000.0, 4000.0),      # a world written in millimetres
    (-1000.0, -1000.0, 1000.0, 1000.0),      # the largest a world file may give now
])
def test_the_coverage_grid_of_huge_bounds_is_coarser_not_bigger(bounds):
    wall = [Footprint('box', 100.0, 0.0, half_x=0.05, half_y=50.0)]
    x = np.linspace(-10.0, 10.0, 2001)
    value, peak = peak_allocated(coverage, x, np.zeros_like(x), bounds, wall, 0.2)
    assert value is not None and 0.0 < value < 0.01
    assert peak < 200 * 2 ** 20  # a 1000 x 1000 grid of centres, distances and flags


def test_the_offset_path_of_a_huge_target_is_traced_on_a_coarser_grid():
    target = (Footprint('box', 0.0, 0.0, half_x=500.0, half_y=1.0),)
    length, peak = peak_allocated(offset_path_length, target, 0.5)
    assert length == pytest.approx(2 * 1000.0 + 2 * 2.0 + math.pi, rel=1e-3)
    assert peak < 500 * 2 ** 20  # 2000 x 2000 points


def test_collisions_clearance_distance_and_speed_up():
    trace = make_trace(np.linspace(0.0, 3.0, 301), np.zeros(301),
                       clearance=np.linspace(1.0, 0.0, 301) + 0.1)
    trace.collisions.append(CollisionEvent(1.0, 1.0, 0.0, 'pillar'))
    trace.collisions.append(CollisionEvent(2.5, 2.5, 0.0, 'pillar'))
    metrics = metrics_of(trace, wall_time_s=0.01)
    assert metrics['collisions'] == 2
    assert metrics['collision_events'][1] == {'time': 2.5, 'x': 2.5, 'y': 0.0,
                                              'obstacle': 'pillar'}
    assert metrics['min_clearance_m'] == pytest.approx(0.1)
    assert metrics['distance_m'] == pytest.approx(3.0)
    assert metrics['sim_time_s'] == pytest.approx(3.01)
    assert metrics['real_time_factor'] == pytest.approx(301.0)


def test_metrics_are_plain_json_even_for_an_empty_run():
    metrics = metrics_of(Trace(robot_radius=0.2), wall_time_s=0.0,
                         node_errors=[{'node': 'wall_follow', 'error': 'ValueError: boom'}])
    text = json.dumps(metrics, allow_nan=False)
    assert json.loads(text) == metrics
    assert metrics['node_errors'] == [{'node': 'wall_follow', 'error': 'ValueError: boom'}]
    assert metrics['real_time_factor'] is None and metrics['min_clearance_m'] is None


def test_metrics_of_a_real_trace_hold_only_builtin_types():
    metrics = metrics_of(drive([(0.5, 0.0, 2.0), (0.0, 1.0, 2.0)]), setpoint=0.5)
    assert json.loads(json.dumps(metrics, allow_nan=False)) == metrics


def test_metrics_have_the_keys_and_kinds_criteria_are_checked_against():
    trace = drive([(0.5, 0.0, 2.0), (0.0, 1.0, 2.0)])
    ranges = np.full(36, 2.0, dtype=np.float32)
    trace.scans.append(ScanSnapshot(0.1, (0.0, 0.0, 0.0), ranges, -1.57, 3.14 / 35, 0.12, 10.0))
    said = ['Range ahead: 2.00 m',
            'right: 2 | front-right: 2 | front: 2 | front-left: 2 | left: 2',
            'Closest obstacle: 2.00 m at -90.0 deg']
    lines = [{'t': 0.1, 'node': 'reader', 'level': 'INFO', 'text': text, 'line': text}
             for text in said]
    metrics = metrics_of(trace, setpoint=0.5, log_lines=lines, printed=PRINTED_KINDS)
    kinds = {'number': (int, float), 'list': list, 'text': str}

    def check(values, schema):
        assert values.keys() == schema.keys()
        for key, kind in schema.items():
            if isinstance(kind, dict):
                check(values[key], kind)
            else:
                assert isinstance(values[key], kinds[kind]), key
    check(metrics, METRIC_KINDS)


@pytest.mark.parametrize('footprints, distance, expected', [
    ((Footprint('circle', 0.0, 0.0, radius=1.0),), 0.5, 2 * math.pi * 1.5),
    ((Footprint('box', 1.0, -1.0, yaw=0.4, half_x=1.0, half_y=0.5),), 0.5, 6.0 + math.pi),
    # An L: its outline is as long as its bounding box's (7 m); the offset loop adds an arc at
    # each of the five convex corners and cuts 2 d at the concave one.
    ((Footprint('box', 0.0, 0.0, half_x=1.0, half_y=0.25),
      Footprint('box', -0.75, 0.5, half_x=0.25, half_y=0.75)), 0.3,
     7.0 + 0.3 * 2.5 * math.pi - 2 * 0.3),
])
def test_offset_path_length_matches_the_analytic_perimeter(footprints, distance, expected):
    assert offset_path_length(footprints, distance) == pytest.approx(expected, rel=2e-3)


def test_node_errors_keep_their_traceback_and_nothing_else():
    metrics = metrics_of(Trace(robot_radius=0.2), wall_time_s=1.0, node_errors=[
        {'node': 'wander', 'error': 'boom', 'traceback': 'Traceback ...', 'frame': object()},
        {'node': 'other', 'error': 'bang'}])
    assert metrics['node_errors'] == [
        {'node': 'wander', 'error': 'boom', 'traceback': 'Traceback ...'},
        {'node': 'other', 'error': 'bang'}]


def table_world(top_height: float) -> World:
    """Return a world whose target is a 1.2 x 1.0 m table at the origin, top at top_height."""
    world = make_world([{'name': 'table', 'type': 'cube', 'size': [0.1, 0.1, 0.1],
                         'pose': [3.0, 3.0]}], 'table', (-1.0, -1.0, 1.0, 1.0), (-3.0, 0.0, 0.0))
    legs = tuple(Shape('box', sx * 0.55, sy * 0.45, 0.5 * top_height,
                       size=(0.05, 0.05, top_height)) for sx in (-1, 1) for sy in (-1, 1))
    top = Shape('box', 0.0, 0.0, top_height + 0.02, size=(1.2, 1.0, 0.04))
    return replace(world, obstacles=(Obstacle('table', 'model', legs + (top,), (0.0, 0.0, 0.0)),))


def test_metrics_read_what_the_robot_could_hit_its_bands_slice():
    # The lab robot (0.15 m tall) drives under a table whose top is at 0.7 m, round the
    # inside of its legs, then 2.25 times round the outside: the legs are what it can hit.
    high = table_world(0.7)
    inside_x, inside_y = circle_path(1, radius=0.25 * math.sqrt(2.0), centre=(0.0, 0.0),
                                     start_angle=0.25 * math.pi)
    outside_x, outside_y = circle_path(2.25, radius=1.0, centre=(0.0, 0.0))
    trace = make_trace(np.concatenate((inside_x, outside_x)),
                       np.concatenate((inside_y, outside_y)), robot_radius=0.15)
    metrics = metrics_of(trace, high, setpoint=0.3)
    assert metrics['laps'] == 2
    # Free are the 16 cells of the 2 x 2 m bounds (no centre within 0.15 m of a leg); the
    # inner circle visits the 4 under the top, the outer 12 others.
    assert metrics['coverage'] == 1.0
    assert coverage(inside_x, inside_y, high.bounds, high.footprints(), 0.15) == 0.25
    # The wall distance is to the legs' outline: the nearest leg is 0.3 m from the inner
    # circle's first point, (0.25, 0.25).
    assert signed_distance(np.array([[0.25, 0.25]]), high.obstacle_footprints('table'))[0] == \
        pytest.approx(math.hypot(0.275, 0.175))
    # A top at 0.1 m is in the band: the table's whole outline, under which no cell is free.
    low = table_world(0.1)
    assert coverage(inside_x, inside_y, low.bounds, low.footprints(), 0.15) == 0.0
