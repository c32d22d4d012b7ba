"""
Collision geometry of SDF models: each ``<collision>``'s ``<geometry>`` as a shape or the floor.

``<box>``, ``<cylinder>``, ``<sphere>``, ``<capsule>``, ``<ellipsoid>``, ``<cone>``,
``<polyline>`` (extruded) and ``<mesh>`` (:mod:`.meshes`, times ``<scale>``) become a
:class:`~.geometry.Shape` in the collision's own frame, with SDF's default sizes where a size is
left out; a ``<plane>`` is the floor; a ``<heightmap>`` is not simulated. Units: m.
"""

import xml.etree.ElementTree as ElementTree

import numpy as np
from sim_bridge.simulation.geometry import Mesh, Shape
from sim_bridge.simulation.meshes import cone, extrude, load_mesh, MeshError
from sim_bridge.simulation.sdf_lookup import ModelLookup

#: SDF's default radius (m) of a cylinder and a capsule when the file gives none.
SDF_DEFAULT_RADIUS = {'cylinder': 1.0, 'capsule': 0.5}
#: Collision shapes read but not simulated: terrain from an image. One ignored item each.
UNSIMULATED_GEOMETRY = ('heightmap', 'image')


class GeometryReading(ModelLookup):
    """The SDF reader's collision part: a ``<collision>``'s geometry as a shape or a plane."""

    def collision(self, element: ElementTree.Element, where: str
                  ) -> tuple[Shape | None, tuple[float, float] | None]:
        """Return (the shape in the collision's own frame, or a plane's size)."""
        geometry = element.find('geometry')
        kinds = ('<box>, <cylinder>, <sphere>, <capsule>, <ellipsoid>, <cone>, <mesh>, <plane>, '
                 '<polyline>')
        if geometry is None or not len(geometry) or (
                len(geometry) > 1 and {child.tag for child in geometry} != {'polyline'}):
            raise self.error(f'{where}/<geometry>', f'needs exactly one of {kinds}')
        primitive = geometry[0]
        at = f'{where}/<geometry>/<{primitive.tag}>'
        # Missing sizes take SDF's defaults, as Gazebo gives them.
        if primitive.tag == 'box':
            size = self.vector(primitive, 'size', at, 3) \
                if primitive.find('size') is not None else (1.0, 1.0, 1.0)
            if min(size) <= 0.0:
                raise self.error(f'{at}/<size>', f'must be positive, got {size}')
            return Shape('box', size=size), None
        if primitive.tag in ('cylinder', 'capsule'):
            radius = self.positive(primitive, 'radius', at, SDF_DEFAULT_RADIUS[primitive.tag])
            return Shape(primitive.tag, radius=radius,
                         length=self.positive(primitive, 'length', at, 1.0)), None
        if primitive.tag == 'cone':
            return Shape('mesh', mesh=cone(self.positive(primitive, 'radius', at, 1.0),
                                           self.positive(primitive, 'length', at, 1.0), at)
                         ), None
        if primitive.tag == 'sphere':
            return Shape('sphere', radius=self.positive(primitive, 'radius', at, 1.0)), None
        if primitive.tag == 'ellipsoid':
            radii = self.vector(primitive, 'radii', at, 3)
            if min(radii) <= 0.0:
                raise self.error(f'{at}/<radii>', f'must be positive, got {radii}')
            return Shape('ellipsoid', size=tuple(2.0 * radius for radius in radii)), None
        if primitive.tag == 'plane':
            return None, self.plane(primitive, at)
        if primitive.tag == 'mesh':
            return Shape('mesh', mesh=self.mesh(primitive, at)), None
        if primitive.tag == 'polyline':
            return Shape('mesh', mesh=self.polyline(geometry, at)), None
        if primitive.tag == 'empty':
            return None, None
        raise self.error(at, f'unsupported geometry <{primitive.tag}>; use one of {kinds} '
                         '(replace a heightmap with a mesh)')

    @staticmethod
    def unsupported_geometry(collision: ElementTree.Element) -> str:
        """Return '<heightmap>' (or another shape not simulated) for such a collision, or ''."""
        geometry = collision.find('geometry')
        if geometry is not None and len(geometry) and geometry[0].tag in UNSIMULATED_GEOMETRY:
            return f'<{geometry[0].tag}>'
        return ''

    def plane(self, element: ElementTree.Element, where: str) -> tuple[float, float]:
        normal = self.vector(element, 'normal', where, 3) \
            if element.find('normal') is not None else (0.0, 0.0, 1.0)
        if abs(normal[0]) > 1e-9 or abs(normal[1]) > 1e-9 or normal[2] <= 0.0:
            raise self.error(f'{where}/<normal>', f'only a horizontal plane (the floor, '
                             f'normal 0 0 1) is supported, got {normal}')
        if element.find('size') is None:
            return (1.0, 1.0)  # SDF's default plane size
        size = self.vector(element, 'size', where, 2)
        if min(size) <= 0.0:
            raise self.error(f'{where}/<size>', f'must be positive, got {size}')
        return size

    def mesh(self, element: ElementTree.Element, where: str) -> Mesh:
        uri = (element.findtext('uri') or '').strip()
        if not uri:
            raise self.error(f'{where}/<uri>', 'is missing; name the mesh file')
        scale = self.vector(element, 'scale', where, 3) \
            if element.find('scale') is not None else (1.0, 1.0, 1.0)
        if min(scale) <= 0.0:
            raise self.error(f'{where}/<scale>', f'must be positive, got {scale}')
        path = self.model_folder(uri, f'{where}/<uri>')
        try:
            return load_mesh(path, scale)
        except MeshError as error:
            raise self.error(f'{where}/<uri>', str(error)) from None

    def polyline(self, geometry: ElementTree.Element, where: str) -> Mesh:
        """Return the polylines of a geometry extruded upwards from z = 0 as one mesh."""
        parts = []
        for index, polyline in enumerate(geometry.findall('polyline')):
            at = f'{where}[{index}]'
            points = [self.numbers(point.text, f'{at}/<point>', 2)
                      for point in polyline.findall('point')]
            try:
                parts.append(extrude(points, self.positive(polyline, 'height', at), at))
            except MeshError as error:
                raise self.error(f'{at}/<point>', str(error).removeprefix(f'{at}: ')) from None
        offsets = np.cumsum([0] + [len(part.vertices) for part in parts[:-1]])
        return Mesh(np.vstack([part.vertices for part in parts]),
                    np.vstack([part.faces + offset for part, offset in zip(parts, offsets)]),
                    f'{self.path} polyline')
