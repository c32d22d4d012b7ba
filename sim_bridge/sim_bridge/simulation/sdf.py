"""
Read Gazebo model folders: ``model.config`` and the collision shapes and lidar of ``model.sdf``.

Only what the simulator uses is read, with :mod:`xml.etree`; everything it cannot honour is
rejected with an :class:`SdfError` naming the file and the element, never silently ignored:

- ``<model>`` holding ``<link>`` elements, each with an optional ``<pose>`` (rotation about z
  only) and ``<collision>`` elements whose ``<geometry>`` is a ``<box><size>``, a
  ``<cylinder><radius><length>`` (axis vertical) or a ``<sphere><radius>``, each with an
  optional ``<pose>`` (rotation about z only). Visuals, inertials, joints and plugins are
  ignored: the simulator moves the model as one rigid body.
- The first lidar ``<sensor>`` of the model, in either dialect: Gazebo classic
  ``type="ray"``/``"gpu_ray"`` with a ``<ray>`` element, or Gazebo Sim
  ``type="gpu_lidar"``/``"lidar"`` with a ``<lidar>`` element; inside it ``<scan><horizontal>``
  (``samples``, ``resolution``, ``min_angle``, ``max_angle``), ``<range>`` (``min``, ``max``,
  ``resolution``) and ``<noise>`` (``type`` gaussian or none, ``mean``, ``stddev``), plus the
  sensor's ``<update_rate>`` and ``<pose>`` (the laser frame on the robot, any rotation). An
  element left out takes the lab's default from :class:`LidarConfig`.

A ``<pose>`` is ``x y z roll pitch yaw`` (m, rad; degrees with ``degrees="true"``) relative to
the parent element, the SDF default.
"""

from dataclasses import dataclass, field
from functools import cached_property
import math
import os
from pathlib import Path
import xml.etree.ElementTree as ElementTree

from sim_bridge.simulation.geometry import compose_pose, Footprint, Shape
from sim_bridge.simulation.robot import DiffDriveConfig

LIDAR_SENSOR_TYPES = ('ray', 'gpu_ray', 'lidar', 'gpu_lidar')
NOISE_TYPES = ('gaussian', 'none')


class SdfError(ValueError):
    """A model file the simulator cannot use; the message names the file and the element."""


@dataclass(frozen=True)
class LidarConfig:
    """
    A planar lidar as a Gazebo ``<sensor>`` block describes it (defaults: the lab's lidar).

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
    noise_stddev: float = 0.01
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
    A model read from its ``model.sdf``: collision shapes in the model frame, maybe a lidar.

    The model frame's origin is on the floor (z = 0) where the model is placed.
    """

    name: str
    path: Path
    shapes: tuple[Shape, ...]
    lidar: LidarConfig | None = None
    static: bool = False
    #: The model's diff-drive plugin, None when it has none.
    drive: DiffDriveConfig | None = None
    footprints: tuple[Footprint, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'footprints', tuple(shape.footprint() for shape in self.shapes))

    @property
    def radius(self) -> float:
        """Return the radius of the smallest circle about the origin holding the outline (m)."""
        radius = 0.0
        for footprint in self.footprints:
            if footprint.kind == 'circle':
                radius = max(radius, math.hypot(footprint.x, footprint.y) + footprint.radius)
            else:
                corners = footprint.outline()
                radius = max(radius, float(max(math.hypot(*corner) for corner in corners)))
        return radius

    @property
    def height(self) -> float:
        """Return the height of the top of the highest collision shape (m)."""
        return max((shape.z_range()[1] for shape in self.shapes), default=0.0)


def load_model(folder_or_file: str | os.PathLike) -> Model:
    """
    Read a model folder (``model.config`` naming its SDF file) or a ``.sdf`` file.

    Raises :class:`SdfError` for a file that cannot be used, FileNotFoundError for none.
    """
    path = Path(folder_or_file)
    if path.is_dir():
        path = path / sdf_file_name(path)
    if not path.is_file():
        raise FileNotFoundError(f'model file not found: {path}')
    return parse_model(path.read_text(encoding='utf-8'), path)


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


def parse_model(text: str, path: Path) -> Model:
    """Read the first ``<model>`` of an SDF document ``text`` read from ``path``."""
    root = _parse_xml(text, path)
    reader = _Reader(path)
    if root.tag == 'model':
        model = root
    else:
        if root.tag != 'sdf':
            raise SdfError(f'{path}: <{root.tag}>: the root element must be <sdf>')
        model = root.find('model')
        if model is None:
            raise SdfError(f'{path}: <sdf>: has no <model> element')
    return reader.model(model)


def _parse_xml(text: str, path: Path) -> ElementTree.Element:
    try:
        return ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise SdfError(f'{path}: invalid XML: {error}') from None


def _label(element: ElementTree.Element) -> str:
    name = element.get('name')
    return f'<{element.tag} name="{name}">' if name is not None else f'<{element.tag}>'


class _Reader:
    """Walks one SDF file, keeping the file name for error messages."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def error(self, where: str, problem: str) -> SdfError:
        return SdfError(f'{self.path}: {where}: {problem}')

    def model(self, element: ElementTree.Element) -> Model:
        where = _label(element)
        name = element.get('name')
        if not name:
            raise self.error(where, 'the model has no name attribute')
        for unsupported in ('include', 'model'):
            child = element.find(unsupported)
            if child is not None:
                raise self.error(f'{where}/{_label(child)}',
                                 'nested models are not supported; copy the links in')
        model_pose = self.upright_pose(element, where)
        shapes = []
        lidar = None
        for link in element.findall('link'):
            link_where = f'{where}/{_label(link)}'
            placement = compose_pose(model_pose, self.upright_pose(link, link_where))
            for collision in link.findall('collision'):
                shapes.append(self.collision(collision, f'{link_where}/{_label(collision)}')
                              .placed(*placement))
            for sensor in link.findall('sensor'):
                if lidar is None and sensor.get('type') in LIDAR_SENSOR_TYPES:
                    lidar = self.lidar(sensor, f'{link_where}/{_label(sensor)}', placement)
        static = self.boolean(element.find('static'), f'{where}/<static>', default=False)
        return Model(name=name, path=self.path, shapes=tuple(shapes), lidar=lidar,
                     static=static)

    def collision(self, element: ElementTree.Element, where: str) -> Shape:
        x, y, z, yaw = self.upright_pose(element, where)
        geometry = element.find('geometry')
        if geometry is None or len(geometry) != 1:
            raise self.error(f'{where}/<geometry>',
                             'needs exactly one of <box>, <cylinder>, <sphere>')
        primitive = geometry[0]
        primitive_where = f'{where}/<geometry>/<{primitive.tag}>'
        if primitive.tag == 'box':
            size = self.vector(primitive, 'size', primitive_where, 3)
            if min(size) <= 0.0:
                raise self.error(f'{primitive_where}/<size>', f'must be positive, got {size}')
            return Shape('box', x, y, z, yaw, size=size)
        if primitive.tag == 'cylinder':
            return Shape('cylinder', x, y, z, yaw,
                         radius=self.positive(primitive, 'radius', primitive_where),
                         length=self.positive(primitive, 'length', primitive_where))
        if primitive.tag == 'sphere':
            return Shape('sphere', x, y, z, yaw,
                         radius=self.positive(primitive, 'radius', primitive_where))
        raise self.error(primitive_where, f'unsupported geometry <{primitive.tag}>; use <box>, '
                         '<cylinder> or <sphere>')

    def lidar(self, sensor: ElementTree.Element, where: str,
              placement: tuple[float, float, float, float]) -> LidarConfig:
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
        x, y, z, roll, pitch, yaw = self.pose(sensor, where)
        # The link turns only about z, so composing its rotation just adds to the sensor's yaw
        # (SDF's roll-pitch-yaw is R = Rz(yaw) Ry(pitch) Rx(roll)).
        x, y, z, yaw = compose_pose(placement, (x, y, z, yaw))
        values['pose'] = (x, y, z, roll, pitch, yaw)
        values['frame_id'] = self.frame_id(sensor)
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
        kind = (element.findtext('type') or 'gaussian').strip()
        if kind not in NOISE_TYPES:
            raise self.error(f'{where}/<type>',
                             f'unsupported noise {kind!r}; use one of {NOISE_TYPES}')
        if kind == 'none':
            return {'noise_mean': 0.0, 'noise_stddev': 0.0}
        values = self.children(element, where, {'mean': 'noise_mean', 'stddev': 'noise_stddev'})
        if values.get('noise_stddev', 0.0) < 0.0:
            raise self.error(f'{where}/<stddev>', 'must not be negative')
        return values

    def children(self, element: ElementTree.Element, where: str,
                 fields: dict[str, str]) -> dict[str, float]:
        """Return {field: number} for each child element ``fields`` maps to a field name."""
        return {name: self.number(element, tag, where) for tag, name in fields.items()
                if element.find(tag) is not None}

    @staticmethod
    def frame_id(sensor: ElementTree.Element) -> str:
        """Return the laser frame: Gazebo Sim's <gz_frame_id>, a plugin <frame_name>, the name."""
        for path in ('gz_frame_id', 'ignition_frame_id', 'plugin/frame_name'):
            text = (sensor.findtext(path) or '').strip()
            if text:
                return text
        return sensor.get('name') or LidarConfig().frame_id

    def pose(self, element: ElementTree.Element, where: str
             ) -> tuple[float, float, float, float, float, float]:
        pose = element.find('pose')
        if pose is None:
            return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        pose_where = f'{where}/<pose>'
        relative_to = pose.get('relative_to')
        if relative_to:
            raise self.error(pose_where, f'relative_to="{relative_to}" is not supported; give '
                             'the pose relative to the parent element')
        if pose.get('rotation_format', 'euler_rpy') != 'euler_rpy':
            raise self.error(pose_where, 'only rotation_format="euler_rpy" is supported')
        values = self.numbers(pose.text, pose_where, 6)
        if pose.get('degrees', 'false').strip().lower() in ('true', '1'):
            values = values[:3] + tuple(math.radians(angle) for angle in values[3:])
        return values

    def upright_pose(self, element: ElementTree.Element, where: str
                     ) -> tuple[float, float, float, float]:
        x, y, z, roll, pitch, yaw = self.pose(element, where)
        if abs(roll) > 1e-9 or abs(pitch) > 1e-9:
            raise self.error(f'{where}/<pose>', 'only rotations about z are supported here '
                             f'(roll and pitch must be 0, got {roll} and {pitch})')
        return x, y, z, yaw

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
