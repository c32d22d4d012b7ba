"""Tests of simulation.geometry: footprints, signed distances, shapes and their meshes."""

import math

import numpy as np
import pytest
import shapely

from sim_bridge.simulation.geometry import (
    Footprint, FootprintSet, MESH_TOLERANCE, point_in_world, Shape, signed_distance,
    slice_footprints, triangulate, wrap_angle)


def test_wrap_angle_maps_into_minus_pi_to_pi():
    angles = np.linspace(-20.0, 20.0, 401)
    wrapped = np.array([wrap_angle(angle) for angle in angles])
    assert np.all(wrapped >= -math.pi) and np.all(wrapped < math.pi)
    assert np.allclose(np.sin(wrapped), np.sin(angles)) and np.allclose(np.cos(wrapped),
                                                                        np.cos(angles))


def test_a_point_in_a_frame_is_rotated_by_the_frame_yaw():
    assert point_in_world((1.0, 2.0, math.pi / 2), (1.0, 0.0)) == pytest.approx((1.0, 3.0))


def test_circle_distance_is_negative_inside_zero_on_edge_positive_outside():
    circle = Footprint('circle', 1.0, 1.0, radius=0.5)
    assert circle.distance(1.0, 1.0) == pytest.approx(-0.5)
    assert circle.distance(1.5, 1.0) == pytest.approx(0.0)
    assert circle.distance(1.0, 3.0) == pytest.approx(1.5)


def test_rotated_box_distance_to_faces_and_corners():
    # 2 m x 1 m box turned by 90 degrees: it spans x in [-0.5, 0.5] and y in [-1, 1].
    box = Footprint('box', 0.0, 0.0, math.pi / 2, half_x=1.0, half_y=0.5)
    assert box.distance(0.0, 2.0) == pytest.approx(1.0)
    assert box.distance(1.5, 0.0) == pytest.approx(1.0)
    assert box.distance(1.5, 2.0) == pytest.approx(math.sqrt(2.0))
    assert box.distance(0.0, 0.0) == pytest.approx(-0.5)
    assert box.distance(0.0, 0.9) == pytest.approx(-0.1)


def test_box_bounds_and_outline_follow_the_rotation():
    box = Footprint('box', 1.0, 0.0, math.pi / 4, half_x=1.0, half_y=1.0)
    half_diagonal = math.sqrt(2.0)
    assert box.bounds() == pytest.approx((1.0 - half_diagonal, -half_diagonal,
                                          1.0 + half_diagonal, half_diagonal))
    corners = box.outline()
    assert corners.shape == (4, 2)
    assert np.allclose(np.hypot(corners[:, 0] - 1.0, corners[:, 1]), half_diagonal)


def test_unknown_footprint_or_shape_kind_is_rejected():
    with pytest.raises(ValueError, match='footprint kind'):
        Footprint('triangle', 0.0, 0.0)
    with pytest.raises(ValueError, match='shape kind'):
        Shape('cone')


def random_footprints() -> list[Footprint]:
    return [Footprint('circle', -2.0, 1.0, radius=0.8),
            Footprint('box', 1.0, 0.5, 0.7, half_x=1.2, half_y=0.3),
            Footprint('box', 0.0, -2.0, -2.0, half_x=0.4, half_y=0.9),
            Footprint('circle', 2.5, -1.5, radius=0.2)]


def test_vectorised_and_scalar_distances_agree_and_name_the_nearest_footprint():
    footprints = random_footprints()
    points = np.random.default_rng(1).uniform(-4.0, 4.0, size=(400, 2))
    per_footprint = np.array([[fp.distance(x, y) for fp in footprints] for x, y in points])
    assert np.allclose(signed_distance(points, footprints), per_footprint.min(axis=1))
    field = FootprintSet(footprints)
    for (x, y), expected in zip(points, per_footprint):
        distance, index = field.nearest(x, y)
        assert distance == pytest.approx(expected.min())
        assert index == int(np.argmin(expected))


def test_box_distance_matches_a_brute_force_distance_to_its_outline():
    box = Footprint('box', 0.3, -0.2, 0.4, half_x=0.7, half_y=0.25)
    corners = box.outline()
    edge_points = np.vstack([np.linspace(corners[k], corners[(k + 1) % 4], 2001)
                             for k in range(4)])
    points = np.random.default_rng(2).uniform(-2.0, 2.0, size=(200, 2))
    brute = np.min(np.linalg.norm(points[:, None, :] - edge_points[None], axis=2), axis=1)
    computed = signed_distance(points, [box])
    assert np.allclose(np.abs(computed), brute, atol=1e-3)


def test_empty_footprint_set_is_infinitely_far():
    assert FootprintSet([]).nearest(0.0, 0.0) == (math.inf, -1)
    assert np.all(np.isinf(signed_distance(np.zeros((3, 2)), [])))


def test_shape_placed_footprint_and_heights():
    box = Shape('box', x=1.0, y=0.0, z=0.5, yaw=0.1, size=(2.0, 1.0, 1.0))
    moved = box.placed(0.0, 0.0, 0.2, math.pi / 2)
    assert (moved.x, moved.y, moved.z) == pytest.approx((0.0, 1.0, 0.7))
    assert moved.yaw == pytest.approx(math.pi / 2 + 0.1)
    assert moved.footprint() == Footprint('box', moved.x, moved.y, moved.yaw, half_x=1.0,
                                          half_y=0.5)
    assert moved.z_range() == pytest.approx((0.2, 1.2))
    assert Shape('cylinder', radius=0.5, length=2.0).height == 2.0
    assert Shape('sphere', radius=0.5).footprint() == Footprint('circle', 0.0, 0.0,
                                                                radius=0.5)


def test_box_mesh_is_exact():
    vertices, faces = triangulate(Shape('box', size=(2.0, 1.0, 0.5)))
    assert np.allclose(np.abs(vertices), (1.0, 0.5, 0.25))
    assert faces.shape == (12, 3) and set(faces.ravel()) == set(range(8))


def sample_surface(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    weights = np.random.default_rng(3).dirichlet((1.0, 1.0, 1.0), size=(len(faces), 8))
    on_faces = np.einsum('tkj,tjd->tkd', weights, vertices[faces]).reshape(-1, 3)
    return np.vstack((on_faces, vertices[faces].mean(axis=1), vertices))


@pytest.mark.parametrize('radius', [0.05, 0.5, 3.0])
def test_sphere_mesh_stays_within_tolerance_of_the_sphere(radius):
    vertices, faces = triangulate(Shape('sphere', radius=radius))
    error = np.linalg.norm(sample_surface(vertices, faces), axis=1) - radius
    assert np.max(np.abs(error)) <= MESH_TOLERANCE


@pytest.mark.parametrize('radius', [0.05, 0.8, 3.0])
def test_cylinder_mesh_stays_within_tolerance_of_the_cylinder(radius):
    vertices, faces = triangulate(Shape('cylinder', radius=radius, length=1.0))
    points = sample_surface(vertices, faces)
    assert np.allclose(np.abs(vertices[:, 2]), 0.5)
    side = np.abs(points[:, 2]) < 0.5 - 1e-9
    error = np.hypot(points[side, 0], points[side, 1]) - radius
    assert np.max(np.abs(error)) <= MESH_TOLERANCE
    caps = np.hypot(points[~side, 0], points[~side, 1])
    assert np.max(caps) <= radius + MESH_TOLERANCE


def test_polygon_footprints_measure_like_the_analytic_ones():
    # An L-shaped polygon: its distances, bounds and reach, alone and in a set with a circle.
    ell = Footprint.from_polygon(shapely.Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2),
                                                  (0, 2)]))
    assert ell.distance(0.5, 0.5) == pytest.approx(-0.5)
    assert ell.distance(1.5, 1.5) == pytest.approx(0.5)
    assert ell.distance(3.0, 0.5) == pytest.approx(1.0)
    assert ell.bounds() == (0.0, 0.0, 2.0, 2.0) and len(ell.outline()) == 6
    assert ell.distance(ell.x, ell.y) < 0.0
    assert ell.reach() == pytest.approx(max(math.hypot(px - ell.x, py - ell.y)
                                            for px, py in ell.outline()))
    footprints = FootprintSet([Footprint('circle', 5.0, 0.0, radius=1.0), ell])
    points = np.random.default_rng(3).uniform(-1.0, 7.0, (200, 2))
    vectorised = footprints.distance(points)
    scalar = [footprints.nearest(x, y) for x, y in points]
    assert vectorised == pytest.approx([distance for distance, _ in scalar])
    assert {index for _, index in scalar} == {0, 1}


def test_a_rotated_shape_projects_to_its_polygon():
    # A cylinder rolled onto its side projects to a rectangle (within the mesh tolerance).
    wheel = Shape('cylinder', 1.0, 2.0, 0.1, radius=0.1, length=0.04, roll=0.5 * math.pi)
    footprint = wheel.footprint()
    assert footprint.kind == 'polygon'
    assert footprint.bounds() == pytest.approx((0.9, 1.98, 1.1, 2.02), abs=3e-4)
    # Between 0.15 and 0.3 m only its top part is left: a narrower rectangle.
    (top,) = slice_footprints(wheel, 0.15, 0.3)
    half = math.sqrt(0.1 ** 2 - 0.05 ** 2)
    assert top.bounds() == pytest.approx((1.0 - half, 1.98, 1.0 + half, 2.02), abs=3e-4)
    assert slice_footprints(wheel, 0.25, 0.3) == ()
