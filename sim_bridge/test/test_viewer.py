"""Tests of the pybullet window's drawing, in a DIRECT client (no display needed)."""

import math

import numpy as np
import pybullet
import pytest

from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.viewer import drawn_beams, MAX_DRAWN_RAYS, Viewer


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
    viewer = Viewer(client, radius=0.15, height=0.15)
    viewer.show_robot((1.0, -2.0, math.pi / 2))
    position, orientation = pybullet.getBasePositionAndOrientation(
        viewer.robot_body, physicsClientId=client)
    assert position == pytest.approx((1.0, -2.0, 0.0))
    assert pybullet.getEulerFromQuaternion(orientation)[2] == pytest.approx(math.pi / 2)


def test_viewer_reuses_its_ray_lines_scan_after_scan(client):
    viewer = Viewer(client, radius=0.15, height=0.15, draw_rays=True)
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
