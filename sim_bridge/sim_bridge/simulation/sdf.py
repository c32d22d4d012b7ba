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
"""

from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from functools import cached_property, partial
import math
import os
from pathlib import Path
from urllib.parse import unquote, urlparse
import xml.etree.ElementTree as ElementTree

import numpy as np
from sim_bridge.common import paths
from sim_bridge.simulation.geometry import (
    euler_from_matrix, Footprint, Mesh, pose_matrix, rotation_matrix, Shape, triangulate)
from sim_bridge.simulation.meshes import cone, extrude, load_mesh, MeshError
from sim_bridge.simulation.robot import DiffDriveConfig
from sim_bridge.simulation.sdf_drive import DriveReading, NO_SPEED_LIMIT, plugin_kind  # noqa: F401
from sim_bridge.simulation.xml_text import parse_xml, XmlError

LIDAR_SENSOR_TYPES = ('ray', 'gpu_ray', 'lidar', 'gpu_lidar')
NOISE_TYPES = ('gaussian', 'none')
#: SDF's default radius (m) of a cylinder and a capsule when the file gives none.
SDF_DEFAULT_RADIUS = {'cylinder': 1.0, 'capsule': 0.5}
#: A model named by a bare file name with one of these suffixes is that file, not a folder.
MODEL_FILE_SUFFIXES = ('.sdf', '.urdf', '.xacro')
#: Collision shapes read but not simulated: terrain from an image. One ignored item each.
UNSIMULATED_GEOMETRY = ('heightmap', 'image')

Pose6 = tuple[float, float, float, float, float, float]
ZERO_POSE: Pose6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
#: An entry of an ignored list: (what, its name or '' when only counted).
Ignored = tuple[str, str]


class SdfError(ValueError):
    """A model file the simulator cannot use; the message names the file and the element."""


def compose(parent: Pose6, child: Pose6) -> Pose6:
    """Return the pose of ``child``, given in ``parent``'s frame, in parent's parent (m, rad)."""
    matrix = pose_matrix(*parent) @ pose_matrix(*child)
    return (float(matrix[0, 3]), float(matrix[1, 3]), float(matrix[2, 3]),
            *euler_from_matrix(matrix))


def relative_pose(parent: Pose6, child: Pose6) -> Pose6:
    """Return ``child`` (a pose in some frame) in the frame of ``parent`` (same frame)."""
    rotation = rotation_matrix(*parent[3:]).T
    position = rotation @ (np.asarray(child[:3]) - parent[:3])
    return (*map(float, position), *euler_from_matrix(rotation @ rotation_matrix(*child[3:])))


def place(shape: Shape, pose: Pose6) -> Shape:
    """Return ``shape``, given in a frame at ``pose`` (m, rad), in that frame's parent."""
    x, y, z, roll, pitch, yaw = pose
    return shape.placed(x, y, z, yaw, roll, pitch)


def describe_ignored(items: Iterable[Ignored]) -> str:
    """
    Return one line summing up ignored items, e.g. ``12 visuals, 2 lights, plugins a, b``.

    Items without a name are counted; named items are listed once each. '' for none.
    """
    items = list(items)
    counts = Counter(kind for kind, name in items if not name)
    named: dict[str, list[str]] = {}
    for kind, name in items:
        if name and name not in named.setdefault(kind, []):
            named[kind].append(name)
    parts = [f'{count} {kind}{"s" if count > 1 else ""}' for kind, count in counts.items()]
    parts += [f'{kind}{"s" if len(names) > 1 else ""} {", ".join(names)}'
              for kind, names in named.items()]
    return ', '.join(parts)


@dataclass(frozen=True)
class Plane:
    """A ``<plane>`` collision: the floor at height ``z`` (m), ``size`` (x, y in m)."""

    z: float
    size: tuple[float, float]


@dataclass(frozen=True)
class LidarConfig:
    """
    A planar lidar as a Gazebo ``<sensor>`` block describes it (defaults: the lab's, noiseless).

    ``samples`` beams (times the horizontal ``resolution``) spread evenly from ``min_angle`` to
    ``max_angle`` (rad, counter-clockwise from the laser's +x); readings from ``range_min`` to
    ``range_max`` (m); ``range_resolution`` (m) is reported, not applied (as in Gazebo);
    ``update_rate`` (Hz); Gaussian noise ``noise_mean``, ``noise_stddev`` (m). ``pose`` is the
    laser frame in the robot's base frame: x, y, z (m), roll, pitch, yaw (rad). ``frame_id``
    names the laser frame. The derived ``beams``, ``angle_increment``, ``last_angle`` and
    ``scan_period`` are worked out on first use and kept (the fields never change), as every
    scan reads them.
    """

    samples: int = 36
    resolution: float = 1.0
    min_angle: float = -1.57
    max_angle: float = 1.57
    range_min: float = 0.12
    range_max: float = 10.0
    range_resolution: float = 0.01
    update_rate: float = 10.0
    noise_mean: float = 0.0
    noise_stddev: float = 0.0
    pose: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    frame_id: str = 'laser'

    def __post_init__(self) -> None:
        problems = []
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) \
                or self.samples < 1:
            problems.append(f'samples must be a positive integer, got {self.samples!r}')
        numbers = ('resolution', 'min_angle', 'max_angle', 'range_min', 'range_max',
                   'range_resolution', 'update_rate', 'noise_mean', 'noise_stddev')
        for name in numbers:
            if not math.isfinite(getattr(self, name)):
                problems.append(f'{name} must be finite, got {getattr(self, name)!r}')
        if not problems:
            if self.resolution <= 0.0:
                problems.append(f'resolution must be positive, got {self.resolution}')
            if self.min_angle > self.max_angle:
                problems.append(f'min_angle {self.min_angle} is above max_angle '
                                f'{self.max_angle}')
            if not 0.0 <= self.range_min < self.range_max:
                problems.append(f'need 0 <= range_min < range_max, got {self.range_min} and '
                                f'{self.range_max}')
            if self.update_rate <= 0.0:
                problems.append(f'update_rate must be positive, got {self.update_rate}')
            if self.noise_stddev < 0.0:
                problems.append(f'noise_stddev must not be negative, got {self.noise_stddev}')
        if len(self.pose) != 6 or not all(math.isfinite(value) for value in self.pose):
            problems.append(f'pose must be 6 finite numbers, got {self.pose!r}')
        if problems:
            raise ValueError('invalid lidar: ' + '; '.join(problems))

    @cached_property
    def beams(self) -> int:
        """Return the number of readings per scan: samples times resolution, at least 1."""
        return max(1, round(self.samples * self.resolution))

    @cached_property
    def angle_increment(self) -> float:
        """Return the angle (rad) between beams: (max - min) / (beams - 1); 0 for one beam."""
        if self.beams == 1:
            return 0.0
        return (self.max_angle - self.min_angle) / (self.beams - 1)

    @cached_property
    def last_angle(self) -> float:
        """Return the angle (rad) of the last beam: max_angle, or min_angle for one beam."""
        return self.min_angle + self.angle_increment * (self.beams - 1)

    @cached_property
    def scan_period(self) -> float:
        """Return the time (s) between scans."""
        return 1.0 / self.update_rate


@dataclass(frozen=True)
class Model:
    """
    A model read from its SDF file: collision shapes in the model frame, maybe a lidar and a drive.

    ``shapes`` are every collision of every link (and nested model) in the model frame, whose
    origin is where the model is placed (on the floor, z = 0, for a robot); ``pose`` is the
    model's own ``<pose>``, used only where nothing places the model (an ``<include>``'s pose,
    a YAML entry's or a spawn pose replace it, as in Gazebo). ``planes`` are its ``<plane>``
    collisions (a ground plane: the floor). ``lidars`` are every lidar sensor read, by name,
    ``lidar`` the one used (see :meth:`with_lidar`). ``ignored`` lists what the simulator does
    not simulate but the unused lidars (:attr:`not_simulated` adds them; see
    :func:`describe_ignored`); ``sources`` the SDF and mesh files read.
    """

    name: str
    path: Path
    shapes: tuple[Shape, ...]
    lidar: LidarConfig | None = None
    static: bool = False
    #: The model's diff-drive plugin, None when it has none.
    drive: DiffDriveConfig | None = None
    pose: Pose6 = ZERO_POSE
    planes: tuple[Plane, ...] = ()
    ignored: tuple[Ignored, ...] = ()
    sources: tuple[Path, ...] = ()
    lidars: tuple[tuple[str, LidarConfig], ...] = ()
    #: (parent link, child link, the parent's pose, the child's pose; in the model frame, m
    #: and rad) of each joint between the top model's links, at joint position 0: the tree of
    #: frames robot_state_publisher sends as TF.
    joints: tuple[tuple[str, str, Pose6, Pose6], ...] = ()

    def with_lidar(self, name: str) -> 'Model':
        """Return this model using its lidar sensor called ``name``; SdfError when none is."""
        for sensor, config in self.lidars:
            if sensor == name:
                return replace(self, lidar=config)
        names = ', '.join(sensor for sensor, _ in self.lidars) or 'none'
        raise SdfError(f'{self.path}: <model name="{self.name}">: has no lidar sensor named '
                       f"'{name}' (lidars: {names})")

    @property
    def not_simulated(self) -> tuple[Ignored, ...]:
        """Return :attr:`ignored` and the lidars not used (a 1-beam one is a range sensor)."""
        unused = tuple(('sensor', f'{name} (1 beam lidar)' if config.samples == 1
                        else f'{name} (lidar not used)')
                       for name, config in self.lidars if config is not self.lidar)
        return self.ignored + unused

    @cached_property
    def footprints(self) -> tuple[Footprint, ...]:
        """Return the floor outlines of the shapes (upright primitives only, for now)."""
        return tuple(shape.footprint() for shape in self.shapes)

    @property
    def is_robot(self) -> bool:
        """Return True for a model Gazebo can drive and scan with: a diff drive and a lidar."""
        return self.drive is not None and self.lidar is not None

    @cached_property
    def radius(self) -> float:
        """Return the radius of the smallest circle about the origin holding the outline (m)."""
        radius = 0.0
        for shape in self.shapes:
            if shape.upright and shape.kind in ('box', 'cylinder', 'sphere'):
                footprint = shape.footprint()
                if footprint.kind == 'circle':
                    reach = math.hypot(footprint.x, footprint.y) + footprint.radius
                else:
                    reach = float(max(math.hypot(*corner) for corner in footprint.outline()))
            else:
                points = triangulate(shape)[0] @ shape.rotation().T + (shape.x, shape.y, 0.0)
                reach = float(np.hypot(points[:, 0], points[:, 1]).max())
            radius = max(radius, reach)
        return radius

    @property
    def height(self) -> float:
        """Return the height of the top of the highest collision shape (m)."""
        return max((shape.z_range()[1] for shape in self.shapes), default=0.0)


@dataclass(frozen=True)
class PlacedModel:
    """A model of a world at its ``pose`` (x, y, z m, roll, pitch, yaw rad) in the world."""

    name: str
    model: Model
    pose: Pose6
    static: bool


@dataclass(frozen=True)
class SdfWorld:
    """
    An SDF ``<world>``: its models where they stand, the floor and the physics step.

    ``planes`` are the ground planes in the world frame; ``physics_step_s`` is
    ``<physics><max_step_size>`` (s), None when unset; ``ignored`` what the world itself (not
    its models, see :attr:`Model.ignored`) has that is not simulated.
    """

    name: str
    path: Path
    models: tuple[PlacedModel, ...]
    planes: tuple[Plane, ...]
    physics_step_s: float | None
    ignored: tuple[Ignored, ...]
    sources: tuple[Path, ...]


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
    from sim_bridge.simulation import urdf  # it reads the SDF it makes with this module
    if urdf.is_urdf_file(path):
        return urdf.load_urdf(path, lidar)
    return parse_model(path.read_text(encoding='utf-8'), path, lidar=lidar,
                       world_folder=world_folder)


def model_file(path: Path) -> Path:
    """Return the SDF file of a model folder or file; FileNotFoundError when there is none."""
    if path.is_dir():
        path = path / sdf_file_name(path)
    if not path.is_file():
        raise FileNotFoundError(f'model file not found: {path}')
    return path


def sdf_file_name(folder: Path) -> str:
    """
    Return the SDF file a model folder's ``model.config`` names (newest version first).

    Gazebo's rule; ``model.sdf`` when there is no ``model.config``.
    """
    config = folder / 'model.config'
    if not config.is_file():
        return 'model.sdf'
    root = _parse_xml(config.read_text(encoding='utf-8'), config)
    candidates = []
    for element in root.iter('sdf'):
        version = element.get('version', '0')
        try:
            key = tuple(int(part) for part in version.split('.'))
        except ValueError:
            raise SdfError(f'{config}: <sdf version="{version}">: version must be like "1.6"')
        if not (element.text or '').strip():
            raise SdfError(f'{config}: <sdf version="{version}">: names no file')
        candidates.append((key, element.text.strip()))
    if not candidates:
        raise SdfError(f'{config}: <model>: has no <sdf> element naming the model file')
    return max(candidates)[1]


def parse_model(text: str, path: Path, lidar: str | None = None,
                world_folder: Path | None = None) -> Model:
    """Read the first ``<model>`` of an SDF document ``text`` read from ``path``."""
    root = _parse_xml(text, path)
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
    root = _parse_xml(text, path)
    if root.tag != 'sdf' or root.find('world') is None:
        what = 'a model file' if root.find('model') is not None or root.tag == 'model' \
            else f'<{root.tag}>'
        raise SdfError(f'{path}: <{root.tag}>: is {what}, not an SDF world (<sdf><world>)')
    return _Reader(path, path.parent).world(root.find('world'))


def is_sdf_text(text: str) -> bool:
    """Return True when ``text`` looks like XML (an SDF file) rather than YAML."""
    return text.lstrip().startswith('<')


def _parse_xml(text: str, path: Path) -> ElementTree.Element:
    try:
        return parse_xml(text, path)
    except XmlError as error:
        raise SdfError(str(error)) from None


def _label(element: ElementTree.Element) -> str:
    name = element.get('name')
    return f'<{element.tag} name="{name}">' if name is not None else f'<{element.tag}>'


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


#: Builtin stand-ins for the two models every Gazebo world includes, so they work offline.
_GROUND_PLANE_SIZE = (100.0, 100.0)
_FUEL_BUILTINS = {'ground plane': 'ground_plane', 'sun': 'sun'}


def _fuel_cache(uri) -> Path | None:
    """
    Return the newest downloaded copy of a Fuel model URI in Gazebo's cache, or None.

    ``https://fuel.gazebosim.org/1.0/OWNER/models/NAME[/VERSION]`` is kept by ``gz fuel
    download`` in ``~/.gz/fuel/fuel.gazebosim.org/owner/models/name/VERSION`` (owner and name
    in lower case; ``~/.ignition/fuel`` before Gazebo Garden, or ``GZ_FUEL_CACHE_PATH``).
    """
    parts = [unquote(part) for part in uri.path.strip('/').split('/')]
    if 'models' not in parts[1:-1]:
        return None
    index = parts.index('models')
    owner, name = parts[index - 1].lower(), parts[index + 1].lower()
    version = parts[index + 2] if len(parts) > index + 2 else ''
    roots = [Path(os.environ['GZ_FUEL_CACHE_PATH'])] if os.environ.get('GZ_FUEL_CACHE_PATH') \
        else []
    roots += [Path.home() / '.gz' / 'fuel', Path.home() / '.ignition' / 'fuel']
    for root in roots:
        folder = root / uri.netloc / owner / 'models' / name
        if version.isdigit() and (folder / version).is_dir():
            return folder / version
        versions = sorted((place for place in folder.glob('*') if place.name.isdigit()),
                          key=lambda place: int(place.name))
        if versions:
            return versions[-1]
    return None


class _Reader(DriveReading):
    """Walks one SDF file, keeping the file name for error messages."""

    def __init__(self, path: Path, world_folder: Path | None) -> None:
        self.path = path
        self.world_folder = world_folder

    def error(self, where: str, problem: str) -> SdfError:
        return SdfError(f'{self.path}: {where}: {problem}')

    # Worlds and models ---------------------------------------------------------------------

    def world(self, element: ElementTree.Element) -> SdfWorld:
        where = _label(element)
        found = _Found(sources=[self.path])
        models: list[PlacedModel] = []
        step = None
        for child in element:
            child_where = f'{where}/{_label(child)}'
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
        planes = []
        for placed in models:
            found.sources += placed.model.sources
            for plane in placed.model.planes:
                planes.append(Plane(plane.z + placed.pose[2], plane.size))
            if not placed.model.shapes and placed.model.lidar is None:  # a sun, a ground plane
                found.ignored += placed.model.not_simulated
        models = [placed for placed in models if placed.model.shapes or placed.model.lidar]
        return SdfWorld(name=element.get('name') or self.path.stem, path=self.path,
                        models=tuple(models), planes=tuple(planes), physics_step_s=step,
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
                         planes=(Plane(0.0, _GROUND_PLANE_SIZE),))
        if builtin == 'sun':
            return Model('sun', self.path, (), static=True, ignored=(('light', ''),))
        folder = self.model_folder(uri, f'{where}/<uri>')
        try:
            return load_model(folder, world_folder=self.world_folder)
        except FileNotFoundError as error:
            raise self.error(f'{where}/<uri>', str(error)) from None

    def builtin(self, uri: str) -> str | None:
        """Return 'ground_plane' or 'sun' for those URIs when no model folder provides them."""
        parsed = urlparse(uri)
        if parsed.scheme == 'model':
            name = parsed.netloc
            if name in ('ground_plane', 'sun') and not self.findable(name):
                return name
            return None
        if parsed.scheme in ('http', 'https'):
            name = unquote(parsed.path.rstrip('/').split('/models/')[-1].split('/')[0])
            return _FUEL_BUILTINS.get(name.lower())
        return None

    def findable(self, name: str) -> bool:
        try:
            paths.find_model(name, self.world_folder)
        except FileNotFoundError:
            return False
        return True

    def model_folder(self, uri: str, where: str) -> Path:
        """Return the model folder (or SDF file) a ``model://``, Fuel, file or path URI names."""
        parsed = urlparse(uri)
        if parsed.scheme == 'model':
            # model:///NAME/... (three slashes) names the same file as model://NAME/...
            name, _, rest = (parsed.netloc + parsed.path).lstrip('/').partition('/') \
                if not parsed.netloc else (parsed.netloc, '', parsed.path)
            try:
                folder = paths.find_model(name, self.world_folder)
            except FileNotFoundError as error:
                raise self.error(where, str(error)) from None
            return folder / unquote(rest.lstrip('/'))
        if parsed.scheme in ('http', 'https'):
            cached = _fuel_cache(parsed)
            if cached is not None:
                return cached
            raise self.error(where, f'{uri} is a Gazebo Fuel model, not available offline: '
                             f"download it (gz fuel download -u '{uri}') and put its model "
                             'folder on GZ_SIM_RESOURCE_PATH')
        return self.local_file(uri, where)

    def local_file(self, uri: str, where: str) -> Path:
        """Return the file a ``file://`` URI or a path names, relative to this file's folder."""
        parsed = urlparse(uri)
        if parsed.scheme not in ('', 'file'):
            raise self.error(where, f'unsupported URI {uri!r}; use model://NAME/..., a '
                             'file:// URI or a path relative to the SDF file')
        text = unquote(parsed.netloc + parsed.path) if parsed.scheme else uri
        path = Path(text)
        if path.is_absolute():
            return path
        candidates = [self.path.parent / path]
        candidates += [folder / path for folder in paths.model_search_path(self.world_folder)]
        return next((place for place in candidates if place.exists()), candidates[0])

    def top_model(self, element: ElementTree.Element) -> Model:
        where = _label(element)
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
        frames = _Frames(self, element, where)
        for child in element:
            child_where = f'{where}/{_label(child)}'
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
    def joint_frames(joint: ElementTree.Element, frames: '_Frames'
                     ) -> list[tuple[str, str, Pose6, Pose6]]:
        """Return [(parent, child, their poses in the model)] of a joint between two links."""
        parent = (joint.findtext('parent') or '').strip()
        child = (joint.findtext('child') or '').strip()
        links = {name for name, (element, _) in frames.elements.items() if element.tag == 'link'}
        if parent not in links or child not in links:
            return []
        return [(parent, child, frames.pose_of(parent), frames.pose_of(child))]

    def nested_include(self, include: ElementTree.Element, where: str, frame: Pose6,
                       frames: '_Frames', found: _Found) -> None:
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
             frames: '_Frames', found: _Found) -> None:
        for child in link:
            child_where = f'{where}/{_label(child)}'
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

    # Collisions ----------------------------------------------------------------------------

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

    # The lidar -----------------------------------------------------------------------------

    def lidar(self, sensor: ElementTree.Element, where: str, pose: Pose6,
              link_name: str) -> LidarConfig:
        values = {}
        blocks = [child for child in sensor if child.tag in ('lidar', 'ray')]
        if len(blocks) > 1:
            raise self.error(where, 'has both <lidar> and <ray>; keep one')
        if blocks:
            block_where = f'{where}/<{blocks[0].tag}>'
            values.update(self.horizontal(blocks[0].find('scan/horizontal'),
                                          f'{block_where}/<scan>/<horizontal>'))
            values.update(self.lidar_range(blocks[0].find('range'), f'{block_where}/<range>'))
            values.update(self.noise(blocks[0].find('noise'), f'{block_where}/<noise>'))
        values.update(self.children(sensor, where, {'update_rate': 'update_rate'}))
        if values.get('update_rate', 1.0) <= 0.0:
            raise self.error(f'{where}/<update_rate>', 'must be positive')
        values['pose'] = pose
        values['frame_id'] = self.frame_id(sensor, link_name)
        try:
            return LidarConfig(**values)
        except ValueError as error:
            raise self.error(where, str(error)) from None

    def horizontal(self, element: ElementTree.Element | None, where: str) -> dict:
        if element is None:
            return {}
        values = self.children(element, where, {'resolution': 'resolution',
                                                'min_angle': 'min_angle',
                                                'max_angle': 'max_angle'})
        if element.find('samples') is not None:
            values['samples'] = self.integer(element, 'samples', where)
        if values.get('resolution', 1.0) <= 0.0:
            raise self.error(f'{where}/<resolution>', 'must be positive')
        defaults = LidarConfig()
        if values.get('min_angle', defaults.min_angle) > values.get('max_angle',
                                                                    defaults.max_angle):
            raise self.error(f'{where}/<min_angle>', 'must not be above <max_angle>')
        return values

    @staticmethod
    def layers(sensor: ElementTree.Element) -> int:
        """Return a lidar sensor's vertical samples: 1 for a planar lidar."""
        text = (sensor.findtext('lidar/scan/vertical/samples')
                or sensor.findtext('ray/scan/vertical/samples') or '1').strip()
        return int(text) if text.isdigit() else 1

    def lidar_range(self, element: ElementTree.Element | None, where: str) -> dict:
        if element is None:
            return {}
        values = self.children(element, where, {'min': 'range_min', 'max': 'range_max',
                                                'resolution': 'range_resolution'})
        defaults = LidarConfig()
        low = values.get('range_min', defaults.range_min)
        high = values.get('range_max', defaults.range_max)
        if low < 0.0:
            raise self.error(f'{where}/<min>', f'must not be negative, got {low}')
        if high <= low:
            raise self.error(f'{where}/<max>', f'must be above <min> ({low}), got {high}')
        if values.get('range_resolution', 1.0) <= 0.0:
            raise self.error(f'{where}/<resolution>', 'must be positive')
        return values

    def noise(self, element: ElementTree.Element | None, where: str) -> dict:
        if element is None:
            return {}
        kind = (element.findtext('type') or element.get('type') or 'gaussian').strip()
        if kind not in NOISE_TYPES:
            raise self.error(f'{where}/<type>',
                             f'unsupported noise {kind!r}; use one of {NOISE_TYPES}')
        if kind == 'none':
            return {'noise_mean': 0.0, 'noise_stddev': 0.0}
        values = self.children(element, where, {'mean': 'noise_mean', 'stddev': 'noise_stddev'})
        if values.get('noise_stddev', 0.0) < 0.0:
            raise self.error(f'{where}/<stddev>', 'must not be negative')
        return values

    @staticmethod
    def frame_id(sensor: ElementTree.Element, link_name: str) -> str:
        """Return the laser frame: <gz_frame_id>, the ray plugin's <frame_name>, the link."""
        for path in ('gz_frame_id', 'ignition_frame_id', 'plugin/frame_name'):
            text = (sensor.findtext(path) or '').strip()
            if text:
                return text
        return link_name or sensor.get('name') or LidarConfig().frame_id

    # Values --------------------------------------------------------------------------------

    def children(self, element: ElementTree.Element, where: str,
                 fields: dict[str, str]) -> dict[str, float]:
        """Return {field: number} for each child element ``fields`` maps to a field name."""
        return {name: self.number(element, tag, where) for tag, name in fields.items()
                if element.find(tag) is not None}

    def pose(self, element: ElementTree.Element, where: str) -> Pose6:
        """Return an element's own ``<pose>`` numbers (m, rad), ZERO_POSE when it has none."""
        pose = element.find('pose')
        if pose is None:
            return ZERO_POSE
        pose_where = f'{where}/<pose>'
        if pose.get('rotation_format', 'euler_rpy') != 'euler_rpy':
            raise self.error(pose_where, 'only rotation_format="euler_rpy" is supported')
        values = self.numbers(pose.text, pose_where, 6)
        if pose.get('degrees', 'false').strip().lower() in ('true', '1'):
            values = values[:3] + tuple(math.radians(angle) for angle in values[3:])
        return values

    def numbers(self, text: str | None, where: str, count: int) -> tuple[float, ...]:
        parts = (text or '').split()
        try:
            values = tuple(float(part) for part in parts)
        except ValueError:
            values = ()
        if len(values) != count or not all(math.isfinite(value) for value in values):
            raise self.error(where, f'must be {count} finite numbers, got {(text or "")!r}')
        return values

    def number(self, parent: ElementTree.Element, tag: str, where: str) -> float:
        return self.numbers(parent.findtext(tag), f'{where}/<{tag}>', 1)[0]

    def integer(self, parent: ElementTree.Element, tag: str, where: str) -> int:
        text = (parent.findtext(tag) or '').strip()
        if not text.isdigit() or int(text) < 1:
            raise self.error(f'{where}/<{tag}>', f'must be a positive integer, got {text!r}')
        return int(text)

    def positive(self, parent: ElementTree.Element, tag: str, where: str,
                 default: float | None = None) -> float:
        """Return a positive number; ``default`` (SDF's) when the element is missing."""
        if parent.find(tag) is None:
            if default is not None:
                return default
            raise self.error(f'{where}/<{tag}>', 'is missing')
        value = self.number(parent, tag, where)
        if value <= 0.0:
            raise self.error(f'{where}/<{tag}>', f'must be positive, got {value}')
        return value

    def vector(self, parent: ElementTree.Element, tag: str, where: str,
               count: int) -> tuple[float, ...]:
        if parent.find(tag) is None:
            raise self.error(f'{where}/<{tag}>', 'is missing')
        return self.numbers(parent.findtext(tag), f'{where}/<{tag}>', count)

    def boolean(self, element: ElementTree.Element | None, where: str, default: bool) -> bool:
        if element is None:
            return default
        text = (element.text or '').strip().lower()
        if text in ('true', '1'):
            return True
        if text in ('false', '0'):
            return False
        raise self.error(where, f'must be true or false, got {text!r}')


class _Frames:
    """
    The named frames of one model (links, ``<frame>``s, joints, nested models) for poses.

    SDF 1.7's ``relative_to``: a link's pose is relative to the model unless it names another
    frame; a collision's or sensor's is relative to its link; a joint's to its child link; a
    ``<frame>``'s to what it is ``attached_to``. ``__model__`` is the model frame.
    """

    def __init__(self, reader: _Reader, model: ElementTree.Element, where: str) -> None:
        self.reader = reader
        self.where = where
        self.elements: dict[str, tuple[ElementTree.Element, str | None]] = {}
        for child in model:
            name = child.get('name')
            if name and child.tag in ('link', 'model', 'include', 'frame'):
                self.elements[name] = (child, child.get('attached_to') or None)
            elif name and child.tag == 'joint':
                self.elements[name] = (child, (child.findtext('child') or '').strip() or None)
        self.poses: dict[str, Pose6] = {'__model__': ZERO_POSE}
        self.resolving: set[str] = set()

    def pose_of(self, name: str | None) -> Pose6:
        """Return the pose (m, rad) of the frame ``name`` in the model frame."""
        if name in self.poses:
            return self.poses[name]
        if name not in self.elements or name in self.resolving:
            problem = 'is a loop of relative_to' if name in self.resolving else 'names no frame'
            raise self.reader.error(self.where, f'relative_to="{name}" {problem} of this model '
                                    '(links, frames, joints, nested models or __model__)')
        self.resolving.add(name)
        element, default_parent = self.elements[name]
        at = f'{self.where}/{_label(element)}'
        self.poses[name] = self.resolve(element, at, parent=default_parent)
        self.resolving.discard(name)
        return self.poses[name]

    def resolve(self, element: ElementTree.Element, where: str, parent: str | None = None,
                link: ElementTree.Element | None = None) -> Pose6:
        """Return an element's pose in the model frame, relative to its parent by default."""
        own = self.reader.pose(element, where)
        pose = element.find('pose')
        relative_to = (pose.get('relative_to') or '').strip() if pose is not None else ''
        if relative_to:
            base = self.pose_of(relative_to)
        elif link is not None:
            base = self.resolve(link, self.where)
        elif parent:
            base = self.pose_of(parent)
        else:
            return own
        return compose(base, own)
