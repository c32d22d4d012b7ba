"""Tests of simulation.floor_slice: what a robot can hit is the world through its height band."""

from dataclasses import replace
import math

import numpy as np
import pytest
import shapely

from sim_bridge.simulation.floor_slice import FLOOR_CLEARANCE, FloorSlice, height_band
from sim_bridge.simulation.geometry import Mesh, Shape, slice_footprints
from sim_bridge.simulation.robot import DriveLimits
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import Obstacle, World, WorldError
import trimesh

INSTANT = DriveLimits(max_linear_accel=math.inf, max_angular_accel=math.inf)
# A robot 0.2 m tall: one upright cylinder of radius 0.15 m about its origin.
SHORT_ROBOT = (Shape('cylinder', 0.0, 0.0, 0.1, radius=0.15, length=0.2),)
# A TurtleBot3 Waffle's collisions, as its SDF places them: the base box behind the wheel axle,
# two wheels (cylinders rolled onto their side) and a caster ball. 0.306 m wide; the circle
# about its origin holding it has a radius of 0.237 m.
WHEEL = Shape('cylinder', 0.0, 0.144, 0.033, radius=0.033, length=0.018, roll=0.5 * math.pi)
WAFFLE = (Shape('box', -0.064, 0.0, 0.047, size=(0.265, 0.265, 0.089)),
          WHEEL, replace(WHEEL, y=-0.144),
          Shape('sphere', -0.177, 0.0, 0.005, radius=0.005))


def world_of(robot_shapes, obstacles: dict, start=(0.0, 0.0, 0.0)) -> World:
    """Return the lab robot's world with other collision shapes and named obstacles."""
    world = World.from_dict({'name': 'sliced'})
    robot = replace(world.robot, shapes=tuple(robot_shapes))
    world = replace(world, robot=robot, obstacles=tuple(
        Obstacle(name, 'model', tuple(shapes), (shapes[0].x, shapes[0].y, 0.0))
        for name, shapes in obstacles.items()))
    return world.with_robot_start(*start)


def table(x: float, top_height: float) -> list[Shape]:
    """Return a 1.2 x 1.0 m table at (x, 0): four 5 cm legs and a 4 cm top at top_height."""
    legs = [Shape('box', x + sx * 0.55, sy * 0.45, 0.5 * top_height,
                  size=(0.05, 0.05, top_height)) for sx in (-1, 1) for sy in (-1, 1)]
    return legs + [Shape('box', x, 0.0, top_height + 0.02, size=(1.2, 1.0, 0.04))]


def drive(world: World, linear: float, angular: float, seconds: float) -> Simulator:
    simulator = Simulator(world, limits=INSTANT)
    simulator.trajectory = []
    simulator.set_command(linear, angular)
    for _ in range(round(seconds / 0.01)):
        simulator.step(0.01)
    return simulator


def test_the_band_runs_from_just_above_the_floor_to_the_robots_top():
    assert height_band(SHORT_ROBOT) == (FLOOR_CLEARANCE, pytest.approx(0.2))
    assert height_band(WAFFLE) == (FLOOR_CLEARANCE, pytest.approx(0.0915))


def test_rolled_wheels_give_the_waffle_its_rectangular_outline():
    floor = FloorSlice(WAFFLE, [])
    assert not floor.round
    # Wheels 0.018 wide outside the body, the body's back 0.1965 m behind the axle.
    assert floor.robot_polygon.bounds == pytest.approx((-0.1965, -0.153, 0.0685, 0.153),
                                                       abs=1e-4)
    assert floor.robot_radius == pytest.approx(math.hypot(0.1965, 0.1325), abs=1e-4)
    assert floor.robot_polygon.area == pytest.approx(0.265 ** 2 + 2 * 0.066 * 0.018, rel=1e-3)


def test_a_table_above_the_robot_is_its_legs_and_one_it_reaches_is_its_top():
    short = FloorSlice(SHORT_ROBOT, [('table', table(0.0, 0.7))])
    assert len(short.footprints) == 4 and set(short.owners) == {'table'}
    low = FloorSlice(SHORT_ROBOT, [('table', table(0.0, 0.15))])
    assert max(fp.bounds()[2] for fp in low.footprints) == pytest.approx(0.6)
    assert low.obstacles.nearest(0.0, 0.0)[0] < 0.0


def test_a_sphere_in_the_band_is_its_widest_section_in_it():
    ball = Shape('sphere', 0.0, 0.0, 0.5, radius=0.5)
    assert slice_footprints(ball, FLOOR_CLEARANCE, 0.15)[0].radius == pytest.approx(
        math.sqrt(0.5 ** 2 - 0.35 ** 2))
    assert slice_footprints(ball, FLOOR_CLEARANCE, 0.6)[0].radius == 0.5
    assert slice_footprints(replace(ball, z=1.2), FLOOR_CLEARANCE, 0.6) == ()


def test_the_floor_and_a_ground_plane_are_never_obstacles():
    ground = Shape('box', 0.0, 0.0, -0.005, size=(100.0, 100.0, 0.01))
    mat = Shape('box', 0.0, 0.0, 0.002, size=(3.0, 3.0, 0.004))
    assert FloorSlice(SHORT_ROBOT, [('ground', [ground]), ('mat', [mat])]).footprints == ()


def test_the_robot_drives_under_a_high_table_and_is_stopped_by_a_low_one():
    high = drive(world_of(SHORT_ROBOT, {'table': table(1.5, 0.7)}), 0.3, 0.0, 10.0)
    assert high.collisions == [] and high.pose[0] == pytest.approx(3.0)
    low = drive(world_of(SHORT_ROBOT, {'table': table(1.5, 0.15)}), 0.3, 0.0, 10.0)
    assert [event.obstacle for event in low.collisions] == ['table']
    # Stopped with its front on the top's edge at x = 0.9.
    assert low.pose[0] == pytest.approx(0.9 - 0.15, abs=1e-5)


def test_a_mesh_obstacle_collides_where_its_slice_is():
    # A cone standing on its apex: at the robot's top (0.2 m) it is 0.1 m wide in radius,
    # the most of it the robot's band holds.
    cone = trimesh.creation.cone(0.5, 1.0, sections=512)
    cone.apply_transform(trimesh.transformations.rotation_matrix(math.pi, (1.0, 0.0, 0.0)))
    cone.apply_translation((0.0, 0.0, 1.0))
    shape = Shape('mesh', 2.0, 0.0, 0.0, mesh=Mesh(cone.vertices, cone.faces))
    (footprint,) = FloorSlice(SHORT_ROBOT, [('cone', [shape])]).footprints
    assert footprint.bounds() == pytest.approx((1.9, -0.1, 2.1, 0.1), abs=1e-5)
    simulator = drive(world_of(SHORT_ROBOT, {'cone': [shape]}), 0.3, 0.0, 10.0)
    assert [event.obstacle for event in simulator.collisions] == ['cone']
    assert simulator.pose[0] == pytest.approx(2.0 - 0.1 - 0.15, abs=1e-5)


def test_a_waffle_passes_a_gap_its_circumscribed_circle_would_not():
    # Two boxes leave a 0.40 m gap across the robot's way at x = 1.5.
    gap = {'left': [Shape('box', 1.5, 0.45, 0.25, size=(0.5, 0.5, 0.5))],
           'right': [Shape('box', 1.5, -0.45, 0.25, size=(0.5, 0.5, 0.5))]}
    waffle = drive(world_of(WAFFLE, gap), 0.2, 0.0, 15.0)
    assert waffle.collisions == [] and waffle.pose[0] == pytest.approx(3.0)
    assert 0.0 < min(sample[-1] for sample in waffle.trajectory) < 0.05
    circle = (Shape('cylinder', 0.0, 0.0, 0.05, radius=waffle.robot_radius, length=0.09),)
    blocked = drive(world_of(circle, gap), 0.2, 0.0, 15.0)
    assert [event.obstacle for event in blocked.collisions] == ['left']
    assert blocked.pose[0] < 1.25


def test_clearance_is_measured_from_the_robots_outline():
    wall = {'wall': [Shape('box', 0.0, 0.5, 0.25, size=(4.0, 0.2, 0.5))]}
    simulator = Simulator(world_of(WAFFLE, wall), limits=INSTANT)
    # The wheels' outer faces are at y = 0.153, the wall's face at 0.4.
    assert simulator.clearance() == pytest.approx(0.4 - 0.153, abs=1e-4)


def test_a_polygon_robots_gap_is_its_least_distance_to_every_footprint():
    # A ring wall of 256 sides around the world, posts and a box: the gap along a path
    # through them is what shapely measures to each whole footprint.
    wall = trimesh.creation.annulus(2.8, 3.0, 0.5, sections=256)
    obstacles = [('wall', [Shape('mesh', z=0.25, mesh=Mesh(wall.vertices, wall.faces))]),
                 ('box', [Shape('box', 1.0, 0.6, 0.25, yaw=0.3, size=(0.4, 0.2, 0.5))])]
    obstacles += [(f'post{i}', [Shape('cylinder', -1.0 + 0.5 * i, -0.8, 0.25, radius=0.1,
                                      length=0.5)]) for i in range(5)]
    floor = FloorSlice(WAFFLE, obstacles)
    pieces = [shapely.Point(fp.x, fp.y) if fp.kind == 'circle' else fp.geometry()
              for fp in floor.footprints]
    radii = [fp.radius if fp.kind == 'circle' else 0.0 for fp in floor.footprints]
    for t in np.linspace(0.0, 2.0 * math.pi, 400):
        pose = (2.2 * math.cos(t), 1.9 * math.sin(2.0 * t), 3.0 * t)
        gaps = shapely.distance(floor.robot_at(pose), pieces) - radii
        gap, index = floor.clearance(pose)
        assert gap == pytest.approx(gaps.min(), abs=1e-12)
        assert gaps[index] == pytest.approx(gaps.min(), abs=1e-12)


def test_a_long_robot_turning_in_place_is_stopped_by_its_corner():
    # A 0.6 x 0.1 m plank robot, a wall face 0.15 m to its left: its front-left corner
    # (0.3, 0.05) meets the wall after turning by the angle solved below.
    plank = (Shape('box', 0.0, 0.0, 0.05, size=(0.6, 0.1, 0.1)),)
    wall = {'wall': [Shape('box', 0.0, 0.25, 0.25, size=(4.0, 0.2, 0.5))]}
    simulator = drive(world_of(plank, wall), 0.0, 0.5, 2.0)
    reach = math.hypot(0.3, 0.05)
    touch = math.asin(0.15 / reach) - math.atan2(0.05, 0.3)
    assert [event.obstacle for event in simulator.collisions] == ['wall']
    assert simulator.pose[2] == pytest.approx(touch, abs=1e-5)
    assert 0.0 < simulator.clearance() <= 1e-5


def test_a_robot_start_overlapping_by_its_outline_is_rejected_but_not_by_its_circle():
    wall = {'wall': [Shape('box', 0.0, 0.28, 0.25, size=(4.0, 0.2, 0.5))]}
    # The wall's face is 0.18 m to the left; the waffle's side is 0.153 m from its origin,
    # its back 0.1965 m.
    assert world_of(WAFFLE, wall, start=(0.0, 0.0, 0.0)).robot_start == (0.0, 0.0, 0.0)
    with pytest.raises(WorldError, match="overlaps obstacle 'wall'"):
        world_of(WAFFLE, wall, start=(0.0, 0.0, -0.5 * math.pi))


def test_the_robots_outline_turns_and_moves_with_its_pose():
    floor = FloorSlice(WAFFLE, [])
    # The body and each wheel (2.5 mm apart, as in the Waffle's SDF) are three rings.
    rings = floor.robot_outlines((1.0, 2.0, 0.5 * math.pi))
    assert len(rings) == 3 and all(np.allclose(ring[0], ring[-1]) for ring in rings)
    assert shapely.MultiPoint(np.vstack(rings)).bounds == pytest.approx(
        (1.0 - 0.153, 2.0 - 0.1965, 1.0 + 0.153, 2.0 + 0.0685), abs=1e-4)


def test_a_robot_flatter_than_the_floor_clearance_is_a_clear_error():
    mat = (Shape('box', 0.0, 0.0, 0.001, size=(0.3, 0.3, 0.002)),)
    with pytest.raises(WorldError, match="robot: 'model': 'lab_robot' .* no collision shape "
                       'higher than 0.005 m'):
        world_of(mat, {})


def test_a_polygon_robots_gap_is_the_same_along_straight_runs_turns_and_returns():
    # Straight runs keep the yaw (and the outline's turned corners); a turn changes it; a
    # return to an earlier yaw or place must not find anything stale. A fresh slice per pose
    # measures each from scratch.
    obstacles = [('box', [Shape('box', 1.0, 0.6, 0.25, yaw=0.3, size=(0.4, 0.2, 0.5))]),
                 ('post', [Shape('cylinder', -0.6, -0.5, 0.25, radius=0.1, length=0.5)])]
    floor = FloorSlice(WAFFLE, obstacles)
    poses = [(0.02 * step, 0.0, 0.0) for step in range(5)]
    poses += [(0.1, 0.0, 0.1 * step) for step in range(5)]
    poses += [(0.1 - 0.03 * step, 0.01 * step, 0.4) for step in range(5)]
    poses += [(0.1, 0.0, 0.0), (0.0, 0.0, 0.4), (0.0, 0.0, 0.0)]
    first = floor.robot_at(poses[0])
    kept = shapely.get_coordinates(first).copy()
    for pose in poses:
        assert floor.clearance(pose) == FloorSlice(WAFFLE, obstacles).clearance(pose), pose
        assert shapely.equals_exact(floor.robot_at(pose),
                                    FloorSlice(WAFFLE, obstacles).robot_at(pose), 0.0), pose
    # An outline handed out before is not moved by the later ones.
    assert np.array_equal(shapely.get_coordinates(first), kept)


# A thin box wall and an open mesh wall (one vertical quad, two triangles), both at an angle.
THIN_WALL = Shape('box', 1.0, 0.2, 0.25, yaw=0.4, size=(0.005, 2.0, 0.5))
SHEET = Shape('mesh', 1.0, 0.2, 0.0, yaw=-0.3, mesh=Mesh(
    np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.5], [0.0, -1.0, 0.5]]),
    np.array([[0, 1, 2], [0, 2, 3]])))


@pytest.mark.parametrize('wall, start, command, stop, contact_time, clearance', [
    (THIN_WALL, (0.0, 0.0, 0.2), (0.25, 0.0),
     ('0x1.ce5424138ae4fp-1', '0x1.76dfe8fd6ad78p-3', '0x1.99999999999a0p-3'),
     3.7354055212790045, '0x1.83383d034a007p-21'),
    (THIN_WALL, (0.0, 0.0, -0.3), (0.2, 0.12),
     ('0x1.00dcf2bb29e0bp+0', '0x1.3d946d93b7083p-7', '0x1.99a1404cacdf0p-2'),
     5.077446540256715, '0x1.9b860b84a092bp-22'),
    (SHEET, (0.0, 0.0, 0.2), (0.25, 0.0),
     ('0x1.b97a0e774937cp-1', '0x1.65f793b5b13ffp-3', '0x1.99999999999a0p-3'),
     3.568, '0x1.00ec827be44b1p-21'),
    (SHEET, (0.0, 0.0, -0.3), (0.2, 0.12),
     ('0x1.9773392e7686fp-1', '-0x1.683fdd341a576p-5', '0x1.7d6f91dcf9cf0p-3'),
     4.064, '0x1.c4704ad36370ep-22')])
def test_a_polygon_robot_stops_at_a_thin_wall_and_a_mesh_sheet_to_the_last_bit(
        wall, start, command, stop, contact_time, clearance):
    # Stepped as the bridge steps 1 ms physics, 16 steps a call, straight and on an arc: the
    # stop, the contact's time and the gap left are pinned to the bit, as the collision code
    # gave them before its speed-ups (a faster check must not move the robot).
    simulator = Simulator(world_of(WAFFLE, {'wall': [wall]}, start=start))
    simulator.set_command(*command)
    for _ in range(400):
        simulator.step(0.001, 16)
    assert simulator.pose == tuple(float.fromhex(value) for value in stop)
    assert [(event.time, event.obstacle) for event in simulator.collisions] == [
        (contact_time, 'wall')]
    assert simulator.clearance() == float.fromhex(clearance)
