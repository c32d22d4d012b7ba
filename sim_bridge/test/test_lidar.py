"""Tests of simulation.lidar: ray casts, beam layout, REP-117 readings, noise and batching."""

from dataclasses import replace
import math

import numpy as np
import pybullet
import pytest

from sim_bridge.simulation import lidar as lidar_module
from sim_bridge.simulation.geometry import Mesh, Shape
from sim_bridge.simulation.lidar import beam_directions, build_scene, cast_rays, Lidar
from sim_bridge.simulation.sdf_lidar import LidarConfig
import trimesh

NOISELESS = LidarConfig(noise_stddev=0.0)
# A 4 m wall across +x at x = 2 (its near face), a post on the left, a ball behind.
SCENE = (Shape('box', 2.05, 0.0, 0.5, size=(0.1, 4.0, 1.0)),
         Shape('cylinder', 0.0, 1.5, 0.5, radius=0.25, length=1.0),
         Shape('sphere', -3.0, 0.0, 0.5, radius=0.5))


@pytest.fixture
def client():
    client = pybullet.connect(pybullet.DIRECT)
    yield client
    pybullet.disconnect(physicsClientId=client)


@pytest.fixture
def scene(client):
    build_scene(client, SCENE)
    return client


def test_cast_rays_measures_distances_to_each_kind_of_shape(scene):
    starts = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.3], [0.0, 0.0, 0.5], [0.0, 0.0, 0.3]])
    ends = np.array([[9.0, 0.0, 0.3], [0.0, 9.0, 0.3], [-9.0, 0.0, 0.5], [0.0, -9.0, 0.3]])
    distances = cast_rays(scene, starts, ends)
    assert distances[:3] == pytest.approx([2.0, 1.25, 2.5], abs=1e-3)
    assert distances[3] == math.inf


def test_rays_pointing_down_hit_the_floor(client):
    build_scene(client, (), floor_size=(4.0, 4.0))
    distances = cast_rays(client, [[0.0, 0.0, 1.0], [5.0, 0.0, 1.0]],
                          [[0.0, 0.0, -1.0], [5.0, 0.0, -1.0]])
    assert distances[0] == pytest.approx(1.0) and distances[1] == math.inf


def inside(point, shape: Shape) -> bool:
    low, high = shape.z_range()
    if shape.kind == 'sphere':
        return math.dist(point, (shape.x, shape.y, shape.z)) < shape.radius
    return low < point[2] < high and shape.footprint().distance(point[0], point[1]) < 0


def rays_at_shapes(shapes, distance: float = 3.0, directions: int = 16):
    """
    Return (starts, ends) of horizontal rays from round each shape towards its centre.

    Rays starting inside a shape are left out: a mesh is hit from inside, a primitive is not.
    """
    angles = np.linspace(0.0, 2 * math.pi, directions, endpoint=False)
    starts, ends = [], []
    for shape in shapes:
        centre = np.array([shape.x, shape.y, shape.z])
        for angle in angles:
            offset = distance * np.array([math.cos(angle), math.sin(angle), 0.0])
            if not any(inside(centre + offset, other) for other in shapes):
                starts.append(centre + offset)
                ends.append(centre - offset)
    return np.array(starts), np.array(ends)


def test_pybullet_primitives_and_meshes_agree_within_a_millimetre(client):
    build_scene(client, SCENE)
    primitives = pybullet.connect(pybullet.DIRECT)
    try:
        build_scene(primitives, SCENE, meshes=False)
        starts, ends = rays_at_shapes(SCENE)
        meshes = cast_rays(client, starts, ends)
        exact = cast_rays(primitives, starts, ends)
    finally:
        pybullet.disconnect(physicsClientId=primitives)
    assert np.all(np.isfinite(exact))
    assert np.max(np.abs(meshes - exact)) < 1e-3


def test_chunked_batches_give_the_same_distances(scene):
    angles = np.linspace(0.0, 2 * math.pi, 50)
    ends = np.column_stack((5 * np.cos(angles), 5 * np.sin(angles), np.full(50, 0.3)))
    starts = np.tile([0.0, 0.0, 0.3], (50, 1))
    assert np.array_equal(cast_rays(scene, starts, ends, batch_size=7),
                          cast_rays(scene, starts, ends))


def test_beams_spread_from_min_to_max_angle_counter_clockwise(scene):
    config = replace(NOISELESS, samples=5, min_angle=-math.pi / 2, max_angle=math.pi / 2)
    scan = Lidar(scene, config, np.random.default_rng(0)).scan((0.0, 0.0, 0.0), stamp=1.5)
    assert scan.angle_increment == pytest.approx(math.pi / 4)
    assert (scan.angle_min, scan.angle_max) == (-math.pi / 2, math.pi / 2)
    # Index 0 looks right (-y: nothing), index 2 ahead (the wall), index 4 left (the post).
    assert scan.ranges[0] == math.inf
    assert scan.ranges[2] == pytest.approx(2.0, abs=1e-6)
    assert scan.ranges[4] == pytest.approx(1.25, abs=1e-3)
    assert (scan.stamp, scan.frame_id, scan.time_increment) == (1.5, 'laser', 0.0)
    assert scan.scan_time == pytest.approx(0.1)
    assert len(scan.intensities) == 5 and not scan.intensities.any()


def test_robot_pose_and_laser_mounting_move_and_turn_the_beams(scene):
    config = replace(NOISELESS, samples=1, min_angle=0.0, max_angle=0.0,
                     pose=(0.5, 0.0, 0.3, 0.0, 0.0, math.pi / 2))
    lidar = Lidar(scene, config, np.random.default_rng(0))
    # The laser sits 0.5 m ahead of the robot's centre and looks to the robot's left. Robot at
    # (0.5, -0.5) facing +y: the laser is at (0.5, 0) looking along -x, at the ball behind
    # (its cross-section at the laser's height has radius sqrt(0.5^2 - 0.2^2)).
    assert lidar.origin((0.5, -0.5, math.pi / 2)) == pytest.approx((0.5, 0.0, 0.3))
    expected = 3.5 - math.sqrt(0.5 ** 2 - 0.2 ** 2)
    assert lidar.scan((0.5, -0.5, math.pi / 2)).ranges[0] == pytest.approx(expected, abs=1e-3)
    # Facing -x instead, the laser is at (0, -0.5) looking along -y: nothing there.
    assert lidar.origin((0.5, -0.5, math.pi)) == pytest.approx((0.0, -0.5, 0.3))
    assert lidar.scan((0.5, -0.5, math.pi)).ranges[0] == math.inf


def test_a_tilted_laser_sees_the_floor(client):
    build_scene(client, (), floor_size=(10.0, 10.0))
    config = replace(NOISELESS, samples=1, min_angle=0.0, max_angle=0.0,
                     pose=(0.0, 0.0, 0.5, 0.0, math.pi / 6, 0.0))
    ranges = Lidar(client, config, np.random.default_rng(0)).scan((0.0, 0.0, 0.0)).ranges
    assert ranges[0] == pytest.approx(1.0)


def test_one_beam_looks_along_min_angle_with_zero_increment(scene):
    config = replace(NOISELESS, samples=1, min_angle=0.0, max_angle=1.0)
    scan = Lidar(scene, config, np.random.default_rng(0)).scan((0.0, 0.0, 0.0))
    assert len(scan.ranges) == 1 and scan.angle_increment == 0.0
    assert scan.angle_min == scan.angle_max == 0.0
    assert scan.ranges[0] == pytest.approx(2.0, abs=1e-6)


def test_no_return_is_plus_inf_and_too_close_is_minus_inf(scene):
    config = replace(NOISELESS, samples=3, min_angle=-math.pi / 2, max_angle=math.pi / 2,
                     range_min=1.5, range_max=1.9)
    ranges = Lidar(scene, config, np.random.default_rng(0)).scan((0.0, 0.0, 0.0)).ranges
    # Right: nothing; ahead: the wall at 2.0 > range_max; left: the post at 1.25 < range_min.
    assert list(ranges) == [math.inf, math.inf, -math.inf]


@pytest.mark.parametrize('beams', [10_000, pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE, 20_000])
def test_thousands_of_beams_each_get_a_reading(scene, beams):
    config = replace(NOISELESS, samples=beams, min_angle=-math.pi, max_angle=math.pi)
    scan = Lidar(scene, config, np.random.default_rng(0)).scan((0.0, 0.0, 0.0))
    assert len(scan.ranges) == beams
    angles = scan.angle_min + scan.angle_increment * np.arange(beams)
    ahead = np.abs(angles) < 0.4
    assert np.allclose(scan.ranges[ahead], 2.0 / np.cos(angles[ahead]), atol=1e-6)
    assert np.isinf(scan.ranges).sum() > 0


def noisy_wall_scan(seed: int, stddev: float = 0.01):
    client = pybullet.connect(pybullet.DIRECT)
    try:
        build_scene(client, SCENE)
        config = replace(NOISELESS, samples=2001, min_angle=-0.3, max_angle=0.3,
                         noise_stddev=stddev)
        lidar = Lidar(client, config, np.random.default_rng(seed))
        return lidar.true_ranges((0.0, 0.0, 0.0)), lidar.scan((0.0, 0.0, 0.0)).ranges
    finally:
        pybullet.disconnect(physicsClientId=client)


def test_noise_is_gaussian_with_the_configured_spread_and_repeats_with_the_seed():
    true, noisy = noisy_wall_scan(seed=7)
    error = noisy - true
    assert abs(error.mean()) < 0.001
    assert error.std() == pytest.approx(0.01, rel=0.1)
    assert np.array_equal(noisy, noisy_wall_scan(seed=7)[1])
    assert not np.array_equal(noisy, noisy_wall_scan(seed=8)[1])


def test_noisy_readings_are_clamped_into_the_valid_range(scene):
    config = replace(NOISELESS, samples=500, min_angle=-0.05, max_angle=0.05, range_min=1.99,
                     range_max=2.02, noise_stddev=0.5)
    ranges = Lidar(scene, config, np.random.default_rng(0)).scan((0.0, 0.0, 0.0)).ranges
    assert np.all((ranges >= 1.99) & (ranges <= 2.02))
    assert np.any(ranges == 1.99) and np.any(ranges == 2.02)


def test_noisy_scan_is_the_true_range_plus_the_generators_noise_clamped(scene):
    config = replace(NOISELESS, samples=200, min_angle=-math.pi, max_angle=math.pi,
                     range_min=1.3, range_max=2.2, noise_mean=0.01, noise_stddev=0.2,
                     pose=(0.0, 0.0, 0.3, 0.0, 0.0, 0.0))
    pose = (0.0, 0.1, 0.4)
    lidar = Lidar(scene, config, np.random.default_rng(3))
    true = lidar.true_ranges(pose)
    ranges = lidar.scan(pose).ranges
    noise = np.random.default_rng(3).normal(0.01, 0.2, 200)
    expected = np.clip(true + noise, 1.3, 2.2)
    expected[true >= 2.2] = math.inf
    expected[true < 1.3] = -math.inf
    assert np.array_equal(ranges, expected)
    # The wall is in range, the post too close and most directions see nothing.
    assert np.isfinite(ranges).any() and np.isneginf(ranges).any() and np.isposinf(ranges).any()


def test_scans_do_not_share_arrays_with_later_scans(scene):
    config = replace(NOISELESS, samples=8, min_angle=-math.pi, max_angle=math.pi)
    lidar = Lidar(scene, config, np.random.default_rng(0))
    first, true = lidar.scan((0.0, 0.0, 0.0)), lidar.true_ranges((0.0, 0.0, 0.0))
    kept = first.ranges.copy(), first.intensities.copy(), true.copy()
    second = lidar.scan((0.5, 0.3, 1.0))
    lidar.true_ranges((-0.4, 0.2, -2.0))
    assert np.array_equal(first.ranges, kept[0]) and not np.array_equal(second.ranges, kept[0])
    assert np.array_equal(first.intensities, kept[1]) and np.array_equal(true, kept[2])
    assert second.intensities is not first.intensities


def test_ray_ends_are_the_beams_turned_by_the_robots_yaw(scene):
    config = replace(NOISELESS, samples=7, pose=(0.2, -0.1, 0.3, 0.0, 0.1, 0.4))
    lidar = Lidar(scene, config, np.random.default_rng(0))
    pose = (0.3, -0.6, 2.5)
    starts, ends = lidar.ray_segments(pose, np.full(7, math.inf))
    origin = lidar.origin(pose)
    cos_yaw, sin_yaw = math.cos(pose[2]), math.sin(pose[2])
    reach = beam_directions(config) * config.range_max
    assert np.array_equal(starts, np.tile(origin, (7, 1)))
    # Bit for bit the formula, summed left to right.
    assert np.array_equal(ends[:, 0], origin[0] + cos_yaw * reach[:, 0] - sin_yaw * reach[:, 1])
    assert np.array_equal(ends[:, 1], origin[1] + sin_yaw * reach[:, 0] + cos_yaw * reach[:, 1])
    assert np.array_equal(ends[:, 2], origin[2] + reach[:, 2])


def test_two_scenes_in_two_clients_do_not_see_each_other(scene):
    other = pybullet.connect(pybullet.DIRECT)
    try:
        build_scene(other, (Shape('box', 1.0, 0.0, 0.5, size=(0.2, 1.0, 1.0)),))
        ray = ([[0.0, 0.0, 0.3]], [[9.0, 0.0, 0.3]])
        assert cast_rays(other, *ray)[0] == pytest.approx(0.9)
        assert cast_rays(scene, *ray)[0] == pytest.approx(2.0)
    finally:
        pybullet.disconnect(physicsClientId=other)


def test_pybullet_threads_split_a_dense_scan_without_changing_it():
    from sim_bridge.simulation.simulator import BulletOptions, Simulator
    scans = {}
    for threads in (1, 0, None):
        with Simulator('room', lidar_samples=1081, lidar_noise_stddev=0.0,
                       bullet=BulletOptions(ray_threads=threads)) as sim:
            scans[threads] = sim.scan().ranges
            assert sim._lidar.threads == (0 if threads is None else threads)
    assert np.array_equal(scans[1], scans[0]) and np.array_equal(scans[1], scans[None])


def test_a_rolled_cylinder_and_a_mesh_are_seen_where_their_surfaces_are(client):
    # A wheel-like cylinder rolled onto its side (axis along y) ahead, and a trimesh cone
    # standing on its apex on the left: at the laser's height z its section has radius z/2.
    cone = trimesh.creation.cone(0.5, 1.0, sections=256)
    cone.apply_transform(trimesh.transformations.rotation_matrix(math.pi, (1.0, 0.0, 0.0)))
    cone.apply_translation((0.0, 0.0, 1.0))
    build_scene(client, (Shape('cylinder', 2.0, 0.0, 0.3, radius=0.3, length=0.2,
                               roll=0.5 * math.pi),
                         Shape('mesh', 0.0, 2.0, 0.0, mesh=Mesh(cone.vertices, cone.faces))))
    starts = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.5], [0.0, 0.0, 0.4], [0.0, 0.0, 0.8]])
    ends = starts + [[9.0, 0.0, 0.0], [9.0, 0.0, 0.0], [0.0, 9.0, 0.0], [0.0, 9.0, 0.0]]
    distances = cast_rays(client, starts, ends)
    wheel_front = 2.0 - math.sqrt(0.3 ** 2 - 0.2 ** 2)
    assert distances == pytest.approx([1.7, wheel_front, 1.8, 1.6], abs=1e-3)


def test_a_robot_standing_still_casts_no_rays_and_reads_as_if_it_had(scene, monkeypatch):
    casts = []
    cast = lidar_module._fractions
    monkeypatch.setattr(lidar_module, '_fractions',
                        lambda *args: casts.append(args[0]) or cast(*args))
    config = replace(NOISELESS, samples=90, min_angle=-math.pi, max_angle=math.pi,
                     noise_stddev=0.01)
    here, there = (0.0, 0.0, 0.3), (0.4, -0.2, 1.0)
    still = Lidar(scene, config, np.random.default_rng(3))
    moving = Lidar(scene, config, np.random.default_rng(3))
    first, second = still.scan(here).ranges, still.scan(here).ranges
    assert len(casts) == 1
    # Each lidar's second scan takes the same noise; the moving one casts anew.
    moving.scan(there)
    assert np.array_equal(second, moving.scan(here).ranges)
    assert not np.array_equal(first, second)
    assert np.array_equal(still.scan(there).ranges, moving.scan(there).ranges)
    assert len(casts) == 5
    # What a caller does to a reading does not reach the next.
    still.true_ranges(there).fill(0.0)
    assert np.array_equal(still.true_ranges(there), moving.true_ranges(there))
