"""
Triangle meshes of a model: the files ``<mesh>`` names (STL, OBJ, COLLADA) and extrusions.

trimesh reads every format (DAE through pycollada). A COLLADA file carries its own length unit
(``<asset><unit meter="0.0254"/>`` for a file drawn in inches) and Gazebo scales the mesh by
it; trimesh's plain load does not, so :func:`load_mesh` applies it from pycollada's reading of
the asset. The SDF ``<scale>`` is applied on top. Only the triangles matter here: what trimesh
warns about while reading (a texture image missing or unreadable) is kept in the mesh's
``notes`` for the one ``ignored:`` line, never printed as a traceback. A file is read once
per process and kept
(worlds repeat the same mesh many times). :func:`extrude` builds the prism of an SDF
``<polyline>`` (shapely triangulates the outline).
"""

from functools import lru_cache
import logging
from pathlib import Path

import numpy as np
from sim_bridge.simulation.geometry import Mesh

#: File suffixes trimesh reads here (lower case).
MESH_SUFFIXES = ('.stl', '.obj', '.dae')


class MeshError(ValueError):
    """A mesh file that cannot be read; the message names the file and why."""


def load_mesh(path: Path, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> Mesh:
    """
    Return the mesh in file ``path`` in metres, times ``scale``, as one triangle mesh.

    The file's scene graph (node transforms) is flattened; a DAE's ``<unit>`` is applied.
    Raises :class:`MeshError` for a format not read here or a file with no triangles. The
    same file at the same scale is the same (read-only) Mesh each time, so what is worked
    out from it once (its slices, see geometry.slice_polygon) holds for every world using it.
    """
    return _scaled(Path(path).resolve(), str(path), tuple(float(value) for value in scale))


@lru_cache(maxsize=256)
def _scaled(path: Path, source: str, scale: tuple[float, float, float]) -> Mesh:
    vertices, faces, notes = _read(path)
    vertices = vertices * np.asarray(scale, dtype=float)
    vertices.setflags(write=False)
    return Mesh(vertices, faces, source, notes)


class _Warnings(logging.Handler):
    """Collects the messages trimesh logs at WARNING and above while it reads one file."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def _load_quietly(path: Path):
    """Return trimesh's mesh of ``path`` and the warnings it logged (texture problems)."""
    import trimesh  # imported on first use: a world of primitives never pays for it
    logger = logging.getLogger('trimesh')
    collected = _Warnings()
    propagate = logger.propagate
    logger.addHandler(collected)
    logger.propagate = False
    try:
        return trimesh.load(str(path), force='mesh'), tuple(dict.fromkeys(collected.messages))
    finally:
        logger.removeHandler(collected)
        logger.propagate = propagate


@lru_cache(maxsize=256)
def _read(path: Path) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise MeshError(f'{path}: unsupported mesh format {suffix!r}; use one of '
                        f"{', '.join(MESH_SUFFIXES)}")
    if not path.is_file():
        raise MeshError(f'{path}: mesh file not found; check the <uri> (model://NAME/... is '
                        'looked up on GZ_SIM_RESOURCE_PATH)')
    try:
        mesh, notes = _load_quietly(path)
    except Exception as error:  # trimesh and pycollada raise many kinds on a broken file
        raise MeshError(f'{path}: cannot read the mesh: {error}') from None
    if len(getattr(mesh, 'faces', ())) == 0:
        raise MeshError(f'{path}: the mesh has no triangles')
    vertices = np.asarray(mesh.vertices, dtype=float)
    if suffix == '.dae':
        vertices = vertices * _collada_unit(path)
    vertices.setflags(write=False)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    faces.setflags(write=False)
    return vertices, faces, notes


def _collada_unit(path: Path) -> float:
    """Return the metres per unit a COLLADA file declares (1.0 when it declares none)."""
    import collada
    try:
        document = collada.Collada(str(path), ignore=[collada.common.DaeUnsupportedError,
                                                      collada.common.DaeBrokenRefError])
    except Exception as error:  # pycollada raises many kinds on a broken file
        raise MeshError(f'{path}: cannot read the COLLADA asset: {error}') from None
    unit = document.assetInfo.unitmeter
    return float(unit) if unit else 1.0


def cone(radius: float, length: float, source: str) -> Mesh:
    """Return SDF's ``<cone>``: its base circle (``radius`` m) ``length`` m below its apex."""
    import trimesh
    shape = trimesh.creation.cone(radius, length, sections=64)
    return Mesh(np.asarray(shape.vertices) - (0.0, 0.0, 0.5 * length),
                np.asarray(shape.faces, dtype=np.int64), source)


def extrude(points: list[tuple[float, float]], height: float, source: str) -> Mesh:
    """
    Return the prism of a simple polygon (x, y points in m) from z = 0 up to ``height`` (m).

    Raises :class:`MeshError` when the points do not outline a simple polygon of some area.
    """
    import shapely
    outline = shapely.Polygon(points) if len(points) >= 3 else None
    if outline is None or not outline.is_valid or outline.area <= 0.0:
        raise MeshError(f'{source}: need at least 3 points outlining a simple polygon')
    triangles = [np.asarray(triangle.exterior.coords)[:3]
                 for triangle in shapely.constrained_delaunay_triangles(outline).geoms]
    pieces = []
    for triangle in triangles:
        pieces.append(np.column_stack((triangle[::-1], np.zeros(3))))  # bottom, facing down
        pieces.append(np.column_stack((triangle, np.full(3, height))))  # top, facing up
    ring = np.asarray(outline.exterior.coords)
    for start, end in zip(ring[:-1], ring[1:]):
        low_start, low_end = (*start, 0.0), (*end, 0.0)
        high_start, high_end = (*start, height), (*end, height)
        pieces.append(np.array([low_start, low_end, high_end]))
        pieces.append(np.array([low_start, high_end, high_start]))
    vertices = np.vstack(pieces)
    return Mesh(vertices, np.arange(len(vertices)).reshape(-1, 3), source)
