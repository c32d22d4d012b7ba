"""
Plain geometry of the simulated world: 3-D primitives, their 2-D floor outlines, distances.

A :class:`Shape` is a collision primitive (box, cylinder, sphere, capsule, ellipsoid) or a
triangle :class:`Mesh`, placed by its centre and a rotation (roll, pitch, yaw: SDF's fixed-axis
X-Y-Z, REP-103). :func:`slice_footprints` gives the vertical projection on the floor of the
part of a shape between two heights, the outline a robot driving through that height band
can bump into, as :class:`Footprint` s: an exact circle or rectangle for an upright box,
cylinder or sphere, else shapely polygons of the triangulated shape clipped to the band
(trimesh clips, shapely unites). :meth:`Shape.footprint` is the projection of the whole shape.
:func:`signed_distance` and :class:`FootprintSet` measure how far points are from footprints;
:func:`triangulate` turns a shape into a triangle mesh for the ray caster and the slicer.

Units: m and rad; angles counter-clockwise (REP-103).
"""

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
import math

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry
from sim_bridge.simulation.mesh_slice import clip_triangles, mesh_slice
import trimesh
from trimesh import transformations

SHAPE_KINDS = ('box', 'cylinder', 'sphere', 'capsule', 'ellipsoid', 'mesh')
FOOTPRINT_KINDS = ('circle', 'box', 'polygon')
#: Largest distance (m) between a triangulated surface and the true one (see :func:`triangulate`).
MESH_TOLERANCE = 2e-4
#: Cap on the segments around a round mesh, so huge radii stay affordable.
MAX_MESH_SEGMENTS = 720
#: Segments per quarter circle of a circle footprint turned into a polygon (see
#: :meth:`Footprint.geometry`): 0.03 mm off a 0.1 m radius.
CIRCLE_QUARTER_SEGMENTS = 32


def wrap_angle(angle: float) -> float:
    """Return ``angle`` (rad) wrapped into [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def point_in_world(pose: tuple[float, float, float],
                   offset: tuple[float, float]) -> tuple[float, float]:
    """Return (x, y) in m of the point ``offset`` (m) in the frame ``pose`` (x, y m; yaw rad)."""
    x, y, yaw = pose
    return (x + offset[0] * math.cos(yaw) - offset[1] * math.sin(yaw),
            y + offset[0] * math.sin(yaw) + offset[1] * math.cos(yaw))


@dataclass(frozen=True)
class Footprint:
    """
    A 2-D outline on the floor in the world frame: a circle, a rotated rectangle or a polygon.

    ``x``, ``y`` (m) is the centre and ``yaw`` (rad) the rectangle's rotation; ``radius`` (m)
    sizes a circle, ``half_x`` and ``half_y`` (m) a rectangle along its own axes. A 'polygon'
    is the shapely ``polygon`` (m; a Polygon, maybe with holes, or for the projection of a
    whole mesh a MultiPolygon) and its ``x``, ``y`` a point inside it.
    """

    kind: str
    x: float
    y: float
    yaw: float = 0.0
    radius: float = 0.0
    half_x: float = 0.0
    half_y: float = 0.0
    polygon: BaseGeometry | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in FOOTPRINT_KINDS:
            raise ValueError(f'footprint kind must be one of {FOOTPRINT_KINDS}, not {self.kind!r}')
        if (self.kind == 'polygon') != (self.polygon is not None):
            raise ValueError('a polygon footprint, and only one, has a polygon')

    @classmethod
    def from_polygon(cls, polygon: BaseGeometry) -> 'Footprint':
        """Return the footprint of a shapely (Multi)Polygon (m), centred on a point inside it."""
        inside = polygon.representative_point()
        return cls('polygon', inside.x, inside.y, polygon=polygon)

    def distance(self, x: float, y: float) -> float:
        """Return the signed distance from the point (x, y) to the edge (m); negative inside."""
        dx = x - self.x
        dy = y - self.y
        if self.kind == 'circle':
            return math.hypot(dx, dy) - self.radius
        if self.kind == 'polygon':
            return float(_polygon_distance(self.polygon, np.array([[x, y]]))[0])
        cos_yaw = math.cos(self.yaw)
        sin_yaw = math.sin(self.yaw)
        return _box_distance(cos_yaw * dx + sin_yaw * dy, cos_yaw * dy - sin_yaw * dx,
                             self.half_x, self.half_y)

    def bounds(self) -> tuple[float, float, float, float]:
        """Return the axis-aligned bounding box (xmin, ymin, xmax, ymax) in m."""
        if self.kind == 'polygon':
            return tuple(float(value) for value in self.polygon.bounds)
        if self.kind == 'circle':
            extent_x = extent_y = self.radius
        else:
            cos_yaw = abs(math.cos(self.yaw))
            sin_yaw = abs(math.sin(self.yaw))
            extent_x = cos_yaw * self.half_x + sin_yaw * self.half_y
            extent_y = sin_yaw * self.half_x + cos_yaw * self.half_y
        return (self.x - extent_x, self.y - extent_y, self.x + extent_x, self.y + extent_y)

    def outline(self, segments: int = 64) -> np.ndarray:
        """
        Return the closed outline as a (K, 2) array of points (m), e.g. for plotting.

        A circle gets ``segments`` points; a rectangle its four corners (counter-clockwise); a
        polygon its outer ring (a MultiPolygon, the whole projection of a mesh, its convex
        hull's).
        """
        if self.kind == 'polygon':
            polygon = self.polygon
            if polygon.geom_type != 'Polygon':
                polygon = polygon.convex_hull
            return np.asarray(polygon.exterior.coords)[:-1]
        if self.kind == 'circle':
            angles = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
            return np.column_stack((self.x + self.radius * np.cos(angles),
                                    self.y + self.radius * np.sin(angles)))
        corners = np.array([[1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0]])
        corners *= (self.half_x, self.half_y)
        cos_yaw = math.cos(self.yaw)
        sin_yaw = math.sin(self.yaw)
        rotation = np.array([[cos_yaw, -sin_yaw], [sin_yaw, cos_yaw]])
        return corners @ rotation.T + (self.x, self.y)

    def reach(self) -> float:
        """Return the largest distance (m) from the centre (x, y) to the outline."""
        if self.kind == 'circle':
            return self.radius
        if self.kind == 'box':
            return math.hypot(self.half_x, self.half_y)
        corners = shapely.get_coordinates(self.polygon.exterior if self.polygon.geom_type ==
                                          'Polygon' else self.polygon)
        return float(np.hypot(corners[:, 0] - self.x, corners[:, 1] - self.y).max())

    def geometry(self) -> BaseGeometry:
        """
        Return the outline as a shapely Polygon or MultiPolygon (m).

        A rectangle is exact; a circle a polygon of 4 * :data:`CIRCLE_QUARTER_SEGMENTS` vertices
        on the circle (for set operations; distances to circles stay analytic elsewhere).
        """
        if self.kind == 'polygon':
            return self.polygon
        if self.kind == 'circle':
            return shapely.Point(self.x, self.y).buffer(self.radius, CIRCLE_QUARTER_SEGMENTS)
        return shapely.Polygon(self.outline())


def _polygon_distance(polygon: BaseGeometry, points: np.ndarray) -> np.ndarray:
    """Return the signed distances (m) of (N, 2) points (m) to a polygon's edge; < 0 inside."""
    distance = shapely.distance(polygon.boundary, shapely.points(points))
    inside = shapely.contains_xy(polygon, points[:, 0], points[:, 1])
    return np.where(inside, -distance, distance)


def _box_distance(local_x: float, local_y: float, half_x: float, half_y: float) -> float:
    """Return the signed distance (m) from a point in a rectangle's frame to its edge."""
    over_x = abs(local_x) - half_x
    over_y = abs(local_y) - half_y
    if over_x > 0.0 or over_y > 0.0:
        return math.hypot(max(over_x, 0.0), max(over_y, 0.0))
    return max(over_x, over_y)


def signed_distance(points: np.ndarray, footprints: Sequence[Footprint]) -> np.ndarray:
    """
    Return, for (N, 2) points (m), the (N,) distances (m) to the nearest footprint edge.

    Negative inside a footprint; +inf for every point when there are no footprints.
    """
    return FootprintSet(footprints).distance(points)


class FootprintSet:
    """
    A fixed set of footprints prepared for fast distance queries.

    :meth:`nearest` answers for one point in pure Python (a few microseconds for the dozen
    footprints of a lab world, cheaper than any numpy call); :meth:`distance` is vectorised for
    many points.
    """

    def __init__(self, footprints: Sequence[Footprint]) -> None:
        self.footprints = tuple(footprints)
        self._circles = [(index, fp.x, fp.y, fp.radius)
                         for index, fp in enumerate(self.footprints) if fp.kind == 'circle']
        self._boxes = [(index, fp.x, fp.y, math.cos(fp.yaw), math.sin(fp.yaw),
                        fp.half_x, fp.half_y)
                       for index, fp in enumerate(self.footprints) if fp.kind == 'box']
        polygons = [(index, fp.polygon)
                    for index, fp in enumerate(self.footprints) if fp.kind == 'polygon']
        self._polygon_indices = [index for index, _ in polygons]
        self._polygons = np.array([polygon for _, polygon in polygons], dtype=object)
        self._boundaries = shapely.boundary(self._polygons)
        shapely.prepare(self._polygons)
        shapely.prepare(self._boundaries)

    def __len__(self) -> int:
        return len(self.footprints)

    def nearest(self, x: float, y: float) -> tuple[float, int]:
        """
        Return (signed distance in m, index of the footprint) nearest to (x, y).

        The index is -1 and the distance +inf when the set is empty.
        """
        best = math.inf
        best_index = -1
        hypot = math.hypot
        for index, cx, cy, radius in self._circles:
            distance = hypot(x - cx, y - cy) - radius
            if distance < best:
                best = distance
                best_index = index
        for index, cx, cy, cos_yaw, sin_yaw, half_x, half_y in self._boxes:
            dx = x - cx
            dy = y - cy
            over_x = abs(cos_yaw * dx + sin_yaw * dy) - half_x
            over_y = abs(cos_yaw * dy - sin_yaw * dx) - half_y
            if over_x > 0.0 or over_y > 0.0:
                distance = hypot(over_x if over_x > 0.0 else 0.0,
                                 over_y if over_y > 0.0 else 0.0)
            else:
                distance = over_x if over_x > over_y else over_y
            if distance < best:
                best = distance
                best_index = index
        if self._polygon_indices:
            distances = shapely.distance(self._boundaries, shapely.Point(x, y))
            distances[shapely.contains_xy(self._polygons, x, y)] *= -1.0
            nearest = int(np.argmin(distances))
            if distances[nearest] < best:
                best = float(distances[nearest])
                best_index = self._polygon_indices[nearest]
        return best, best_index

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Return the (N,) signed distances (m) from (N, 2) points (m) to the nearest edge."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        best = np.full(len(points), np.inf)
        for _, cx, cy, radius in self._circles:
            np.minimum(best, np.hypot(points[:, 0] - cx, points[:, 1] - cy) - radius, out=best)
        for _, cx, cy, cos_yaw, sin_yaw, half_x, half_y in self._boxes:
            dx = points[:, 0] - cx
            dy = points[:, 1] - cy
            over_x = np.abs(cos_yaw * dx + sin_yaw * dy) - half_x
            over_y = np.abs(cos_yaw * dy - sin_yaw * dx) - half_y
            outside = np.hypot(np.maximum(over_x, 0.0), np.maximum(over_y, 0.0))
            inside = np.minimum(np.maximum(over_x, over_y), 0.0)
            np.minimum(best, outside + inside, out=best)
        for polygon in self._polygons:
            np.minimum(best, _polygon_distance(polygon, points), out=best)
        return best


@dataclass(frozen=True, eq=False)
class Mesh:
    """
    A triangle mesh in its shape's frame: (V, 3) ``vertices`` (m, scale applied), (F, 3) ``faces``.

    ``source`` names the file it was read from, for messages; ``notes`` are the reader's
    warnings about what it could not read besides the triangles (textures).
    """

    vertices: np.ndarray
    faces: np.ndarray
    source: str = ''
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Shape:
    """
    A 3-D collision primitive or mesh resting in (or above) the world.

    ``x``, ``y``, ``z`` (m) is the centre (a mesh's frame origin), ``roll``, ``pitch``, ``yaw``
    (rad) its rotation, fixed axes X then Y then Z as in an SDF ``<pose>``. A box has full edge
    lengths ``size`` (m); a cylinder (axis along its z) has ``radius`` and ``length`` (m); a
    sphere has ``radius`` (m); a capsule is a cylinder of ``radius`` and ``length`` (m) capped by
    half spheres; an ellipsoid has full diameters ``size`` (m, twice SDF's radii); a mesh has
    ``mesh``.
    """

    kind: str
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    yaw: float = 0.0
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    mesh: Mesh | None = None

    def __post_init__(self) -> None:
        if self.kind not in SHAPE_KINDS:
            raise ValueError(f'shape kind must be one of {SHAPE_KINDS}, not {self.kind!r}')
        if (self.kind == 'mesh') != (self.mesh is not None):
            raise ValueError('a mesh shape, and only a mesh shape, has a mesh')

    @property
    def upright(self) -> bool:
        """Return True when the shape is rotated about the vertical axis only."""
        return self.roll == 0.0 and self.pitch == 0.0

    def rotation(self) -> np.ndarray:
        """Return the 3x3 rotation of the shape's frame: Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
        return rotation_matrix(self.roll, self.pitch, self.yaw)

    @property
    def height(self) -> float:
        """Return the vertical extent (m)."""
        bottom, top = self.z_range()
        return top - bottom

    def z_range(self) -> tuple[float, float]:
        """Return the (bottom, top) heights (m)."""
        if self.upright and self.kind in ('box', 'cylinder', 'sphere'):
            half = {'box': 0.5 * self.size[2], 'cylinder': 0.5 * self.length,
                    'sphere': self.radius}[self.kind]
            return (self.z - half, self.z + half)
        heights = triangulate(self)[0] @ self.rotation()[2] + self.z
        return (float(heights.min()), float(heights.max()))

    def placed(self, x: float, y: float, z: float, yaw: float, roll: float = 0.0,
               pitch: float = 0.0) -> 'Shape':
        """Return this shape, given in a parent frame, moved by the parent's pose (m, rad)."""
        placed = pose_matrix(x, y, z, roll, pitch, yaw) @ pose_matrix(
            self.x, self.y, self.z, self.roll, self.pitch, self.yaw)
        roll, pitch, yaw = euler_from_matrix(placed)
        return replace(self, x=float(placed[0, 3]), y=float(placed[1, 3]),
                       z=float(placed[2, 3]), roll=roll, pitch=pitch, yaw=yaw)

    def footprint(self) -> Footprint:
        """
        Return the vertical projection of the whole shape on the floor.

        Exact for an upright box, cylinder or sphere, else a polygon (see
        :func:`slice_footprints`; several parts of a mesh make one MultiPolygon footprint).
        """
        if self.upright and self.kind == 'box':
            return Footprint('box', self.x, self.y, self.yaw,
                             half_x=0.5 * self.size[0], half_y=0.5 * self.size[1])
        if self.upright and self.kind in ('cylinder', 'sphere'):
            return Footprint('circle', self.x, self.y, radius=self.radius)
        return Footprint.from_polygon(slice_polygon(self, -math.inf, math.inf))

    def world_mesh(self, tolerance: float = MESH_TOLERANCE) -> trimesh.Trimesh:
        """Return the shape's triangle mesh (see :func:`triangulate`) placed in the world (m)."""
        vertices, faces = triangulate(self, tolerance)
        return trimesh.Trimesh(vertices @ self.rotation().T + (self.x, self.y, self.z), faces,
                               process=False)


def pose_matrix(x: float, y: float, z: float, roll: float, pitch: float,
                yaw: float) -> np.ndarray:
    """Return the 4x4 transform of a pose: position (m), fixed-axis roll, pitch, yaw (rad)."""
    matrix = transformations.euler_matrix(roll, pitch, yaw, 'sxyz')
    matrix[:3, 3] = (x, y, z)
    return matrix


def rotation_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Return the 3x3 rotation Rz(yaw) @ Ry(pitch) @ Rx(roll) of fixed-axis angles (rad)."""
    return transformations.euler_matrix(roll, pitch, yaw, 'sxyz')[:3, :3]


def quaternion_from_euler(roll: float, pitch: float, yaw: float
                          ) -> tuple[float, float, float, float]:
    """Return the (x, y, z, w) quaternion of fixed-axis roll, pitch, yaw rotations (rad)."""
    cr, sr = math.cos(roll / 2.0), math.sin(roll / 2.0)
    cp, sp = math.cos(pitch / 2.0), math.sin(pitch / 2.0)
    cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def euler_from_matrix(rotation: np.ndarray) -> tuple[float, float, float]:
    """Return fixed-axis (roll, pitch, yaw) in rad of a 3x3 or 4x4 rotation, yaw wrapped."""
    roll, pitch, yaw = transformations.euler_from_matrix(rotation, 'sxyz')
    return (float(roll) + 0.0, float(pitch) + 0.0, wrap_angle(float(yaw)) + 0.0)


def triangulate(shape: Shape, tolerance: float = MESH_TOLERANCE
                ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return a triangle mesh of ``shape`` in its own frame (centre at the origin, no yaw).

    Returns (V, 3) vertices (m) and (T, 3) vertex indices. A box is exact. Round surfaces are
    polygons whose vertices sit slightly outside the true surface and whose faces cut slightly
    inside it, each by at most ``tolerance`` (m), so the error is centred on the true surface
    (up to :data:`MAX_MESH_SEGMENTS` segments around; beyond that the error grows).
    """
    if shape.kind == 'box':
        return _box_mesh(*(0.5 * np.asarray(shape.size, dtype=float)))
    if shape.kind == 'cylinder':
        return _cylinder_mesh(shape.radius, shape.length, tolerance)
    if shape.kind == 'sphere':
        return _sphere_mesh(shape.radius, tolerance)
    if shape.kind == 'ellipsoid':
        vertices, faces = _sphere_mesh(1.0, tolerance / max(0.5 * max(shape.size), 1e-9))
        return vertices * (0.5 * np.asarray(shape.size, dtype=float)), faces
    if shape.kind == 'capsule':
        vertices, faces = _sphere_mesh(shape.radius, tolerance)
        # The sphere's halves pulled apart by the cylinder's length: the band of triangles
        # across the equator stretches into the cylinder's wall.
        offset = np.where(vertices[:, 2:] >= 0.0, 0.5, -0.5) * shape.length
        vertices = vertices + offset * [0.0, 0.0, 1.0]
        return vertices, faces
    return np.asarray(shape.mesh.vertices, dtype=float), np.asarray(shape.mesh.faces)


def _box_mesh(half_x: float, half_y: float, half_z: float) -> tuple[np.ndarray, np.ndarray]:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                     dtype=float)
    faces = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    return signs * (half_x, half_y, half_z), faces


def _segments(radius: float, tolerance: float) -> tuple[int, float]:
    """
    Return (segments, scale) for a polygon whose error about a circle is +-tolerance.

    With vertices at ``scale * radius`` the vertices overshoot and the edge midpoints
    undershoot the circle by the same amount, radius * (1 - c) / (1 + c) with c = cos(pi / n).
    """
    ratio = min(tolerance / radius, 0.5)
    cos_half_step = (1.0 - ratio) / (1.0 + ratio)
    segments = math.ceil(math.pi / math.acos(cos_half_step))
    segments = min(max(segments, 8), MAX_MESH_SEGMENTS)
    return segments, 2.0 / (1.0 + math.cos(math.pi / segments))


def _cylinder_mesh(radius: float, length: float, tolerance: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    segments, scale = _segments(radius, tolerance)
    angles = 2.0 * math.pi * np.arange(segments) / segments
    ring = np.column_stack((np.cos(angles), np.sin(angles))) * (scale * radius)
    half = 0.5 * length
    vertices = np.vstack((np.column_stack((ring, np.full(segments, -half))),
                          np.column_stack((ring, np.full(segments, half))),
                          [[0.0, 0.0, -half], [0.0, 0.0, half]]))
    low = np.arange(segments)
    next_low = (low + 1) % segments
    high = low + segments
    next_high = next_low + segments
    bottom_centre = np.full(segments, 2 * segments)
    top_centre = bottom_centre + 1
    faces = np.vstack((np.column_stack((low, next_low, next_high)),
                       np.column_stack((low, next_high, high)),
                       np.column_stack((bottom_centre, next_low, low)),
                       np.column_stack((top_centre, high, next_high))))
    return vertices, faces


def _sphere_mesh(radius: float, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    # A latitude-longitude sphere with equal polar and azimuth steps: a face centre undershoots
    # by about radius * (1 - cos(step / 2) ** 2); the vertices are pushed out to centre the
    # error on the true surface.
    ratio = min(tolerance / radius, 0.5)
    step = 2.0 * math.acos(math.sqrt((1.0 - ratio) / (1.0 + ratio)))
    rings = min(max(math.ceil(math.pi / step), 4), MAX_MESH_SEGMENTS // 2)
    step = math.pi / rings
    squared_cos = math.cos(0.5 * step) ** 2
    polar = step * np.arange(1, rings)[:, None]
    azimuth = step * np.arange(2 * rings)[None, :]
    grid = np.stack((np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth),
                     np.cos(polar) + 0.0 * azimuth), axis=-1)
    vertices = np.vstack(([[0.0, 0.0, 1.0]], grid.reshape(-1, 3), [[0.0, 0.0, -1.0]]))
    vertices *= 2.0 * radius / (1.0 + squared_cos)
    around = 2 * rings
    column = np.arange(around)
    following = (column + 1) % around
    north = np.zeros(around, dtype=int)
    south = np.full(around, len(vertices) - 1)
    last_row = 1 + (rings - 2) * around
    faces = [np.column_stack((north, 1 + column, 1 + following)),
             np.column_stack((south, last_row + following, last_row + column))]
    for row in range(rings - 2):
        upper = 1 + row * around
        lower = upper + around
        faces.append(np.column_stack((upper + column, lower + column, lower + following)))
        faces.append(np.column_stack((upper + column, lower + following, upper + following)))
    return vertices, np.vstack(faces)


def slice_footprints(shape: Shape, low: float, high: float) -> tuple[Footprint, ...]:
    """
    Return the vertical projection of the part of ``shape`` between heights low and high (m).

    Empty when the shape lies wholly below or above the band (touching it does not count).
    An upright box or cylinder crossing the band projects to its whole footprint, an upright
    sphere to the circle of its widest section in the band: exact, and as fast as before.
    Any other shape is triangulated (within :data:`MESH_TOLERANCE`) and sliced by
    :func:`slice_polygon`: one polygon footprint per separate part (a table's legs).
    """
    bottom, top = shape.z_range()
    if top <= low or bottom >= high:
        return ()
    if shape.upright and shape.kind in ('box', 'cylinder'):
        return (shape.footprint(),)
    if shape.upright and shape.kind == 'sphere':
        offset = shape.z - min(max(shape.z, low), high)
        return (Footprint('circle', shape.x, shape.y,
                          radius=math.sqrt(max(shape.radius ** 2 - offset ** 2, 0.0))),)
    return tuple(Footprint.from_polygon(part)
                 for part in shapely.get_parts(slice_polygon(shape, low, high))
                 if not part.is_empty)


def slice_polygon(shape: Shape, low: float, high: float) -> BaseGeometry:
    """
    Return the vertical projection of the part of ``shape`` between low and high (m), in m.

    A primitive is convex, so its slice is the convex hull of its triangles' corners clipped
    to the band. A mesh's is :func:`~.mesh_slice.mesh_slice`: its clipped faces, those
    standing on edge included, and the area it encloses. An empty geometry when nothing is in
    the band. Kept for the next equal shape and band (a run loads its world more than once;
    meshes compare as the same file at the same scale, see meshes.load_mesh).
    """
    try:
        hash(shape)
    except TypeError:  # a field given as a list: sliced, not kept
        return _slice_polygon(shape, low, high)
    return _kept_slice_polygon(shape, low, high)


def _slice_polygon(shape: Shape, low: float, high: float) -> BaseGeometry:
    mesh = shape.world_mesh()
    if shape.kind == 'mesh':
        return mesh_slice(mesh, low, high)
    pieces = clip_triangles(mesh.triangles, low, high)
    if not pieces:
        return shapely.Polygon()
    return shapely.MultiPoint(np.vstack(pieces)[:, :2]).convex_hull


_kept_slice_polygon = lru_cache(maxsize=1024)(_slice_polygon)
