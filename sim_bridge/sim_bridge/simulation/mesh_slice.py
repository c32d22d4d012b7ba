"""
The floor outline of a triangle mesh between two heights: everything a lidar there can see.

A robot must be blocked by whatever its lidar sees at its height, and meshes as modellers ship
them are rarely tidy: open (a wall that is one sheet of triangles, a house without a floor),
unmerged (every triangle with its own corners, so no two share an edge), or closed only up to
small cracks. :func:`mesh_slice` therefore builds the outline from three parts, none of which
needs the mesh to be closed:

- every triangle clipped to the band and projected on the floor (slanted and flat faces);
- every face standing on edge (its projection a line, or a sliver thinner than
  :data:`WALL_HALF_WIDTH` each side) as that line widened by :data:`WALL_HALF_WIDTH` each
  side: a vertical wall blocks as its lidar return says;
- the area the mesh encloses at the band's limits (:func:`enclosed_area`): the regions the
  section's lines close off, kept where a level ray from inside crosses the section an odd
  number of times (a pipe's bore stays open, a cube's inside is solid, a crack does not
  leak).

shapely unites the parts on a :data:`SLICE_GRID` precision grid: GEOS's snap-rounding overlay
is robust against the near-degenerate slivers of dense meshes (the plain overlay raised a
TopologyException on some). Units: m.
"""

import math

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry
import trimesh
from trimesh.intersections import mesh_plane

#: Half the width (m) given to a face standing on edge: lidar returns from it are at most
#: this much inside the blocking outline.
WALL_HALF_WIDTH = 5e-4
#: Precision grid (m) of the union of a slice's parts.
SLICE_GRID = 1e-6
#: Level directions (x, y) in which :func:`enclosed_area` counts section crossings; the
#: majority decides, so one ray slipping through a crack does not flip a region.
PARITY_DIRECTIONS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0))


def mesh_slice(mesh: trimesh.Trimesh, low: float, high: float) -> BaseGeometry:
    """
    Return the vertical projection (m) of the part of ``mesh`` between heights low and high.

    ``mesh`` is in the world frame (m); low and high may be infinite. An empty polygon when
    nothing of the mesh is in the band.
    """
    pieces = clip_triangles(mesh.triangles, low, high)
    if not pieces:
        return shapely.Polygon()
    by_corners: dict[int, list[np.ndarray]] = {}
    for piece in pieces:
        by_corners.setdefault(len(piece), []).append(piece[:, :2])
    parts = []
    for outlines in by_corners.values():
        parts += _projected_faces(np.array(outlines))
    parts += [enclosed_area(mesh, height) for height in (low, high) if math.isfinite(height)]
    return shapely.union_all(parts, grid_size=SLICE_GRID)


def _projected_faces(outlines: np.ndarray) -> list[BaseGeometry]:
    """
    Return (M, K, 2) projected convex faces (m) as shapely geometries to unite.

    A face with some width is its polygon; the faces standing on edge are one geometry, their
    outlines widened by :data:`WALL_HALF_WIDTH` each side.
    """
    x, y = outlines[..., 0], outlines[..., 1]
    areas = 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - y * np.roll(x, -1, axis=1),
                                axis=1))
    longest = np.linalg.norm(outlines - np.roll(outlines, 1, axis=1), axis=2).max(axis=1)
    wide = areas > WALL_HALF_WIDTH * longest
    geometries = list(shapely.polygons(outlines[wide]))
    on_edge = outlines[~wide & (longest > 0.0)]
    if len(on_edge):
        # Each widened on its own: GEOS's buffer of one multi-line of thousands is far slower
        # than small buffers united with the rest.
        rings = shapely.linestrings(np.concatenate((on_edge, on_edge[:, :1]), axis=1))
        geometries += list(shapely.buffer(rings, WALL_HALF_WIDTH, quad_segs=2))
    return geometries


def enclosed_area(mesh: trimesh.Trimesh, height: float) -> BaseGeometry:
    """
    Return the area (m) the mesh encloses at ``height`` (m), an empty polygon when none.

    The section's segments, widened by :data:`WALL_HALF_WIDTH` so that cracks close, split
    the plane into regions; a region is inside when level rays from it cross the section an
    odd number of times (even-odd, by majority over :data:`PARITY_DIRECTIONS`).
    """
    segments = mesh_plane(mesh, (0.0, 0.0, 1.0), (0.0, 0.0, height))
    if not len(segments):
        return shapely.Polygon()
    segments = np.asarray(segments)[:, :, :2]
    lines = shapely.union_all(shapely.buffer(shapely.linestrings(segments), WALL_HALF_WIDTH,
                                             quad_segs=2))
    # The faces of the widened lines' rings: the lines themselves and the regions they
    # close off (nested ones apart: a pipe's wall and its bore).
    faces = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.boundary(lines))))
    points = shapely.point_on_surface(faces)
    inside = [face for face, point in zip(faces, points)
              if not shapely.contains(lines, point)
              and _odd_crossings(segments, shapely.get_coordinates(point)[0])]
    return shapely.union_all(inside) if inside else shapely.Polygon()


def _odd_crossings(segments: np.ndarray, point: np.ndarray) -> bool:
    """
    Return True when most level rays from ``point`` cross the (N, 2, 2) segments oddly (m).

    Crossings closer together than :data:`WALL_HALF_WIDTH` count once.
    """
    odd = 0
    for direction in PARITY_DIRECTIONS:
        # Turn the frame so that the ray runs along +x from the point.
        cos_turn, sin_turn = direction
        relative = segments - point
        along = relative[..., 0] * cos_turn + relative[..., 1] * sin_turn
        across = relative[..., 1] * cos_turn - relative[..., 0] * sin_turn
        start, end = across[:, 0], across[:, 1]
        straddles = (start > 0.0) != (end > 0.0)
        with np.errstate(divide='ignore', invalid='ignore'):
            where = along[:, 0] + (along[:, 1] - along[:, 0]) * (-start / (end - start))
        crossings = np.sort(where[straddles & (where > 0.0)])
        # Coincident faces (a double-sided sheet, a face repeated) cross once.
        distinct = np.count_nonzero(np.diff(crossings) > WALL_HALF_WIDTH) + len(crossings[:1])
        odd += int(distinct) % 2
    return 2 * odd > len(PARITY_DIRECTIONS)


def clip_triangles(triangles: np.ndarray, low: float, high: float) -> list[np.ndarray]:
    """
    Return the parts of (N, 3, 3) triangles (m) between heights low and high (m).

    Each part is a (K, 3) convex polygon. Triangles wholly inside are kept as they are,
    those wholly outside dropped; only the few crossing a limit are clipped (Sutherland-Hodgman
    against each plane).
    """
    heights = triangles[:, :, 2]
    inside = (heights.min(axis=1) >= low) & (heights.max(axis=1) <= high)
    crossing = ~inside & (heights.max(axis=1) > low) & (heights.min(axis=1) < high)
    pieces = list(triangles[inside])
    for triangle in triangles[crossing]:
        polygon = list(triangle)
        for limit, side in ((low, 1.0), (high, -1.0)):
            polygon = _clip_polygon(polygon, limit, side)
        if len(polygon) >= 3:
            pieces.append(np.array(polygon))
    return pieces


def _clip_polygon(polygon: list, limit: float, side: float) -> list:
    """Return the part of a convex 3-D polygon where side * (z - limit) >= 0 (m)."""
    if not math.isfinite(limit):
        return polygon
    kept = []
    for start, end in zip(polygon, polygon[1:] + polygon[:1]):
        start_over = side * (start[2] - limit)
        end_over = side * (end[2] - limit)
        if start_over >= 0.0:
            kept.append(start)
        if (start_over >= 0.0) != (end_over >= 0.0):
            kept.append(start + (end - start) * (start_over / (start_over - end_over)))
    return kept
