"""
What a robot driving on the floor can hit: the 3-D world sliced through the robot's height band.

The band runs from the lowest to the highest point of the robot's collision shapes (wheels,
casters, body: every link's), its bottom raised to :data:`FLOOR_CLEARANCE` so that the floor,
a ground-plane shape lying on it or a mat flatter than that is never an obstacle. Each
obstacle shape counts with the vertical projection of its part inside the band
(:func:`~.geometry.slice_footprints`): a table whose top is above the robot is its legs, a
cone the part of it the robot's height reaches. Upright boxes, cylinders and spheres keep
exact circles and rectangles, so the lab's worlds cost what they did.

The robot's own outline is the projection of its collision shapes in that band: a circle
when they all are circles about its origin (the lab robot: exact and fast), else a shapely
polygon turned and moved to the robot's pose (a Waffle is a rectangle with wheels, and fits
through gaps its circumscribed circle would not). Gaps between the outlines are 2-D distances
(m): analytic between a circle and footprints; shapely for a polygon robot, measured only to
the footprints that can be the nearest. Those are picked from the footprints' distances to the
robot's origin, with :data:`CANDIDATE_MARGIN` to spare, and kept while the origin stays within
that margin of where they were picked: the robot moves about a millimetre per physics step, so
a step costs one shapely distance call against a few footprints.
"""

from collections.abc import Sequence
import math

import numpy as np
import shapely
from sim_bridge.simulation.geometry import Footprint, FootprintSet, Shape, slice_footprints

#: Height (m) above the floor where the robot's band starts: the floor and anything flatter
#: than this (a ground plane, a mat, a cable cover) is driven over, never bumped into.
FLOOR_CLEARANCE = 0.005
#: How far (m) a polygon robot's origin may move from where the footprints that can be its
#: nearest were picked before they are picked again (see FloorSlice._candidates).
CANDIDATE_MARGIN = 0.05
#: Side (m) of the tiles a polygon robot's gap to a large footprint is measured in.
TILE_SIZE = 0.5


def height_band(shapes: Sequence[Shape]) -> tuple[float, float]:
    """Return the (low, high) heights (m) a robot of these collision shapes can bump into."""
    bottoms, tops = zip(*(shape.z_range() for shape in shapes))
    low = max(min(bottoms), FLOOR_CLEARANCE)
    return low, max(max(tops), low)


class FloorSlice:
    """
    The world in 2-D for one robot: obstacle footprints in its band and its own outline.

    ``robot_shapes`` are the robot's collision shapes in its base frame (origin on the floor);
    ``obstacles`` pairs each obstacle's name with its shapes in the world frame.
    ``footprints`` and ``owners`` list the slice's outlines and, for each, its obstacle's name;
    ``band`` is (low, high) in m; ``robot_radius`` (m) the radius of the robot outline's
    circumscribed circle about its origin; ``round`` whether the outline is that circle.
    """

    def __init__(self, robot_shapes: Sequence[Shape],
                 obstacles: Sequence[tuple[str, Sequence[Shape]]]) -> None:
        if not robot_shapes:
            raise ValueError('the robot has no collision shape to give it an outline')
        self.band = height_band(robot_shapes)
        pieces = [(name, footprint) for name, shapes in obstacles for shape in shapes
                  for footprint in slice_footprints(shape, *self.band)]
        self.footprints: tuple[Footprint, ...] = tuple(footprint for _, footprint in pieces)
        self.owners: tuple[str, ...] = tuple(name for name, _ in pieces)
        self.obstacles = FootprintSet(self.footprints)
        outline = [footprint for shape in robot_shapes
                   for footprint in slice_footprints(shape, *self.band)]
        if not outline:
            raise ValueError(f'the robot has no collision shape higher than {FLOOR_CLEARANCE} m '
                             'above the floor to bump into anything with')
        self.round = all(footprint.kind == 'circle' and footprint.x == 0.0
                         and footprint.y == 0.0 for footprint in outline)
        if self.round:
            self.robot_polygon = None
            self.robot_radius = max(footprint.radius for footprint in outline)
            #: Radius (m) of the largest circle inside the robot's outline.
            self.inscribed_radius = self.robot_radius
        else:
            self.robot_polygon = shapely.union_all([fp.geometry() for fp in outline])
            self._gaps = OutlineGaps(self.robot_polygon, self.footprints)
            self.robot_radius = self._gaps.robot_radius
            self.inscribed_radius = float(
                shapely.maximum_inscribed_circle(self.robot_polygon).length)

    def probe(self, pose: tuple[float, float, float]) -> tuple[float, int, bool]:
        """
        Return (gap m, index of the nearest footprint, clear) for the robot at ``pose``.

        ``pose`` is (x m, y m, yaw rad); the gap is exact (see :meth:`clearance`). ``clear``
        is False when the robot overlaps an obstacle (a polygon robot: or touches it; shapely's
        distance is 0 for both). The index is -1 in an empty world.
        """
        gap, index = self.clearance(pose)
        return gap, index, gap >= 0.0 if self.round else gap > 0.0

    def clearance(self, pose: tuple[float, float, float]) -> tuple[float, int]:
        """Return the exact (gap m, nearest footprint's index) of the robot at ``pose``."""
        if self.round:
            centre, index = self.obstacles.nearest(pose[0], pose[1])
            return centre - self.robot_radius, index
        return self._gaps.gap(pose)

    def robot_at(self, pose: tuple[float, float, float]) -> shapely.Geometry:
        """Return the robot's outline (shapely, m) at ``pose`` (x m, y m, yaw rad)."""
        if self.round:
            return shapely.Point(pose[0], pose[1]).buffer(self.robot_radius, 32)
        return self._gaps.outline_at(pose)

    def robot_outlines(self, pose: tuple[float, float, float]) -> list[np.ndarray]:
        """Return the robot's outer rings at ``pose`` (x m, y m, yaw rad), each (K, 2) m."""
        return [np.asarray(part.exterior.coords)
                for part in shapely.get_parts(self.robot_at(pose))]


class OutlineGaps:
    """
    The exact gap (m) between a polygon robot's outline and the nearest footprint, per pose.

    ``outline`` is the robot's shapely outline in its base frame (m); ``footprints`` the
    world's. What the outline is measured against: a circle as its centre less its radius
    (exact), any other footprint as its shapely outline cut into tiles of :data:`TILE_SIZE`
    (the footprint is their union: its gap is theirs, the least), so that a wall around the
    whole world costs what its few edges near the robot cost. Only the tiles that can be the
    nearest are measured (see :meth:`_candidates`).
    """

    def __init__(self, outline: shapely.Geometry, footprints: Sequence[Footprint]) -> None:
        self._corners = shapely.get_coordinates(outline)
        #: Radius (m) of the circle about the robot's origin holding its outline.
        self.robot_radius = float(np.hypot(self._corners[:, 0], self._corners[:, 1]).max())
        # The outline at a pose is made in this one-element array from its corners (m): turned
        # (kept for the last yaw, rad: a robot driving straight keeps its yaw), then moved by
        # the position written into _position (x, y m).
        self._posed = np.array([outline], dtype=object)
        self._turned_yaw: float | None = None
        self._turned = self._corners
        self._position = np.zeros(2)
        pieces = []  # (footprint index, shapely outline, offset m)
        for index, fp in enumerate(footprints):
            if fp.kind == 'circle':
                pieces.append((index, shapely.Point(fp.x, fp.y), fp.radius))
            else:
                pieces += [(index, tile, 0.0) for tile in tiles(fp.geometry())]
        self._owners = np.array([index for index, _, _ in pieces], dtype=int)
        self._geometries = np.array([geometry for _, geometry, _ in pieces], dtype=object)
        self._offsets = np.array([offset for _, _, offset in pieces], dtype=float)
        # With its origin inside its outline, the robot is nearest to a footprint no farther
        # from its origin than the nearest one plus its radius (see _candidates).
        self._origin_inside = bool(shapely.contains_xy(outline, 0.0, 0.0))
        # The pieces that can be nearest (owners, outlines, offsets), picked for an origin
        # within CANDIDATE_MARGIN of ``_picked_at`` (x m, y m).
        self._picked_at: tuple[float, float] | None = None
        self._picked = (self._owners, self._geometries, self._offsets)
        # The last pose measured and its (gap m, index): a step probes its end pose, then asks
        # for its clearance there.
        self._last: tuple[tuple[float, float, float], tuple[float, int]] | None = None

    def gap(self, pose: tuple[float, float, float]) -> tuple[float, int]:
        """Return (gap m, the nearest footprint's index) for the robot at ``pose``."""
        pose = tuple(pose)  # a list or an array compares as its values
        if self._last is not None and self._last[0] == pose:
            return self._last[1]
        result = (math.inf, -1)
        if len(self._geometries):
            owners, geometries, offsets = self._candidates(pose[0], pose[1])
            gaps = shapely.distance(self.outline_at(pose), geometries) - offsets
            best = int(gaps.argmin())
            result = (float(gaps[best]), int(owners[best]))
        self._last = (pose, result)
        return result

    def _candidates(self, x: float, y: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return the pieces that can be nearest to the robot at (x, y) (m): owners and outlines.

        And their offsets (m). A piece's gap lies between its distance from the robot's
        origin less the robot's radius and that distance (the origin is part of the robot):
        only those whose lower bound is below the least upper bound can be nearest. Both
        distances change by no more than the origin moves, so the pieces picked with twice
        CANDIDATE_MARGIN to spare hold while the origin stays within CANDIDATE_MARGIN of where
        they were picked. Any piece can be nearest to a robot whose origin is outside its
        outline.
        """
        if not self._origin_inside:
            return self._picked
        if self._picked_at is not None and \
                math.hypot(x - self._picked_at[0], y - self._picked_at[1]) <= CANDIDATE_MARGIN:
            return self._picked
        from_origin = shapely.distance(self._geometries, shapely.Point(x, y)) - self._offsets
        picked = np.flatnonzero(from_origin - self.robot_radius - 2.0 * CANDIDATE_MARGIN
                                <= from_origin.min())
        self._picked_at = (x, y)
        self._picked = (self._owners[picked], self._geometries[picked], self._offsets[picked])
        return self._picked

    def outline_at(self, pose: tuple[float, float, float]) -> shapely.Geometry:
        """Return the robot's outline (shapely, m) at ``pose`` (x m, y m, yaw rad)."""
        x, y, yaw = pose
        if yaw != self._turned_yaw:
            cos_yaw = math.cos(yaw)
            sin_yaw = math.sin(yaw)
            self._turned = self._corners @ np.array([[cos_yaw, sin_yaw], [-sin_yaw, cos_yaw]])
            self._turned_yaw = yaw
        self._position[0] = x
        self._position[1] = y
        # A new geometry in the array each time: one returned before stays as it was.
        shapely.set_coordinates(self._posed, self._turned + self._position)
        return self._posed[0]


def tiles(geometry: shapely.Geometry, size: float = TILE_SIZE) -> list[shapely.Geometry]:
    """Return the non-empty parts of ``geometry`` in the cells of a grid of ``size`` (m)."""
    left, bottom, right, top = shapely.bounds(geometry)
    columns = max(1, math.ceil((right - left) / size))
    rows = max(1, math.ceil((top - bottom) / size))
    if columns == rows == 1:
        return [geometry]
    cells = [shapely.box(left + column * size, bottom + row * size,
                         left + (column + 1) * size, bottom + (row + 1) * size)
             for column in range(columns) for row in range(rows)]
    parts = shapely.intersection(geometry, cells)
    return list(parts[~shapely.is_empty(parts)])
