"""Tests of simulation.simulator: shipped worlds as pybullet sees them, driving, collisions."""

from dataclasses import replace
import math

import numpy as np
import pybullet
import pytest

from sim_bridge.common import paths
from sim_bridge.simulation.geometry import Shape
from sim_bridge.simulation.lidar import cast_rays
from sim_bridge.simulation.robot import DriveLimits
from sim_bridge.simulation.simulator import Collision, Simulator
from sim_bridge.simulation.world import World

INSTANT = DriveLimits(max_linear_accel=math.inf, max_angular_accel=math.inf)
ROBOT_RADIUS = 0.15
WALL_FOLLOW_WORLDS = [name for name in paths.world_names() if name.startswith('wall_follow_')]


def ray_entry(start: np.ndarray, direction: np.ndarray, shape: Shape) -> float:
    """Return the distance along the unit ``direction`` to where the ray enters ``shape``."""
    centre = np.array([shape.x, shape.y, shape.z])
    if shape.kind == 'sphere':
        offset = start - centre
        b = offset @ direction
        c = offset @ offset - shape.radius ** 2
        if b * b - c < 0:
            return math.inf
        t = -b - math.sqrt(b * b - c)
        return t if t >= 0 else math.inf
    cos_yaw, sin_yaw = math.cos(shape.yaw), math.sin(shape.yaw)
    to_local = np.array([[cos_yaw, sin_yaw, 0.0], [-sin_yaw, cos_yaw, 0.0], [0.0, 0.0, 1.0]])
    point, heading = to_local @ (start - centre), to_local @ direction
    if shape.kind == 'box':
        near, far = 0.0, math.inf
        for axis, half in enumerate(np.array(shape.size) / 2):
            if abs(heading[axis]) < 1e-12:
                if abs(point[axis]) > half:
                    return math.inf
                continue
            t1, t2 = sorted(((-half - point[axis]) / heading[axis],
                             (half - point[axis]) / heading[axis]))
            near, far = max(near, t1), min(far, t2)
        return near if near <= far else math.inf
    half = shape.length / 2
    hits = []
    a = heading[0] ** 2 + heading[1] ** 2
    if a > 1e-12:
        b = point[:2] @ heading[:2]
        c = point[:2] @ point[:2] - shape.radius ** 2
        if b * b - a * c >= 0:
            t = (-b - math.sqrt(b * b - a * c)) / a
            if t >= 0 and abs(point[2] + t * heading[2]) <= half:
                hits.append(t)
    if abs(heading[2]) > 1e-12:
        for cap in (-half, half):
            t = (cap - point[2]) / heading[2]
            if t >= 0 and np.hypot(*(point[:2] + t * heading[:2])) <= shape.radius:
                hits.append(t)
    return min(hits, default=math.inf)


def inside(point: np.ndarray, shape: Shape) -> bool:
    if shape.kind == 'sphere':
        return math.dist(point, (shape.x, shape.y, shape.z)) < shape.radius
    low, high = shape.z_range()
    return low < point[2] < high and shape.footprint().distance(point[0], point[1]) < 0


def probe_rays(world: World):
    """
    Yield (obstacle name, start, unit direction) of rays aimed at every declared shape.

    Horizontal rays from twelve directions at the shape's mid-height, through its centre and
    off-centre by a fraction of its half-width (odd fractions, so that no ray runs exactly
    along a face of a neighbouring shape), and one ray down onto its top.
    """
    shapes = world.shapes()
    for obstacle in world.obstacles:
        for shape in obstacle.shapes:
            centre = np.array([shape.x, shape.y, shape.z])
            footprint = shape.footprint()
            reach = footprint.radius or math.hypot(footprint.half_x, footprint.half_y)
            width = footprint.radius or min(footprint.half_x, footprint.half_y)
            for angle in np.linspace(0.0, 2 * math.pi, 12, endpoint=False):
                direction = np.array([math.cos(angle), math.sin(angle), 0.0])
                side = np.array([-direction[1], direction[0], 0.0])
                for lateral in (-0.37 * width, 0.0, 0.43 * width):
                    start = centre - (reach + 1.0) * direction + lateral * side
                    if not any(inside(start, other) for other in shapes):
                        yield obstacle.name, start, direction
            top = shape.z_range()[1]
            yield obstacle.name, centre + [0.0, 0.0, top + 1.0 - shape.z], np.array([0, 0, -1.0])


@pytest.mark.parametrize('name', ['obstacles', 'room', *WALL_FOLLOW_WORLDS])
def test_rays_find_every_declared_obstacle_where_the_world_file_puts_it(name):
    world = World.load(name)
    rays = list(probe_rays(world))
    starts = np.array([start for _, start, _ in rays])
    directions = np.array([direction for _, _, direction in rays])
    with Simulator(world, lidar_noise_stddev=0.0) as simulator:
        measured = cast_rays(simulator.physics_client, starts, starts + 20.0 * directions)
    shapes = world.shapes()
    owners = [obstacle.name for obstacle in world.obstacles for _ in obstacle.shapes]
    found = {obstacle.name: 0 for obstacle in world.obstacles}
    for (aimed_at, start, direction), distance in zip(rays, measured):
        entries = [ray_entry(start, direction, shape) for shape in shapes]
        floor = -start[2] / direction[2] if direction[2] < 0 else math.inf
        expected = min(min(entries), floor)
        assert distance == pytest.approx(expected, abs=1e-3), (aimed_at, start, direction)
        if expected == min(entries) and owners[int(np.argmin(entries))] == aimed_at:
            found[aimed_at] += 1
    assert all(count >= 10 for count in found.values()), found


@pytest.mark.parametrize('name', WALL_FOLLOW_WORLDS)
def test_wall_follow_start_reads_half_a_metre_on_the_right_and_mirrored_on_the_left(name):
    world = World.load(name)
    with Simulator(world, lidar_noise_stddev=0.0) as simulator:
        ranges = simulator.scan().ranges
        assert simulator.clearance() == pytest.approx(0.5 - ROBOT_RADIUS)
    assert ranges[0] == pytest.approx(0.5, abs=1e-3)
    assert ranges[-1] > 1.0
    with Simulator(world.mirrored_start(), lidar_noise_stddev=0.0) as simulator:
        ranges = simulator.scan().ranges
    assert ranges[-1] == pytest.approx(0.5, abs=1e-3)
    assert ranges[0] > 1.0


def test_scan_is_laserscan_shaped_from_the_robot_models_lidar():
    with Simulator('obstacles', lidar_noise_stddev=0.0) as simulator:
        simulator.step(0.25)
        scan = simulator.scan()
        config = simulator.lidar_config
    assert len(scan.ranges) == config.samples == 36
    assert (scan.angle_min, scan.angle_max) == (-1.57, 1.57)
    assert scan.angle_increment == pytest.approx(3.14 / 35)
    assert (scan.range_min, scan.range_max, scan.scan_time) == (0.12, 10.0, 0.1)
    assert (scan.stamp, scan.frame_id) == (0.25, 'laser')
    # The cube's front face is 2 m ahead; the two middle beams are 0.045 rad off the axis.
    assert scan.ranges[17] == pytest.approx(2.0 / math.cos(3.14 / 70), abs=1e-3)


def open_floor(**robot) -> World:
    return World.from_dict({'robot': robot or {'pose': [0.0, 0.0, 0.0]}})


def test_straight_line_and_arc_match_the_analytic_motion():
    with Simulator(open_floor(), limits=INSTANT) as simulator:
        simulator.set_command(0.5, 0.0)
        for _ in range(200):
            simulator.step(0.01)
        assert simulator.pose == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)
        simulator.set_command(0.5, 0.5)
        steps = round(math.pi / 0.01)
        for _ in range(steps):
            simulator.step(0.01)
        turned = 0.5 * steps * 0.01
        assert simulator.pose == pytest.approx((1.0 + math.sin(turned), 1.0 - math.cos(turned),
                                                turned), abs=1e-9)
        assert simulator.velocity == (0.5, 0.5)
        assert simulator.time == pytest.approx(2.0 + steps * 0.01)


def test_default_limits_ramp_up_before_cruising():
    with Simulator(open_floor()) as simulator:
        simulator.set_command(0.5, 0.0)
        for _ in range(100):
            simulator.step(0.01)
        limits = simulator.limits
        ramp = 0.5 / limits.max_linear_accel
        assert simulator.pose[0] == pytest.approx(0.5 * (1.0 - ramp) + 0.25 * ramp)


def wall_world(thickness: float = 0.1) -> World:
    """Return a world with a wall whose near face is at x = 1.95 m, the robot at the origin."""
    return World.from_dict({'walls': [{'start': [1.95 + thickness / 2, -2],
                                       'end': [1.95 + thickness / 2, 2],
                                       'thickness': thickness}]})


def drive(simulator: Simulator, linear: float, angular: float, seconds: float) -> None:
    simulator.set_command(linear, angular)
    for _ in range(round(seconds / 0.01)):
        simulator.step(0.01)


def test_driving_into_a_wall_stops_at_contact_and_counts_one_collision():
    with Simulator(wall_world()) as simulator:
        drive(simulator, 0.5, 0.0, 4.0)
        stop = 1.95 - ROBOT_RADIUS
        assert simulator.pose[0] == pytest.approx(stop, abs=1e-6)
        assert simulator.pose[0] <= stop
        assert 0.0 <= simulator.clearance() <= 1e-6
        (collision,) = simulator.collisions
        # 0.2 s ramp covering 0.05 m, then 1.75 m at 0.5 m/s.
        assert collision == Collision(pytest.approx(3.7, abs=1e-6),
                                      pytest.approx(stop, abs=1e-6), 0.0, 'wall_0')
        assert simulator.velocity == (0.0, 0.0)
        drive(simulator, 0.5, 0.0, 5.0)
        assert len(simulator.collisions) == 1
        assert simulator.pose[0] == pytest.approx(stop, abs=1e-6)


def test_the_trajectory_gets_the_ground_truth_after_each_step_once_asked_for():
    with Simulator(wall_world()) as simulator:
        simulator.step(0.01)
        simulator.trajectory = []
        samples = []
        simulator.set_command(0.5, 0.3)
        for _ in range(3):
            simulator.step(0.01)
            samples.append((simulator.time, *simulator.pose, *simulator.velocity,
                            simulator.clearance()))
        assert simulator.trajectory == samples
        assert samples[0][0] == pytest.approx(0.02) and samples[-1][4] > 0.0


def test_a_continuous_contact_is_one_collision_a_new_touch_is_another():
    with Simulator(wall_world(), limits=INSTANT) as simulator:
        drive(simulator, 0.5, 0.0, 4.0)
        drive(simulator, 0.0, 1.0, 1.0)  # turning on the spot while touching
        assert simulator.pose[2] == pytest.approx(1.0)
        drive(simulator, 0.0, -1.0, 1.0)
        drive(simulator, -0.1, 0.0, 0.05)  # backs off 5 mm, less than the release distance
        drive(simulator, 0.1, 0.0, 0.2)
        assert len(simulator.collisions) == 1
        drive(simulator, -0.5, 0.0, 0.5)  # backs off 25 cm
        assert not simulator.in_contact
        drive(simulator, 0.5, 0.0, 1.0)
        assert [collision.obstacle for collision in simulator.collisions] == ['wall_0'] * 2
        assert simulator.collisions[1].time > simulator.collisions[0].time


def test_a_shallow_approach_stops_at_contact_without_penetrating():
    world = World.from_dict({'robot': {'pose': [0.0, 0.0, 0.05]},
                             'walls': [{'start': [-20, 1.05], 'end': [20, 1.05],
                                        'thickness': 0.1}]})
    with Simulator(world, limits=INSTANT) as simulator:
        drive(simulator, 0.5, 0.0, 40.0)
        assert 0.0 <= simulator.clearance() <= 1e-6
        assert simulator.pose[1] == pytest.approx(1.0 - ROBOT_RADIUS, abs=1e-6)
        assert len(simulator.collisions) == 1


def test_a_fast_robot_cannot_jump_through_a_thin_wall():
    with Simulator(wall_world(thickness=0.01), limits=INSTANT) as simulator:
        simulator.set_command(1.0, 0.0)
        for _ in range(4):
            simulator.step(0.9)
        assert simulator.pose[0] == pytest.approx(1.95 - ROBOT_RADIUS, abs=1e-6)
        assert len(simulator.collisions) == 1


def step_by_step(simulator: Simulator, dt: float, steps: int) -> None:
    """Step one at a time while one arc cannot drive the steps, then the rest in one."""
    for done in range(steps):
        if simulator.in_one_arc():
            simulator.step(dt * (steps - done))
            return
        simulator.step(dt)


def test_substeps_drive_as_the_steps_one_by_one_to_the_last_bit():
    # Speeding up while turning (no single arc), then holding the command: clear of the wall,
    # then into it, where the substeps are checked one by one.
    world = wall_world().with_robot_start(1.55, 0.0, 0.0)
    with Simulator(world) as one_by_one, Simulator(world) as at_once:
        at_once.trajectory = []
        for command in [(0.5, 0.8), (0.3, -1.2), (0.5, 0.0), (0.4, 0.6)] * 6:
            one_by_one.set_command(*command)
            at_once.set_command(*command)
            step_by_step(one_by_one, 0.001, 50)
            at_once.step(0.001, 50)
            assert at_once.pose == one_by_one.pose
            assert at_once.velocity == one_by_one.velocity
            assert at_once.time_ns == one_by_one.time_ns
        assert at_once.collisions == one_by_one.collisions != []
        assert at_once.trajectory[-1] == (at_once.time, *one_by_one.pose,
                                          *one_by_one.velocity, one_by_one.clearance())
        with pytest.raises(ValueError, match='substeps'):
            at_once.step(0.001, 0)


def run_wanderer(seed: int, seconds: float = 60.0):
    """Return the scans and poses of a scan-reacting wanderer in the room."""
    scans, poses = [], []
    with Simulator('room', seed=seed) as simulator:
        for step in range(round(seconds * 100)):
            if step % 10 == 0:
                ranges = simulator.scan().ranges
                scans.append(ranges)
                ahead = ranges[12:24]
                blocked = np.min(ahead[np.isfinite(ahead)], initial=np.inf) < 0.6
                simulator.set_command(0.0 if blocked else 0.4, 1.2 if blocked else 0.0)
            simulator.step(0.01)
            poses.append(simulator.pose)
        collisions = list(simulator.collisions)
    return np.array(scans), np.array(poses), collisions


def test_the_same_seed_makes_a_run_bit_identical_and_another_seed_changes_the_noise():
    scans, poses, collisions = run_wanderer(seed=3)
    again_scans, again_poses, again_collisions = run_wanderer(seed=3)
    assert np.array_equal(scans, again_scans)
    assert np.array_equal(poses, again_poses)
    assert collisions == again_collisions
    assert np.ptp(poses[:, 0]) > 1.0  # it did go places
    other_scans, _, _ = run_wanderer(seed=4, seconds=1.0)
    assert not np.array_equal(scans[:len(other_scans)], other_scans)


def test_simulated_time_is_exact_in_nanoseconds():
    with Simulator(open_floor()) as simulator:
        for _ in range(6000):
            simulator.step(0.01)
        assert simulator.time_ns == 60_000_000_000
        assert simulator.time == 60.0


@pytest.mark.parametrize('linear, angular', [(math.nan, 0.0), (0.0, math.inf),
                                             (-math.inf, 1.0)])
def test_commands_that_are_not_finite_are_rejected_and_the_robot_stops(linear, angular):
    with Simulator(open_floor()) as simulator:
        drive(simulator, 0.5, 0.5, 1.0)
        warning = simulator.set_command(linear, angular)
        assert 'rejected' in warning and 'stopping' in warning
        assert simulator.command == (0.0, 0.0)
        drive_on = [simulator.step(0.01) for _ in range(100)]
        assert len(drive_on) == 100 and simulator.velocity == (0.0, 0.0)
        assert all(math.isfinite(value) for value in simulator.pose)


def test_huge_commands_are_clamped_to_the_limits():
    with Simulator(open_floor()) as simulator:
        warning = simulator.set_command(1e9, -1e9)
        assert warning.startswith('clamped')
        limits = simulator.limits
        assert simulator.command == (limits.max_linear_speed, -limits.max_angular_speed)
        for _ in range(200):
            simulator.step(0.01)
        assert simulator.velocity == (limits.max_linear_speed, -limits.max_angular_speed)
        assert simulator.set_command(0.2, 0.1) is None


def test_without_a_new_command_for_longer_than_the_timeout_the_robot_stops():
    with Simulator(open_floor(), command_timeout=0.5) as simulator:
        drive(simulator, 0.4, 0.2, 0.5)
        simulator.step(0.01)  # 0.5 s without a new command: not yet longer than the timeout
        assert simulator.command == (0.4, 0.2)
        simulator.step(0.01)
        assert simulator.command == (0.0, 0.0)
        for _ in range(50):
            simulator.step(0.01)
        assert simulator.velocity == (0.0, 0.0)
        drive(simulator, 0.3, 0.0, 0.3)
        assert simulator.velocity == (0.3, 0.0)
    with Simulator(open_floor()) as simulator:
        drive(simulator, 0.4, 0.2, 5.0)
        assert simulator.command == (0.4, 0.2)
    with pytest.raises(ValueError, match='command_timeout'):
        Simulator(open_floor(), command_timeout=0.0)


@pytest.mark.parametrize('dt', [0.0, -0.01, math.nan, math.inf])
def test_step_needs_a_positive_finite_dt(dt):
    with Simulator(open_floor()) as simulator:
        with pytest.raises(ValueError, match='positive finite dt'):
            simulator.step(dt)


def test_two_simulators_coexist_and_closing_one_leaves_the_other():
    first = Simulator('wall_follow_box', lidar_noise_stddev=0.0)
    second = Simulator('obstacles', lidar_noise_stddev=0.0)
    assert first.physics_client != second.physics_client
    first_ranges = first.scan().ranges
    second.close()
    assert np.array_equal(first.scan().ranges, first_ranges)
    with pytest.raises(pybullet.error):
        second.scan()
    first.close()
    first.close()


def test_lidar_overrides_and_a_robot_model_without_lidar(tmp_path, monkeypatch):
    world = World.load('obstacles')
    custom = replace(world.robot.lidar, samples=5, noise_stddev=0.0)
    with Simulator(world, lidar=custom) as simulator:
        assert len(simulator.scan().ranges) == 5
    with Simulator(world, lidar_samples=720, lidar_noise_stddev=0.05) as simulator:
        assert simulator.lidar_config == replace(world.robot.lidar, samples=720,
                                                 noise_stddev=0.05)
        assert len(simulator.scan().ranges) == 720
    model = tmp_path / 'blind_robot'
    model.mkdir()
    (model / 'model.sdf').write_text(
        paths.find_model('lab_robot').joinpath('model.sdf').read_text().split('<sensor name=')[0]
        + '</link></model></sdf>')
    monkeypatch.setenv('GAZEBO_MODEL_PATH', str(tmp_path))
    blind = World.from_dict({'robot': {'model': 'blind_robot'}})
    with pytest.raises(ValueError, match="'blind_robot'.*has no lidar <sensor>"):
        Simulator(blind)
    with Simulator(blind, lidar=custom) as simulator:
        assert simulator.robot_radius == pytest.approx(ROBOT_RADIUS)


def test_the_gui_robot_follows_the_pose_and_the_lidar_looks_through_it(monkeypatch):
    with Simulator('wall_follow_cylinder', lidar_noise_stddev=0.0) as headless:
        expected = headless.scan().ranges
        assert headless.viewer is None
    # No display here: let the GUI code path build its bodies in a DIRECT client.
    monkeypatch.setattr(pybullet, 'GUI', pybullet.DIRECT)
    with Simulator('wall_follow_cylinder', lidar_noise_stddev=0.0, gui=True,
                   draw_rays=True) as simulator:
        assert np.array_equal(simulator.scan().ranges, expected)
        assert len(simulator.viewer.ray_items) == len(expected)
        drive(simulator, 0.3, -0.3 / 1.3, 1.0)
        position, orientation = pybullet.getBasePositionAndOrientation(
            simulator.viewer.robot_body, physicsClientId=simulator.physics_client)
        x, y, yaw = simulator.pose
        assert position == pytest.approx((x, y, 0.0))
        assert pybullet.getEulerFromQuaternion(orientation)[2] == pytest.approx(yaw)


@pytest.mark.parametrize('seed', [-1, 1.5, True, '3'])
def test_a_seed_that_numpy_cannot_take_is_named(seed):
    with pytest.raises(ValueError, match='seed must be a non-negative integer'):
        Simulator('obstacles', seed=seed)
