"""Tests of the pybullet window's drawing, in a DIRECT client (no display needed)."""

import math

import numpy as np
import pybullet
import pytest

from sim_bridge.simulation.geometry import Mesh, Shape
from sim_bridge.simulation.lidar import build_scene
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.viewer import drawn_beams, MAX_DRAWN_RAYS, robot_mesh, Viewer

LAB_ROBOT = (Shape('cylinder', 0.0, 0.0, 0.075, radius=0.15, length=0.15),)


@pytest.fixture
def client():
    client = pybullet.connect(pybullet.DIRECT)
    yield client
    pybullet.disconnect(physicsClientId=client)


@pytest.mark.parametrize('beams', [1, 36, MAX_DRAWN_RAYS, MAX_DRAWN_RAYS + 1, 1081, 10000])
def test_drawn_beams_keeps_every_beam_of_a_sparse_lidar_and_thins_a_dense_one(beams):
    drawn = drawn_beams(beams)
    assert drawn[0] == 0
    assert len(drawn) <= MAX_DRAWN_RAYS
    assert len(drawn) == beams if beams <= MAX_DRAWN_RAYS else len(drawn) > MAX_DRAWN_RAYS // 2


def test_viewer_moves_the_robot_body_to_the_pose(client):
    viewer = Viewer(client, LAB_ROBOT)
    viewer.show_robot((1.0, -2.0, math.pi / 2))
    position, orientation = pybullet.getBasePositionAndOrientation(
        viewer.robot_body, physicsClientId=client)
    assert position == pytest.approx((1.0, -2.0, 0.0))
    assert pybullet.getEulerFromQuaternion(orientation)[2] == pytest.approx(math.pi / 2)


def test_viewer_reuses_its_ray_lines_scan_after_scan(client):
    viewer = Viewer(client, LAB_ROBOT, draw_rays=True)
    segments = np.zeros((36, 3)), np.ones((36, 3)), np.ones(36, dtype=bool)
    viewer.show_scan(*segments)
    viewer.show_scan(*segments)
    assert len(viewer.ray_items) == 36


def test_ray_segments_end_at_the_readings_and_at_range_max_for_no_return():
    with Simulator('wall_follow_box', lidar_noise_stddev=0.0) as sim:
        scan = sim.scan()
        starts, ends = sim._lidar.ray_segments(sim.pose, scan.ranges)
        lengths = np.linalg.norm(ends - starts, axis=1)
        finite = np.isfinite(scan.ranges)
        assert finite.any() and not finite.all()
        np.testing.assert_allclose(lengths[finite], scan.ranges[finite], atol=1e-9)
        np.testing.assert_allclose(lengths[~finite], sim.lidar_config.range_max, atol=1e-9)


def test_viewer_draws_rolled_wheels_and_meshes_where_they_are(client):
    # A robot of a body box, a wheel rolled onto its side and a mesh bumper; a mesh obstacle.
    wheel = Shape('cylinder', 0.0, 0.2, 0.05, radius=0.05, length=0.02, roll=math.pi / 2)
    bumper = Mesh(np.array([[0.2, -0.1, 0.0], [0.2, 0.1, 0.0], [0.25, 0.0, 0.1]]),
                  np.array([[0, 1, 2]]))
    shapes = (Shape('box', 0.0, 0.0, 0.1, size=(0.3, 0.3, 0.2)), wheel,
              Shape('mesh', mesh=bumper))
    vertices, faces = robot_mesh(shapes)
    assert vertices.min(axis=0) == pytest.approx((-0.15, -0.15, 0.0), abs=1e-3)
    assert vertices.max(axis=0) == pytest.approx((0.25, 0.21, 0.2), abs=1e-3)
    assert faces.max() == len(vertices) - 1
    build_scene(client, (Shape('mesh', 1.0, 0.0, 0.0, mesh=bumper), wheel), visuals=True)
    viewer = Viewer(client, shapes)
    viewer.show_robot((0.5, 0.5, 1.0))
    assert pybullet.getVisualShapeData(viewer.robot_body, physicsClientId=client)
