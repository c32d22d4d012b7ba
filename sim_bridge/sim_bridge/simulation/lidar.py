"""
A planar lidar made of pybullet ray casts, and the pybullet bodies it sees.

:func:`build_scene` turns a world's :class:`~.geometry.Shape` primitives into static
pybullet bodies; :class:`Lidar` casts one ray per beam with ``rayTestBatch`` from the laser
frame on the robot and returns a LaserScan-shaped :class:`LaserScanData`. Readings follow
Gazebo's ``gpu_lidar`` (gz-sensors) and REP-117:

- beam i points at ``angle_min + i * angle_increment`` with
  ``angle_increment = (max_angle - min_angle) / (beams - 1)``; a single beam points at
  ``min_angle`` with increment 0 (and ``angle_max`` reported as ``min_angle``);
- nothing within ``range_max`` → ``+inf``; a true range below ``range_min`` → ``-inf``;
- otherwise the true range plus Gaussian noise (from the simulator's seeded generator),
  clamped to [range_min, range_max].

Every shape is given to pybullet as a static triangle mesh (exact for boxes, within
:data:`~.geometry.MESH_TOLERANCE` for round ones): Bullet's ray test against its
cylinder and sphere primitives runs an iterative convex cast several times slower per ray (see
``test/bench/bench_simulator.py``), which would cap a 1081-beam lidar far below 100x real time.
"""

from dataclasses import dataclass
import math
from operator import itemgetter

import numpy as np
from sim_bridge.simulation.bullet import pybullet
from sim_bridge.simulation.geometry import MESH_TOLERANCE, rotation_matrix, Shape, triangulate
from sim_bridge.simulation.sdf_lidar import LidarConfig

#: Rays per ``rayTestBatch`` call. pybullet refuses more than MAX_RAY_INTERSECTION_BATCH_SIZE
#: and, at exactly that many, silently returns one result fewer; so stay one below.
RAY_BATCH_SIZE = pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE - 1
#: From this many beams on, pybullet's worker threads cast a scan faster than one thread
#: (bench_simulator.py); the threads only split the batch, the ranges are the same.
THREADED_FROM_BEAMS = 100
#: Thickness (m) of a sized floor, a thin box whose top face is z = 0.
FLOOR_THICKNESS = 0.01
SHAPE_COLOURS = {'box': (0.80, 0.50, 0.20, 1.0), 'cylinder': (0.20, 0.60, 0.30, 1.0),
                 'sphere': (0.70, 0.20, 0.20, 1.0), 'mesh': (0.55, 0.55, 0.65, 1.0)}
#: Kinds pybullet has a primitive of (given as primitives when ``meshes`` is off); the others
#: are always given as triangle meshes.
PRIMITIVE_KINDS = ('box', 'cylinder', 'sphere')
FLOOR_COLOUR = (0.85, 0.85, 0.85, 1.0)
_FRACTION = itemgetter(2)


@dataclass(frozen=True)
class LaserScanData:
    """
    One scan, shaped like sensor_msgs/LaserScan (angles in rad, ranges in m, times in s).

    ``ranges`` and ``intensities`` are float64 arrays (intensities are 0, as from Gazebo
    without retro-reflectors); ``stamp`` is the simulation time of the scan and ``frame_id``
    the laser frame. All beams are cast at once, so ``time_increment`` is 0.
    """

    ranges: np.ndarray
    intensities: np.ndarray
    angle_min: float
    angle_max: float
    angle_increment: float
    time_increment: float
    scan_time: float
    range_min: float
    range_max: float
    stamp: float
    frame_id: str


def cast_rays(client: int, starts: np.ndarray, ends: np.ndarray, *,
              batch_size: int = RAY_BATCH_SIZE, threads: int = 1) -> np.ndarray:
    """
    Return the distance (m) from each start to the first surface towards its end.

    ``starts`` and ``ends`` are (N, 3) world points (m); +inf where the segment hits nothing.
    Batches larger than ``batch_size`` are cast in chunks; ``threads`` is pybullet's
    ``numThreads`` (1: this thread only, 0: Bullet's choice).
    """
    starts = np.asarray(starts, dtype=float).reshape(-1, 3)
    ends = np.asarray(ends, dtype=float).reshape(-1, 3)
    lengths = np.linalg.norm(ends - starts, axis=1)
    fractions = _fractions(client, starts, ends, batch_size, threads)
    distances = fractions * lengths
    distances[fractions >= 1.0] = np.inf
    return distances


def _fractions(client: int, starts: np.ndarray, ends: np.ndarray, batch_size: int,
               threads: int) -> np.ndarray:
    """
    Return each ray's hit fraction along its segment (1.0: no hit).

    pybullet reads (N, 3) float64 arrays a little faster than lists, and far faster than a
    list mixed with an array (see the benchmark).
    """
    count = len(ends)
    if count <= batch_size:
        results = pybullet.rayTestBatch(starts, ends, numThreads=threads,
                                        physicsClientId=client)
        return np.fromiter(map(_FRACTION, results), float, count)
    return np.concatenate([
        _fractions(client, starts[first:first + batch_size], ends[first:first + batch_size],
                   batch_size, threads)
        for first in range(0, count, batch_size)])


def build_scene(client: int, shapes: tuple[Shape, ...] | list[Shape], *,
                floor_size: tuple[float, float] | None = None, meshes: bool = True,
                visuals: bool = False, tolerance: float = MESH_TOLERANCE) -> list[int]:
    """
    Create the floor and a static pybullet body per shape; return their ids in that order.

    ``floor_size`` (x, y in m) makes the floor a thin box centred on the origin, None an
    endless plane. ``meshes`` gives shapes to pybullet as triangle meshes (fast, see the
    module text) instead of its primitives; ``visuals`` adds coloured primitives to look at
    in the GUI.
    """
    bodies = [_floor(client, floor_size, visuals)]
    for shape in shapes:
        if meshes or shape.kind not in PRIMITIVE_KINDS:
            vertices, faces = triangulate(shape, tolerance)
            collision = pybullet.createCollisionShape(
                pybullet.GEOM_MESH, vertices=vertices.tolist(), indices=faces.ravel().tolist(),
                flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=client)
        else:
            collision = pybullet.createCollisionShape(physicsClientId=client,
                                                      **_primitive(shape, 'height'))
        visual = -1
        if visuals and shape.kind in PRIMITIVE_KINDS:
            visual = pybullet.createVisualShape(rgbaColor=SHAPE_COLOURS[shape.kind],
                                                physicsClientId=client,
                                                **_primitive(shape, 'length'))
        elif visuals:
            visual = pybullet.createVisualShape(
                pybullet.GEOM_MESH, vertices=vertices.tolist(), indices=faces.ravel().tolist(),
                rgbaColor=SHAPE_COLOURS['mesh'], physicsClientId=client)
        bodies.append(pybullet.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual,
            basePosition=(shape.x, shape.y, shape.z),
            baseOrientation=pybullet.getQuaternionFromEuler((shape.roll, shape.pitch,
                                                             shape.yaw)),
            physicsClientId=client))
    # Bullet fills its broadphase bounding boxes lazily; rays only find bodies it has updated.
    pybullet.performCollisionDetection(physicsClientId=client)
    return bodies


def _primitive(shape: Shape, length_keyword: str) -> dict:
    """
    Return pybullet's shape arguments; cylinders' length is 'height' or 'length'.

    createCollisionShape calls a cylinder's length 'height', createVisualShape 'length'.
    """
    if shape.kind == 'box':
        return {'shapeType': pybullet.GEOM_BOX,
                'halfExtents': [0.5 * size for size in shape.size]}
    if shape.kind == 'cylinder':
        return {'shapeType': pybullet.GEOM_CYLINDER, 'radius': shape.radius,
                length_keyword: shape.length}
    return {'shapeType': pybullet.GEOM_SPHERE, 'radius': shape.radius}


def _floor(client: int, floor_size: tuple[float, float] | None, visuals: bool) -> int:
    if floor_size is None:
        collision = pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client)
        return pybullet.createMultiBody(0.0, collision, physicsClientId=client)
    half_extents = (0.5 * floor_size[0], 0.5 * floor_size[1], 0.5 * FLOOR_THICKNESS)
    collision = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half_extents,
                                              physicsClientId=client)
    visual = -1
    if visuals:
        visual = pybullet.createVisualShape(pybullet.GEOM_BOX, halfExtents=half_extents,
                                            rgbaColor=FLOOR_COLOUR, physicsClientId=client)
    return pybullet.createMultiBody(0.0, collision, visual,
                                    basePosition=(0.0, 0.0, -0.5 * FLOOR_THICKNESS),
                                    physicsClientId=client)


def beam_directions(config: LidarConfig) -> np.ndarray:
    """Return the (beams, 3) unit beam directions in the robot's base frame."""
    angles = config.min_angle + config.angle_increment * np.arange(config.beams)
    in_laser = np.column_stack((np.cos(angles), np.sin(angles), np.zeros(config.beams)))
    roll, pitch, yaw = config.pose[3:]
    return in_laser @ rotation_matrix(roll, pitch, yaw).T


class Lidar:
    """
    A lidar on the robot casting rays into one pybullet client.

    ``rng`` supplies the noise (the only randomness); ``threads`` is pybullet's numThreads
    (0: pybullet's choice), by default 1 below ``THREADED_FROM_BEAMS`` beams and 0 from there.
    The scene's bodies are static: a scan from the pose of the last cast reuses its distances
    (a robot standing still casts no rays; its readings get fresh noise all the same).
    """

    def __init__(self, client: int, config: LidarConfig, rng: np.random.Generator, *,
                 threads: int | None = None) -> None:
        self.client = client
        self.config = config
        self.rng = rng
        if threads is None:
            threads = 0 if config.beams >= THREADED_FROM_BEAMS else 1
        self.threads = threads
        # Each beam's end relative to the laser (m, robot axes), its x and y as contiguous
        # arrays; the rays' starts and ends (m, world frame) are rewritten in place every scan
        # apart from their heights, which the robot's motion in the plane never changes.
        self._reach = beam_directions(config) * config.range_max
        self._reach_x = np.ascontiguousarray(self._reach[:, 0])
        self._reach_y = np.ascontiguousarray(self._reach[:, 1])
        height = config.pose[2]
        self._starts = np.empty_like(self._reach)
        self._starts[:, 2] = height
        self._ends = np.empty_like(self._reach)
        self._ends[:, 2] = height + self._reach[:, 2]
        self._noisy = config.noise_stddev > 0.0 or config.noise_mean != 0.0
        # The robot pose (m, m, rad) of the last rays cast and their distances (m): the scene
        # is static, so a robot that has not moved since sees the same and casts no rays.
        self._cast_pose: tuple[float, float, float] | None = None
        self._cast = np.empty(0)

    def origin(self, pose: tuple[float, float, float]) -> tuple[float, float, float]:
        """Return where the laser frame is (m, world frame) for the robot pose (m, m, rad)."""
        x, y, yaw = pose
        offset_x, offset_y, height = self.config.pose[:3]
        cos_yaw = math.cos(yaw)
        sin_yaw = math.sin(yaw)
        return (x + cos_yaw * offset_x - sin_yaw * offset_y,
                y + sin_yaw * offset_x + cos_yaw * offset_y, height)

    def _world_points(self, pose: tuple[float, float, float], reach_x: np.ndarray,
                      reach_y: np.ndarray, points: np.ndarray) -> tuple[float, float, float]:
        """
        Write the world x, y of points near the laser into ``points``; return the laser origin.

        ``reach_x`` and ``reach_y`` (m) place the points relative to the laser along the
        robot's axes; ``points`` is (N, 3), its z column (m) is left to the caller. Origin and
        points are in the world frame (m) for the robot pose (m, m, rad). The rotation is
        written out term by term, not as a matrix product, whose summing may round the last
        bit differently.
        """
        origin = self.origin(pose)
        cos_yaw = math.cos(pose[2])
        sin_yaw = math.sin(pose[2])
        x = origin[0] + cos_yaw * reach_x
        x -= sin_yaw * reach_y
        y = origin[1] + sin_yaw * reach_x
        y += cos_yaw * reach_y
        points[:, 0] = x
        points[:, 1] = y
        return origin

    def _distances(self, pose: tuple[float, float, float]) -> np.ndarray:
        """
        Return the distance (m) along each beam to the first surface, range_max for none.

        A new array, cast anew unless the pose is the last one cast from.
        """
        pose = tuple(pose)  # a list or an array compares as its values
        if pose != self._cast_pose:
            origin = self._world_points(pose, self._reach_x, self._reach_y, self._ends)
            self._starts[:, 0].fill(origin[0])
            self._starts[:, 1].fill(origin[1])
            self._cast = _fractions(self.client, self._starts, self._ends, RAY_BATCH_SIZE,
                                    self.threads)
            self._cast *= self.config.range_max
            self._cast_pose = pose
        return self._cast.copy()

    def true_ranges(self, pose: tuple[float, float, float]) -> np.ndarray:
        """Return the noise-free distance (m) along each beam, +inf from range_max on."""
        ranges = self._distances(pose)
        np.putmask(ranges, ranges >= self.config.range_max, np.inf)
        return ranges

    def ray_segments(self, pose: tuple[float, float, float], ranges: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the (N, 3) starts and ends (m, world frame) of the beams of a scan, for drawing.

        Each ray ends at its reading, or at range_max for no return (+inf) and at the laser for
        a reading too close (-inf).
        """
        fractions = np.clip(np.nan_to_num(np.asarray(ranges) / self.config.range_max,
                                          nan=1.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        reach = self._reach * fractions[:, np.newaxis]
        ends = np.empty_like(reach)
        ends[:, 2] = self.config.pose[2] + reach[:, 2]
        origin = self._world_points(pose, reach[:, 0], reach[:, 1], ends)
        return np.broadcast_to(origin, ends.shape), ends

    def scan(self, pose: tuple[float, float, float], stamp: float = 0.0) -> LaserScanData:
        """Return the scan from the robot pose (x m, y m, yaw rad) at time ``stamp`` (s)."""
        config = self.config
        distances = self._distances(pose)
        no_return = distances >= config.range_max
        too_close = distances < config.range_min
        ranges = distances
        if self._noisy:
            ranges = self.rng.normal(config.noise_mean, config.noise_stddev, len(distances))
            ranges += distances
            ranges.clip(config.range_min, config.range_max, out=ranges)
        np.putmask(ranges, no_return, np.inf)
        np.putmask(ranges, too_close, -np.inf)
        return LaserScanData(
            ranges=ranges, intensities=np.zeros(len(ranges)), angle_min=config.min_angle,
            angle_max=config.last_angle, angle_increment=config.angle_increment,
            time_increment=0.0, scan_time=config.scan_period, range_min=config.range_min,
            range_max=config.range_max, stamp=stamp, frame_id=config.frame_id)
