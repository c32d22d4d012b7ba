"""
Read Gazebo model files as Gazebo reads them: collisions, the lidar and the diff-drive plugin.

:func:`load_model` reads a model folder (``model.config`` naming its SDF file) or an SDF file,
any SDF version (1.0 to 1.12), Gazebo Sim and Gazebo Classic forms alike, with :mod:`xml.etree`
(:mod:`.xml_text`: as leniently as Gazebo's TinyXML2, e.g. ``--`` in comments and undeclared
``gz:`` prefixes as Gazebo's own example worlds have them):

- every ``<collision>`` of every ``<link>``, at the link's and the collision's ``<pose>`` (any
  rotation; ``relative_to`` a link, a ``<frame>`` or the model), as a
  :class:`~.geometry.Shape`: ``<box>``, ``<cylinder>``, ``<sphere>``, ``<capsule>``,
  ``<ellipsoid>``, ``<cone>``, ``<polyline>`` (extruded) and ``<mesh>`` (STL, OBJ, DAE with
  its ``<unit>``, times ``<scale>``; :mod:`.meshes`), SDF's default sizes where a size is left
  out. A ``<plane>`` is the floor, not an obstacle (:attr:`Model.planes`); a ``<heightmap>`` is
  not simulated;
- nested ``<model>`` elements at their pose in the parent, and ``<include>`` elements, whose
  ``<pose>``, ``<name>`` and ``<static>`` replace the included model's own (Gazebo's rule);
  ``model://NAME/...`` is looked up on :func:`~sim_bridge.common.paths.model_search_path`;
- the lidar: the first ``gpu_lidar``/``lidar``/``gpu_ray``/``ray`` sensor with more than one
  horizontal sample (a one-beam range sensor is not a lidar), or the one named by the caller;
  its frame is Gazebo Sim's ``<gz_frame_id>``, Classic's ray plugin ``<frame_name>``, else the
  link's name; noise only when the SDF gives a ``<noise>``;
- the diff-drive plugin, Gazebo Sim's DiffDrive system or Classic's
  ``libgazebo_ros_diff_drive.so``, as a :class:`~.robot.DiffDriveConfig` with Gazebo's defaults
  for what it leaves unset.

What the simulator does not simulate (visuals, joints, lights, cameras, 3-D lidars, other
sensors and plugins, heightmaps, ``<submesh>``, textures) is listed in
:attr:`Model.not_simulated`, never dropped in silence; a model file holding only a
``<light>`` (Classic's ``sun`` folder) is a model of nothing but that light. What it cannot read
is an :class:`SdfError` naming the file, the element path and what to do.

A ``<pose>`` is ``x y z roll pitch yaw`` (m, rad; degrees with ``degrees="true"``), fixed axes
X-Y-Z, relative to the parent element unless ``relative_to`` says otherwise.

The reader's parts: :mod:`.sdf_values` (values, poses, errors), :mod:`.sdf_frames` (frames),
:mod:`.sdf_lookup` (model folders and URIs), :mod:`.sdf_geometry` (collisions),
:mod:`.sdf_lidar` (the lidar), :mod:`.sdf_drive` (the diff drive); :mod:`.sdf_model` holds
what it makes.
"""

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
import os
from pathlib import Path
import xml.etree.ElementTree as ElementTree

from sim_bridge.simulation.geometry import Shape
from sim_bridge.simulation.robot import DiffDriveConfig
from sim_bridge.simulation.sdf_drive import DriveReading, plugin_kind
from sim_bridge.simulation.sdf_frames import compose, Frames, place
from sim_bridge.simulation.sdf_geometry import GeometryReading
from sim_bridge.simulation.sdf_lidar import LIDAR_SENSOR_TYPES, LidarConfig, LidarReading
from sim_bridge.simulation.sdf_lookup import model_file
from sim_bridge.simulation.sdf_model import Ignored, Model, PlacedModel, Plane, SdfWorld
from sim_bridge.simulation.sdf_values import label, parse_sdf_xml, Pose6, SdfError, ZERO_POSE
from sim_bridge.simulation.urdf import is_urdf_file, urdf_to_sdf

#: The size (x, y in m) of the builtin stand-in for Gazebo's ground_plane model.
GROUND_PLANE_SIZE = (100.0, 100.0)
#: A static model whose collisions are all upright boxes at least this wide each way (m) and
#: whose tops are at most GROUND_TOP_M from z = 0 is the ground the robot stands on, not an
#: obstacle: gz-sim's sensor example worlds write their ``ground_plane`` as a 20 x 20 x 0.1 m
#: box centred on z = 0, so that its top is 0.05 m up.
GROUND_MIN_SIDE_M = 5.0
#: See GROUND_MIN_SIDE_M (m).
GROUND_TOP_M = 0.1


def load_model(folder_or_file: str | os.PathLike, lidar: str | None = None,
               world_folder: Path | None = None) -> Model:
    """
    Read a model folder (``model.config`` naming its SDF file), an SDF file, or a URDF robot.

    A ``.urdf`` or ``.xacro`` file is read by :mod:`.urdf`.

    ``lidar`` names the sensor to use when the model has several lidars (default: the first);
    ``world_folder`` is searched first for ``model://`` URIs (see
    :func:`~sim_bridge.common.paths.model_search_path`). Raises :class:`SdfError` for a file that
    cannot be used, FileNotFoundError for none.
    """
    path = model_file(Path(folder_or_file))
    if is_urdf_file(path):  # read as Gazebo reads it: converted to SDF
        return parse_model(urdf_to_sdf(path), path, lidar=lidar)
    return parse_model(path.read_text(encoding='utf-8'), path, lidar=lidar,
                       world_folder=world_folder)


def parse_model(text: str, path: Path, lidar: str | None = None,
                world_folder: Path | None = None) -> Model:
    """Read the first ``<model>`` of an SDF document ``text`` read from ``path``."""
    root = parse_sdf_xml(text, path)
    reader = _Reader(path, world_folder)
    if root.tag == 'model':
        element = root
    else:
        if root.tag != 'sdf':
            raise SdfError(f'{path}: <{root.tag}>: the root element must be <sdf>')
        element = root.find('model')
        light = root.find('light')
        if element is None and light is not None:  # a model folder holding a light: a sun
            return Model(light.get('name') or path.parent.name, path, (), static=True,
                         ignored=(('light', light.get('name') or ''),))
        if element is None:
            if root.find('world') is not None:
                raise SdfError(f'{path}: <sdf>: is a world file, not a model; load it as a '
                               'world')
            raise SdfError(f'{path}: <sdf>: has no <model> element')
    model = reader.top_model(element)
    return model.with_lidar(lidar) if lidar is not None else model


def parse_world(text: str, path: Path) -> SdfWorld:
    """Read the ``<world>`` of an SDF document ``text`` read from ``path``."""
    root = parse_sdf_xml(text, path)
    if root.tag != 'sdf' or root.find('world') is None:
        what = 'a model file' if root.find('model') is not None or root.tag == 'model' \
            else f'<{root.tag}>'
        raise SdfError(f'{path}: <{root.tag}>: is {what}, not an SDF world (<sdf><world>)')
    return _Reader(path, path.parent).world(root.find('world'))


def ground_of(placed: PlacedModel) -> Plane | None:
    """
    Return the floor a world's model is, at its top, or None for a model that is not ground.

    The ground is a static model whose collisions are all upright boxes at least
    :data:`GROUND_MIN_SIDE_M` wide each way, their tops within :data:`GROUND_TOP_M` of z = 0: a
    ground plane written as a slab. Its size is its widest box's (x, y in m).
    """
    if not placed.static or not placed.model.shapes or placed.model.lidar is not None:
        return None
    boxes = [place(shape, placed.pose) for shape in placed.model.shapes]
    if not all(box.kind == 'box' and box.upright and min(box.size[:2]) >= GROUND_MIN_SIDE_M
               and abs(box.z_range()[1]) <= GROUND_TOP_M for box in boxes):
        return None
    widest = max(boxes, key=lambda box: box.size[0] * box.size[1])
    return Plane(max(box.z_range()[1] for box in boxes), widest.size[:2])


def is_sdf_text(text: str) -> bool:
    """Return True when ``text`` looks like XML (an SDF file) rather than YAML."""
    return text.lstrip().startswith('<')


#: A diff-drive plugin read but for the model's name and canonical link, which name its
#: default topics and frames in Gazebo Sim.
DriveReader = Callable[[str, str], DiffDriveConfig]


@dataclass
class _Found:
    """What walking one top-level model (and everything nested in it) collected."""

    shapes: list[Shape] = field(default_factory=list)
    planes: list[Plane] = field(default_factory=list)
    #: (sensor name, a function reading its LidarConfig in the top model's frame)
    lidars: list[tuple[str, Callable[[], LidarConfig]]] = field(default_factory=list)
    drives: list[DriveReader] = field(default_factory=list)
    ignored: list[Ignored] = field(default_factory=list)
    sources: list[Path] = field(default_factory=list)
    joints: list[tuple[str, str, Pose6, Pose6]] = field(default_factory=list)


class _Reader(DriveReading, GeometryReading, LidarReading):
    """Walks one SDF file: its world, models, links, includes and joints."""

    # Worlds and models ---------------------------------------------------------------------

    def world(self, element: ElementTree.Element) -> SdfWorld:
        where = label(element)
        found = _Found(sources=[self.path])
        models: list[PlacedModel] = []
        step = None
        for child in element:
            child_where = f'{where}/{label(child)}'
            if child.tag == 'model':
                model = self.top_model(child)
                models.append(PlacedModel(model.name, model, model.pose, model.static))
            elif child.tag == 'include':
                models.append(self.world_include(child, child_where))
            elif child.tag == 'physics':
                if child.find('max_step_size') is not None:
                    step = self.number(child, 'max_step_size', child_where)
                    if step <= 0.0:
                        raise self.error(f'{child_where}/<max_step_size>', 'must be positive')
            elif child.tag == 'plugin':
                found.ignored.append(('plugin', child.get('filename') or child.get('name')))
            elif child.tag in ('light', 'actor', 'population', 'road', 'gui'):
                found.ignored.append((child.tag, ''))
        planes, kept = [], []
        for placed in models:
            found.sources += placed.model.sources
            ground = ground_of(placed)
            if ground is not None:
                planes.append(ground)
                continue
            for plane in placed.model.planes:
                planes.append(Plane(plane.z + placed.pose[2], plane.size))
            if placed.model.shapes or placed.model.lidar:
                kept.append(placed)
            else:  # a sun, a ground plane
                found.ignored += placed.model.not_simulated
        return SdfWorld(name=element.get('name') or self.path.stem, path=self.path,
                        models=tuple(kept), planes=tuple(planes), physics_step_s=step,
                        ignored=tuple(found.ignored),
                        sources=tuple(dict.fromkeys(found.sources)))

    def world_include(self, include: ElementTree.Element, where: str) -> PlacedModel:
        model = self.included_model(include, where)
        pose = self.pose(include, where) if include.find('pose') is not None else model.pose
        name = (include.findtext('name') or '').strip() or model.name
        static = self.boolean(include.find('static'), f'{where}/<static>', model.static)
        return PlacedModel(name, replace(model, name=name, static=static), pose, static)

    def included_model(self, include: ElementTree.Element, where: str) -> Model:
        """Return the model an ``<include>``'s ``<uri>`` names (its own pose kept apart)."""
        uri = (include.findtext('uri') or '').strip()
        if not uri:
            raise self.error(f'{where}/<uri>', 'is missing; name the model, e.g. model://NAME')
        builtin = self.builtin(uri)
        if builtin == 'ground_plane':
            return Model('ground_plane', self.path, (), static=True,
                         planes=(Plane(0.0, GROUND_PLANE_SIZE),))
        if builtin == 'sun':
            return Model('sun', self.path, (), static=True, ignored=(('light', ''),))
        folder = self.model_folder(uri, f'{where}/<uri>', include=True)
        try:
            return load_model(folder, world_folder=self.world_folder)
        except FileNotFoundError as error:
            raise self.error(f'{where}/<uri>', str(error)) from None

    def top_model(self, element: ElementTree.Element) -> Model:
        where = label(element)
        name = element.get('name')
        if not name:
            raise self.error(where, 'the model has no name attribute')
        found = _Found(sources=[self.path])
        self.model(element, where, ZERO_POSE, found)
        lidars = tuple((name, read()) for name, read in found.lidars)
        # The lidar: the first with more than one beam (a 1-beam "ray" is a range sensor).
        lidar = next((config for _, config in lidars if config.samples > 1), None)
        drive = None
        for config in found.drives:
            if drive is None:
                drive = config
            else:
                found.ignored.append(('plugin', 'a second diff drive'))
        if drive is not None:
            drive = drive(name, self.canonical_link(element))
        static = self.boolean(element.find('static'), f'{where}/<static>', default=False)
        return Model(name=name, path=self.path, shapes=tuple(found.shapes), lidar=lidar,
                     static=static, drive=drive, pose=self.pose(element, where),
                     planes=tuple(found.planes), ignored=tuple(found.ignored),
                     sources=tuple(dict.fromkeys(found.sources)), lidars=lidars,
                     joints=tuple(found.joints))

    @staticmethod
    def canonical_link(element: ElementTree.Element) -> str:
        link = element.find('link')
        return (link.get('name') or 'link') if link is not None else 'link'

    def model(self, element: ElementTree.Element, where: str, frame: Pose6,
              found: _Found) -> None:
        """Collect a model's contents, its frame at ``frame`` in the top model's frame."""
        frames = Frames(self, element, where)
        for child in element:
            child_where = f'{where}/{label(child)}'
            if child.tag == 'link':
                self.link(child, child_where, frame, frames, found)
            elif child.tag == 'model':
                self.model(child, child_where, compose(frame, frames.resolve(child, child_where)),
                           found)
            elif child.tag == 'include':
                self.nested_include(child, child_where, frame, frames, found)
            elif child.tag == 'plugin':
                kind = plugin_kind(child)
                if kind is None:
                    found.ignored.append(('plugin', child.get('filename') or child.get('name')))
                else:
                    found.drives.append(self.drive_reader(child, child_where, kind))
            elif child.tag == 'joint':
                found.ignored.append(('joint', ''))
                if frame == ZERO_POSE:  # the top model's own links: its frame tree
                    found.joints += self.joint_frames(child, frames)

    @staticmethod
    def joint_frames(joint: ElementTree.Element, frames: Frames
                     ) -> list[tuple[str, str, Pose6, Pose6]]:
        """Return [(parent, child, their poses in the model)] of a joint between two links."""
        parent = (joint.findtext('parent') or '').strip()
        child = (joint.findtext('child') or '').strip()
        links = {name for name, (element, _) in frames.elements.items() if element.tag == 'link'}
        if parent not in links or child not in links:
            return []
        return [(parent, child, frames.pose_of(parent), frames.pose_of(child))]

    def nested_include(self, include: ElementTree.Element, where: str, frame: Pose6,
                       frames: Frames, found: _Found) -> None:
        model = self.included_model(include, where)
        pose = frames.resolve(include, where) if include.find('pose') is not None \
            else model.pose
        placement = compose(frame, pose)
        found.shapes += [place(shape, placement) for shape in model.shapes]
        found.planes += [Plane(plane.z + placement[2], plane.size) for plane in model.planes]
        found.ignored += model.ignored
        found.sources += model.sources
        for name, config in model.lidars:
            found.lidars.append((name, partial(replace, config,
                                               pose=compose(placement, config.pose))))
        if model.drive is not None:
            found.drives.append(lambda _name, _link, drive=model.drive: drive)

    def link(self, link: ElementTree.Element, where: str, model_frame: Pose6,
             frames: Frames, found: _Found) -> None:
        for child in link:
            child_where = f'{where}/{label(child)}'
            if child.tag == 'collision':
                pose = compose(model_frame, frames.resolve(child, child_where, link=link))
                not_read = self.unsupported_geometry(child)
                if not_read:
                    found.ignored.append((f'{not_read} collision', child.get('name') or ''))
                    continue
                shape, plane = self.collision(child, child_where)
                if plane is not None:
                    found.planes.append(Plane(pose[2], plane))
                elif shape is not None:
                    found.shapes.append(place(shape, pose))
                    if shape.kind == 'mesh':
                        found.sources.append(Path(shape.mesh.source))
                        if shape.mesh.notes:
                            found.ignored.append(('mesh texture', Path(shape.mesh.source).name))
                if child.find('geometry/mesh/submesh') is not None:
                    found.ignored.append(('submesh (whole mesh used)', ''))
            elif child.tag == 'visual':
                found.ignored.append(('visual', ''))
            elif child.tag == 'sensor':
                pose = compose(model_frame, frames.resolve(child, child_where, link=link))
                if child.get('type') in LIDAR_SENSOR_TYPES and self.layers(child) > 1:
                    found.ignored.append(('3-D lidar', child.get('name') or ''))
                elif child.get('type') in LIDAR_SENSOR_TYPES:
                    found.lidars.append((child.get('name') or '', partial(
                        self.lidar, child, child_where, pose, link.get('name') or '')))
                else:
                    found.ignored.append(('sensor', f"{child.get('name')} "
                                                    f"({child.get('type')})"))
            elif child.tag == 'light':
                found.ignored.append(('light', ''))
