"""Tests of simulation.geometry in 3-D: rotations, placing shapes, capsules, ellipsoids, meshes."""

import math

import numpy as np
import pytest

from sim_bridge.simulation.geometry import (
    euler_from_matrix, Mesh, rotation_matrix, Shape, triangulate)

ANGLES = [(0.3, -0.4, 2.0), (math.pi / 2, 0.0, 0.5), (0.0, math.pi / 2, 0.3), (-1.0, 0.2, -3.0),
          (0.0, 0.0, 0.0)]


@pytest.mark.parametrize('roll, pitch, yaw', ANGLES)
def test_euler_angles_read_back_the_same_rotation(roll, pitch, yaw):
    rotation = rotation_matrix(roll, pitch, yaw)
    assert np.allclose(rotation @ rotation.T, np.eye(3))
    assert np.allclose(rotation_matrix(*euler_from_matrix(rotation)), rotation)


def test_rotation_matrix_is_roll_then_pitch_then_yaw_about_fixed_axes():
    # A quarter roll takes y to z; a quarter yaw then takes x to y.
    assert np.allclose(rotation_matrix(math.pi / 2, 0.0, 0.0) @ (0, 1, 0), (0, 0, 1))
    assert np.allclose(rotation_matrix(0.0, 0.0, math.pi / 2) @ (1, 0, 0), (0, 1, 0))
    assert np.allclose(rotation_matrix(math.pi / 2, 0.0, math.pi / 2) @ (0, 1, 0), (0, 0, 1))


def test_a_wheel_rolled_a_quarter_turn_stands_on_its_rim():
    # A TurtleBot3 wheel: a cylinder of radius 0.033 m rolled about x, its centre 0.033 m up.
    wheel = Shape('cylinder', radius=0.033, length=0.018, roll=-math.pi / 2)
    placed = wheel.placed(0.0, 0.08, 0.033, 0.0)
    bottom, top = placed.z_range()
    assert bottom == pytest.approx(0.0, abs=1e-3) and top == pytest.approx(0.066, abs=1e-3)
    vertices = triangulate(placed)[0] @ placed.rotation().T + (placed.x, placed.y, placed.z)
    assert np.ptp(vertices[:, 1]) == pytest.approx(0.018)  # its width is along y now


def test_placing_composes_the_parents_rotation_and_position():
    child = Shape('box', x=1.0, size=(0.1, 0.2, 0.3), yaw=0.5)
    placed = child.placed(2.0, 0.0, 0.0, math.pi / 2)
    assert (placed.x, placed.y) == pytest.approx((2.0, 1.0))
    assert placed.yaw == pytest.approx(0.5 + math.pi / 2)
    assert (placed.roll, placed.pitch) == pytest.approx((0.0, 0.0))


def test_capsules_and_ellipsoids_have_their_extents():
    capsule = triangulate(Shape('capsule', radius=0.1, length=0.5))[0]
    assert np.ptp(capsule, axis=0) == pytest.approx((0.2, 0.2, 0.7), abs=1e-3)
    ellipsoid = triangulate(Shape('ellipsoid', size=(0.2, 0.4, 0.6)))[0]
    assert np.ptp(ellipsoid, axis=0) == pytest.approx((0.2, 0.4, 0.6), abs=1e-3)


def test_a_mesh_shape_is_its_own_triangles_and_only_it_has_a_mesh():
    tetrahedron = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]),
                       np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]))
    shape = Shape('mesh', z=0.5, mesh=tetrahedron)
    assert shape.z_range() == (0.5, 1.5)
    assert triangulate(shape)[0] is not None and len(triangulate(shape)[1]) == 4
    with pytest.raises(ValueError, match='only a mesh shape'):
        Shape('box', size=(1, 1, 1), mesh=tetrahedron)
    with pytest.raises(ValueError, match='only a mesh shape'):
        Shape('mesh')
