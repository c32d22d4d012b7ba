"""
Read Gazebo model files as Gazebo reads them: collisions, the lidar and the diff-drive plugin.

:func:`load_model` reads a model folder (``model.config`` naming its SDF file) or an SDF file,
SDF 1.4 to 1.10, Gazebo Sim and Gazebo Classic forms alike, with :mod:`xml.etree`:

- every ``<collision>`` of every ``<link>``, at the link's and the collision's ``<pose>`` (any
  rotation; ``relative_to`` a link, a ``<frame>`` or the model), as a
  :class:`~.geometry.Shape`: ``<box>``, ``<cylinder>``, ``<sphere>``, ``<capsule>``,
  ``<ellipsoid>``, ``<polyline>`` (extruded) and ``<mesh>`` (STL, OBJ, DAE with its ``<unit>``,
  times ``<scale>``; :mod:`.meshes`). A ``<plane>`` is the floor, not an obstacle
  (:attr:`Model.planes`);
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

What the simulator does not simulate (visuals, joints, other sensors and plugins,
``<submesh>``) is listed in :attr:`Model.not_simulated`, never dropped in silence; what it cannot
read is an :class:`SdfError` naming the file, the element path and what to do.

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
    euler_from_matrix, Footprint, Mesh, rotation_matrix, Shape, triangulate)
from sim_bridge.simulation.meshes import extrude, load_mesh, MeshError
from sim_bridge.simulation.robot import DiffDriveConfig, DriveLimits

LIDAR_SENSOR_TYPES = ('ray', 'gpu_ray', 'lidar', 'gpu_lidar')
NOISE_TYPES = ('gaussian', 'none')
#: Speed limit (m/s and rad/s) standing for "none": a diff-drive plugin without a velocity
#: limit has none in Gazebo, and DriveLimits needs a finite number.
NO_SPEED_LIMIT = 1000.0
#: Gazebo Classic gazebo_ros_diff_drive's wheel separation (m) when the plugin gives none.
CLASSIC_WHEEL_SEPARATION = 0.34
#: Gazebo Sim's DiffDrive odometry rate (Hz) when <odom_publish_frequency> is not given.
SIM_ODOMETRY_RATE = 50.0
#: Gazebo Classic gazebo_ros_diff_drive's update rate (Hz) when <update_rate> is not given.
CLASSIC_UPDATE_RATE = 100.0

Pose6 = tuple[float, float, float, float, float, float]
ZERO_POSE: Pose6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
#: An entry of an ignored list: (what, its name or '' when only counted).
Ignored = tuple[str, str]


class SdfError(ValueError):
    """A model file the simulator cannot use; the message names the file and the element."""


def compose(parent: Pose6, child: Pose6) -> Pose6:
    """Return the pose of ``child``, given in ``parent``'s frame, in parent's parent (m, rad)."""
    rotation = rotation_matrix(*parent[3:])
    position = rotation @ np.asarray(child[:3], dtype=float) + parent[:3]
    roll, pitch, yaw = euler_from_matrix(rotation @ rotation_matrix(*child[3:]))
    return (float(position[0]), float(position[1]), float(position[2]), roll, pitch, yaw)


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
    Read a model folder (``model.config`` naming its SDF file) or an SDF file.

    ``lidar`` names the sensor to use when the model has several lidars (default: the first);
    ``world_folder`` is searched first for ``model://`` URIs (see
    :func:`~sim_bridge.common.paths.model_search_path`). Raises :class:`SdfError` for a file that
    cannot be used, FileNotFoundError for none.
    """
    path = model_file(Path(folder_or_file))
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
        return ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise SdfError(f'{path}: invalid XML: {error}') from None


def _label(element: ElementTree.Element) -> str:
    name = element.get('name')
    return f'<{element.tag} name="{name}">' if name is not None else f'<{element.tag}>'


def _plugin_kind(plugin: ElementTree.Element) -> str | None:
    """Return 'sim' or 'classic' for a diff-drive plugin, None for any other plugin."""
    filename = (plugin.get('filename') or '').strip()
    stem = Path(filename).name.removeprefix('lib').removesuffix('.so')
    if stem in ('gz-sim-diff-drive-system', 'ignition-gazebo-diff-drive-system') or \
            plugin.get('name') in ('gz::sim::systems::DiffDrive',
                                   'ignition::gazebo::systems::DiffDrive'):
        return 'sim'
    if stem == 'gazebo_ros_diff_drive':
        return 'classic'
    return None


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


class _Reader:
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
            try:
                folder = paths.find_model(parsed.netloc, self.world_folder)
            except FileNotFoundError as error:
                raise self.error(where, str(error)) from None
            return folder / unquote(parsed.path.lstrip('/'))
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
                     sources=tuple(dict.fromkeys(found.sources)), lidars=lidars)

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
                kind = _plugin_kind(child)
                if kind is None:
                    found.ignored.append(('plugin', child.get('filename') or child.get('name')))
                else:
                    found.drives.append(self.drive_reader(child, child_where, kind))
            elif child.tag == 'joint':
                found.ignored.append(('joint', ''))

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
                shape, plane = self.collision(child, child_where)
                if plane is not None:
                    found.planes.append(Plane(pose[2], plane))
                elif shape is not None:
                    found.shapes.append(place(shape, pose))
                    if shape.kind == 'mesh':
                        found.sources.append(Path(shape.mesh.source))
                if child.find('geometry/mesh/submesh') is not None:
                    found.ignored.append(('submesh (whole mesh used)', ''))
            elif child.tag == 'visual':
                found.ignored.append(('visual', ''))
            elif child.tag == 'sensor':
                pose = compose(model_frame, frames.resolve(child, child_where, link=link))
                if child.get('type') in LIDAR_SENSOR_TYPES:
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
        kinds = '<box>, <cylinder>, <sphere>, <capsule>, <ellipsoid>, <mesh>, <plane>'
        if geometry is None or len(geometry) != 1:
            raise self.error(f'{where}/<geometry>', f'needs exactly one of {kinds}')
        primitive = geometry[0]
        at = f'{where}/<geometry>/<{primitive.tag}>'
        if primitive.tag == 'box':
            size = self.vector(primitive, 'size', at, 3)
            if min(size) <= 0.0:
                raise self.error(f'{at}/<size>', f'must be positive, got {size}')
            return Shape('box', size=size), None
        if primitive.tag in ('cylinder', 'capsule'):
            return Shape(primitive.tag, radius=self.positive(primitive, 'radius', at),
                         length=self.positive(primitive, 'length', at)), None
        if primitive.tag == 'sphere':
            return Shape('sphere', radius=self.positive(primitive, 'radius', at)), None
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
            self.check_planar(blocks[0].find('scan/vertical'), f'{block_where}/<scan>/<vertical>')
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

    def check_planar(self, element: ElementTree.Element | None, where: str) -> None:
        if element is not None and element.find('samples') is not None:
            layers = self.integer(element, 'samples', where)
            if layers != 1:
                raise self.error(f'{where}/<samples>', 'only planar lidars (1 vertical sample) '
                                 f'are supported, got {layers}')

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

    # The diff drive ------------------------------------------------------------------------

    def drive_reader(self, plugin: ElementTree.Element, where: str, kind: str
                     ) -> Callable[[str, str], DiffDriveConfig]:
        """Return a function of (model name, canonical link) giving the plugin's config."""
        if kind == 'sim':
            return self.sim_drive(plugin, where)
        return self.classic_drive(plugin, where)

    def optional(self, plugin: ElementTree.Element, tag: str, where: str) -> float | None:
        return self.number(plugin, tag, where) if plugin.find(tag) is not None else None

    def limit(self, plugin: ElementTree.Element, where: str, tags: tuple[str, ...],
              default: float) -> float:
        """Return the magnitude of the last given of ``tags`` (Gazebo lets later ones win)."""
        value = default
        for tag in tags:
            given = self.optional(plugin, tag, where)
            if given is not None:
                if given == 0.0:
                    raise self.error(f'{where}/<{tag}>', 'must not be 0')
                value = abs(given)
        return value

    def sim_drive(self, plugin: ElementTree.Element, where: str
                  ) -> Callable[[str, str], DiffDriveConfig]:
        # gz-sim's DiffDrive: the general <max_velocity>/<max_acceleration> set both the
        # linear and the angular limiter, the specific elements override them; a <min_*> only
        # given stands for the limit the other way (DriveLimits is symmetric).
        def speed(which: str) -> float:
            return self.limit(plugin, where, ('min_velocity', 'max_velocity',
                                              f'min_{which}_velocity', f'max_{which}_velocity'),
                              NO_SPEED_LIMIT)

        def accel(which: str) -> float:
            return self.limit(plugin, where, ('min_acceleration', 'max_acceleration',
                                              f'min_{which}_acceleration',
                                              f'max_{which}_acceleration'), math.inf)

        limits = self.drive_limits(where, max_linear_speed=speed('linear'),
                                   max_angular_speed=speed('angular'),
                                   max_linear_accel=accel('linear'),
                                   max_angular_accel=accel('angular'))
        separation = self.optional_positive(plugin, 'wheel_separation', where)
        radius = self.optional_positive(plugin, 'wheel_radius', where)
        rate = self.optional_positive(plugin, 'odom_publish_frequency', where)
        text = {tag: (plugin.findtext(tag) or '').strip()
                for tag in ('topic', 'odom_topic', 'frame_id', 'child_frame_id')}

        def config(model: str, link: str) -> DiffDriveConfig:
            return DiffDriveConfig(
                wheel_separation=separation, wheel_radius=radius, limits=limits,
                command_topic=text['topic'] or f'/model/{model}/cmd_vel',
                odometry_topic=text['odom_topic'] or f'/model/{model}/odometry',
                odometry_frame=text['frame_id'] or f'{model}/odom',
                base_frame=text['child_frame_id'] or f'{model}/{link}',
                odometry_rate=rate or SIM_ODOMETRY_RATE, publish_tf=True)
        return config

    def classic_drive(self, plugin: ElementTree.Element, where: str
                      ) -> Callable[[str, str], DiffDriveConfig]:
        # gazebo_ros_diff_drive: <max_wheel_acceleration> (m/s² at the wheel's rim, 0 = none)
        # bounds each wheel; the body's linear acceleration is that, its angular one twice that
        # over the wheel separation. It has no velocity limit.
        separation = self.optional_positive(plugin, 'wheel_separation', where)
        diameter = self.optional_positive(plugin, 'wheel_diameter', where)
        wheel_accel = self.optional(plugin, 'max_wheel_acceleration', where) or 0.0
        if wheel_accel < 0.0:
            raise self.error(f'{where}/<max_wheel_acceleration>', 'must not be negative')
        linear = wheel_accel if wheel_accel > 0.0 else math.inf
        angular = 2.0 * linear / (separation or CLASSIC_WHEEL_SEPARATION)
        limits = self.drive_limits(where, max_linear_speed=NO_SPEED_LIMIT,
                                   max_angular_speed=NO_SPEED_LIMIT, max_linear_accel=linear,
                                   max_angular_accel=angular)
        rate = self.optional(plugin, 'update_rate', where)
        namespace = (plugin.findtext('ros/namespace') or '').strip()
        remaps = {}
        for remapping in plugin.findall('ros/remapping'):
            source, _, target = (remapping.text or '').strip().partition(':=')
            remaps[source.strip().lstrip('~').lstrip('/')] = target.strip()

        def topic(name: str, legacy: str) -> str:
            # The ROS 2 plugin subscribes to 'cmd_vel' and publishes 'odom' under its node's
            # namespace, renamed by <ros><remapping>; <command_topic>/<odometry_topic> are
            # the ROS 1 plugin's names, honoured when no remapping is given.
            chosen = remaps.get(name) or (plugin.findtext(legacy) or '').strip() or name
            if namespace and not chosen.startswith('/'):
                chosen = f"{namespace.rstrip('/')}/{chosen}"
            return chosen

        config = DiffDriveConfig(
            wheel_separation=separation,
            wheel_radius=0.5 * diameter if diameter is not None else None, limits=limits,
            command_topic=topic('cmd_vel', 'command_topic'),
            odometry_topic=topic('odom', 'odometry_topic'),
            odometry_frame=(plugin.findtext('odometry_frame') or '').strip() or 'odom',
            base_frame=(plugin.findtext('robot_base_frame') or '').strip() or 'base_footprint',
            odometry_rate=rate if rate and rate > 0.0 else CLASSIC_UPDATE_RATE,
            publish_tf=self.boolean(plugin.find('publish_odom_tf'),
                                    f'{where}/<publish_odom_tf>', default=False))
        return lambda _model, _link: config

    def drive_limits(self, where: str, **values: float) -> DriveLimits:
        try:
            return DriveLimits(**values)
        except ValueError as error:
            raise self.error(where, str(error)) from None

    def optional_positive(self, parent: ElementTree.Element, tag: str,
                          where: str) -> float | None:
        return self.positive(parent, tag, where) if parent.find(tag) is not None else None

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

    def positive(self, parent: ElementTree.Element, tag: str, where: str) -> float:
        if parent.find(tag) is None:
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
