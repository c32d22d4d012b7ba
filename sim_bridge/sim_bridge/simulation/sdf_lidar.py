"""
The planar lidar: its configuration (:class:`LidarConfig`) and its reading from an SDF sensor.

:class:`LidarReading` is the SDF reader's lidar part (:mod:`.sdf`): a ``gpu_lidar``/``lidar``/
``gpu_ray``/``ray`` sensor's ``<lidar>`` or ``<ray>`` block (scan, range, noise), its update
rate and its frame (Gazebo Sim's ``<gz_frame_id>``, Classic's ray plugin ``<frame_name>``, else
the link's name). Units: m, rad, Hz.
"""

from dataclasses import dataclass
from functools import cached_property
import math
import xml.etree.ElementTree as ElementTree

from sim_bridge.simulation.sdf_values import Pose6, SdfValues

LIDAR_SENSOR_TYPES = ('ray', 'gpu_ray', 'lidar', 'gpu_lidar')
NOISE_TYPES = ('gaussian', 'none')


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


class LidarReading(SdfValues):
    """The SDF reader's lidar part: a lidar ``<sensor>`` as a :class:`LidarConfig`."""

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
