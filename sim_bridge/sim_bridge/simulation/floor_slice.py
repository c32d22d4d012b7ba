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
(m): analytic between a circle and footprints; shapely for a polygon robot, after a cheap test
of its circumscribed circle, which settles every pose with nothing near.
"""

from collections.abc import Sequence
import math

import numpy as np
import shapely
from sim_bridge.simulation.geometry import Footprint, FootprintSet, Shape, slice_footprints

#: Height (m) above the floor where the robot's band starts: the floor and anything flatter
#: than this (a ground plane, a mat, a cable cover) is driven over, never bumped into.
FLOOR_CLEARANCE = 0.005


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
            corners = shapely.get_coordinates(self.robot_polygon)
            self.robot_radius = float(np.hypot(corners[:, 0], corners[:, 1]).max())
            self.inscribed_radius = float(
                shapely.maximum_inscribed_circle(self.robot_polygon).length)
            # What the robot's outline is measured against: circles as their centre less
            # the radius (exact), everything else as its shapely outline.
            self._geometries = np.array(
                [shapely.Point(fp.x, fp.y) if fp.kind == 'circle' else fp.geometry()
                 for fp in self.footprints], dtype=object)
            self._offsets = np.array([fp.radius if fp.kind == 'circle' else 0.0
                                      for fp in self.footprints])
            shapely.prepare(self._geometries)
            # With its origin inside its outline, the robot is nearest to a footprint no
            # farther from its origin than the nearest one plus its radius (see _polygon_gap).
            self._origin_inside = bool(shapely.contains_xy(self.robot_polygon, 0.0, 0.0))

    def probe(self, pose: tuple[float, float, float]) -> tuple[float, int, bool]:
        """
        Return (gap m, index of the nearest footprint, clear) for the robot at ``pose``.

        ``pose`` is (x m, y m, yaw rad). The gap is exact for a round robot and for a polygon
        robot near an obstacle; a polygon robot with nothing within its circumscribed circle
        gets that circle's gap, a lower bound (see :meth:`clearance` for the exact one).
        ``clear`` is False when the robot overlaps an obstacle (a polygon robot: or touches it;
        shapely's distance is 0 for both). The index is -1 in an empty world.
        """
        centre, index = self.obstacles.nearest(pose[0], pose[1])
        gap = centre - self.robot_radius
        if self.round:
            return gap, index, gap >= 0.0
        if gap > 0.0:
            return gap, index, True
        gap, index = self._polygon_gap(pose)
        return gap, index, gap > 0.0

    def clearance(self, pose: tuple[float, float, float]) -> tuple[float, int]:
        """Return the exact (gap m, nearest footprint's index) of the robot at ``pose``."""
        if self.round:
            centre, index = self.obstacles.nearest(pose[0], pose[1])
            return centre - self.robot_radius, index
        return self._polygon_gap(pose)

    def _polygon_gap(self, pose: tuple[float, float, float]) -> tuple[float, int]:
        if not len(self._geometries):
            return math.inf, -1
        candidates = np.arange(len(self._geometries))
        if self._origin_inside:
            # A footprint's gap lies between its distance from the robot's origin less the
            # robot's radius and that distance (the origin is part of the robot): only those
            # whose lower bound is below the least upper bound can be nearest.
            from_origin = shapely.distance(self._geometries,
                                           shapely.Point(pose[0], pose[1])) - self._offsets
            candidates = np.flatnonzero(from_origin - self.robot_radius <= from_origin.min())
        gaps = (shapely.distance(self.robot_at(pose), self._geometries[candidates])
                - self._offsets[candidates])
        best = int(np.argmin(gaps))
        return float(gaps[best]), int(candidates[best])

    def robot_at(self, pose: tuple[float, float, float]) -> shapely.Geometry:
        """Return the robot's outline (shapely, m) at ``pose`` (x m, y m, yaw rad)."""
        x, y, yaw = pose
        if self.round:
            return shapely.Point(x, y).buffer(self.robot_radius, 32)
        cos_yaw = math.cos(yaw)
        sin_yaw = math.sin(yaw)
        rotation = np.array([[cos_yaw, sin_yaw], [-sin_yaw, cos_yaw]])
        return shapely.transform(self.robot_polygon, lambda xy: xy @ rotation + (x, y))

    def robot_outlines(self, pose: tuple[float, float, float]) -> list[np.ndarray]:
        """Return the robot's outer rings at ``pose`` (x m, y m, yaw rad), each (K, 2) m."""
        return [np.asarray(part.exterior.coords)
                for part in shapely.get_parts(self.robot_at(pose))]
