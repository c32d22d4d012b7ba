"""
The simulator: a world, a differential-drive robot, and its lidar.

Pure (no rclpy): the ROS 2 bridge node (live or stepped by the runner) drives it by calling
:meth:`Simulator.set_command`, :meth:`Simulator.step` and :meth:`Simulator.scan` on simulated
time. One pybullet client in DIRECT mode per simulator (the GUI on request), so several
simulators coexist in one process; the lidar noise comes from a generator seeded by ``seed``,
the only randomness, so one seed makes a run bit-identical.

Collisions are checked on the floor, in the slice of the 3-D world through the robot's height
band (:class:`~.floor_slice.FloorSlice`): the robot's outline against the obstacles' outlines
in that band. A round robot (the lab robot) is a circle against circles and rectangles,
analytically (:class:`~.geometry.FootprintSet`, about a microsecond per check in a lab world,
which also gives the clearance; pybullet's getClosestPoints takes some 20 times longer, see
``test/bench/bench_simulator.py``); any other robot is its shapely polygon, tested only when
an obstacle is within its circumscribed circle. A motion that would make them overlap stops
where they touch, to within :data:`CONTACT_RESOLUTION`; its speed drops to 0. A round robot
keeps turning, which it can do in contact; any other robot stops turning too (turning can
push its corners into an obstacle: the motion is checked at intermediate poses, turn
included). Each new contact is logged once as a :class:`Collision`: contact starts when the
robot is blocked or comes within :data:`CONTACT_DISTANCE` of an obstacle and ends when it is
more than :data:`RELEASE_DISTANCE` away again.
"""

from dataclasses import dataclass, replace
import math
import os
import weakref

import numpy as np
from sim_bridge.simulation.bullet import pybullet
from sim_bridge.simulation.geometry import wrap_angle
from sim_bridge.simulation.lidar import build_scene, LaserScanData, Lidar
from sim_bridge.simulation.robot import DiffDrive, DriveLimits, integrate_arc
from sim_bridge.simulation.sdf_lidar import LidarConfig
from sim_bridge.simulation.viewer import Viewer
from sim_bridge.simulation.world import World

#: Body-to-obstacle distance (m) at or below which the robot touches an obstacle.
CONTACT_DISTANCE = 1e-3
#: Body-to-obstacle distance (m) the robot must exceed before a new contact counts again.
RELEASE_DISTANCE = 1e-2
#: Longest move of any point of the robot (as a fraction of the radius of the largest circle
#: inside its outline) between two collision checks, so that the robot cannot jump over a
#: thin wall in one step.
MAX_MOVE_PER_CHECK = 0.5
#: How close (m) a blocked robot is brought to the obstacle it would otherwise penetrate.
CONTACT_RESOLUTION = 1e-6
#: Conservative-advancement steps before bisection takes over (see _last_free_fraction).
CONTACT_ADVANCES = 8


@dataclass(frozen=True)
class Collision:
    """A new contact: simulation time (s), robot centre (m) and the obstacle's name."""

    time: float
    x: float
    y: float
    obstacle: str


@dataclass(frozen=True)
class BulletOptions:
    """
    How pybullet holds a simulator's scene, for measurements.

    ``ray_threads`` is pybullet's numThreads for the lidar's rays (None: chosen by beam count,
    see :class:`~.lidar.Lidar`); ``collision_meshes`` False gives pybullet primitives instead
    of meshes (slower; for comparison).
    """

    ray_threads: int | None = None
    collision_meshes: bool = True


class Simulator:
    """
    A world with one robot: command it, step it, scan, and read its ground truth.

    ``world`` is a :class:`~.world.World` or a world name/path. ``lidar`` replaces
    the robot model's lidar; ``lidar_samples`` and ``lidar_noise_stddev`` (m) override just
    its beam count and noise; ``limits`` are the drive's :class:`~.robot.DriveLimits`;
    ``command_timeout`` (s, sim time): with no new command for longer than this the robot is
    told to stop (None: a command holds until the next); ``gui`` opens the pybullet window
    (one per process) with a camera following the robot, ``draw_rays`` draws the lidar's rays
    there; ``bullet`` how pybullet holds the scene (:class:`BulletOptions`).
    """

    def __init__(self, world: World | str | os.PathLike, *, seed: int = 0,
                 lidar: LidarConfig | None = None, lidar_samples: int | None = None,
                 lidar_noise_stddev: float | None = None, limits: DriveLimits | None = None,
                 command_timeout: float | None = None, gui: bool = False,
                 draw_rays: bool = False, bullet: BulletOptions | None = None) -> None:
        if not isinstance(world, World):
            world = World.load(world)
        self.world = world
        config = lidar or world.robot.lidar
        if config is None:
            raise ValueError(f"robot model '{world.robot_model}' ({world.robot.path}) has no "
                             'lidar <sensor>; add one or pass lidar=LidarConfig(...)')
        if lidar_samples is not None:
            config = replace(config, samples=lidar_samples)
        if lidar_noise_stddev is not None:
            config = replace(config, noise_stddev=lidar_noise_stddev)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f'seed must be a non-negative integer, got {seed!r}')
        if command_timeout is not None and not command_timeout > 0.0:
            raise ValueError(f'command_timeout must be positive (s) or None, got '
                             f'{command_timeout!r}')
        self.lidar_config = config
        #: None, or a list to which each step appends the robot's ground truth after it, for
        #: scoring: (time s, x m, y m, yaw rad, v m/s, w rad/s, clearance m), as in a
        #: :class:`~sim_bridge.scoring.run_trace.Trace`.
        self.trajectory: list[tuple[float, ...]] | None = None
        self.command_timeout = command_timeout
        self._floor = world.floor_slice
        #: Radius (m) of the circle about the robot's origin holding its outline.
        self.robot_radius = self._floor.robot_radius
        self.limits = limits or DriveLimits()
        self.seed = seed
        self.gui = gui
        self.collisions: list[Collision] = []
        self._drive = DiffDrive(world.robot_start, self.limits)
        self._owners = world.footprint_owners()
        self._time_ns = 0
        self._command_time_ns = 0
        self._in_contact = False
        self._clearance = self._floor.clearance(world.robot_start)[0]
        client = pybullet.connect(pybullet.GUI if gui else pybullet.DIRECT)
        if client < 0:
            raise RuntimeError('cannot start pybullet' + (
                ' with a GUI: is there a display, and no other pybullet window?' if gui else ''))
        self.physics_client = client
        self._finalizer = weakref.finalize(self, _disconnect, client)
        bullet = bullet or BulletOptions()
        self.bodies = build_scene(client, world.shapes(), floor_size=world.floor_size,
                                  meshes=bullet.collision_meshes, visuals=gui)
        self._lidar = Lidar(client, config, np.random.default_rng(seed),
                            threads=bullet.ray_threads)
        self.viewer = Viewer(client, world.robot.shapes, draw_rays) if gui else None
        if self.viewer is not None:
            self.viewer.show_robot(self._drive.pose)

    @property
    def time(self) -> float:
        """Return the simulation time in s."""
        return self._time_ns / 1e9

    @property
    def time_ns(self) -> int:
        """Return the simulation time (ns), exact."""
        return self._time_ns

    @property
    def pose(self) -> tuple[float, float, float]:
        """Return the robot's ground-truth pose: x (m), y (m), yaw (rad) in the world."""
        return self._drive.pose

    @property
    def velocity(self) -> tuple[float, float]:
        """Return the velocity the robot achieved: v (m/s) forward, w (rad/s) counter-clockwise."""
        return self._drive.velocity

    @property
    def command(self) -> tuple[float, float]:
        """Return the command in force (after clamping): v (m/s), w (rad/s)."""
        return self._drive.command

    @property
    def in_contact(self) -> bool:
        """Return whether the robot is touching an obstacle now."""
        return self._in_contact

    def set_command(self, linear: float, angular: float) -> str | None:
        """
        Command forward speed (m/s) and turn rate (rad/s) until the next command.

        Returns a warning text when the command was rejected (not finite: the robot is told to
        stop) or clamped to the drive limits, else None.
        """
        self._command_time_ns = self._time_ns
        return self._drive.set_command(linear, angular)

    def step(self, dt: float, substeps: int = 1) -> None:
        """
        Advance the robot and the clock by ``substeps`` physics steps of dt (s) each.

        As that many calls would: one step at a time while one arc cannot drive them (see
        :meth:`in_one_arc`), then the rest in one piece; a trajectory sample after each. A
        robot that cannot reach an obstacle in them (see :meth:`_out_of_reach`) is driven
        through those one-at-a-time steps without collision checks, to the same pose, with
        one sample after them.
        """
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'step needs a positive finite dt in s, got {dt!r}')
        if substeps.__class__ is not int or substeps < 1:
            raise ValueError(f'step needs a whole number of substeps >= 1, got {substeps!r}')
        done = 0
        if substeps > 1 and self.command_timeout is None and not self.in_one_arc() and \
                self._out_of_reach(dt * substeps):
            while done < substeps and not self.in_one_arc():
                self._drive.pose = self._move_clear(dt)
                self._time_ns += round(dt * 1e9)
                done += 1
            self._settle(self._drive.pose, None, self._floor.clearance(self._drive.pose))
        while done < substeps:
            if self.in_one_arc():
                self._step(dt * (substeps - done))
                return
            self._step(dt)
            done += 1

    def in_one_arc(self) -> bool:
        """
        Tell whether one arc drives any number of steps from now as the steps one by one would.

        The drive holds its command's velocity (one arc), or only speeds up or slows down in a
        straight line or turning on the spot (the mean velocity covers the same distance or
        angle). A drive changing its speed while turning, or with a command timeout to keep,
        takes one step at a time.
        """
        (linear, angular), command = self._drive.velocity, self._drive.command
        steady = (linear, angular) == command
        straight_ramp = angular == command[1] == 0.0
        spin_ramp = linear == command[0] == 0.0
        return (steady or straight_ramp or spin_ramp) and self.command_timeout is None

    def _out_of_reach(self, duration: float) -> bool:
        """
        Tell whether no point of the robot can come within RELEASE_DISTANCE of an obstacle.

        Within ``duration`` (s) of driving towards the command: no point moves faster than
        the faster of its velocity now and the command's.
        """
        (linear, angular), command = self._drive.velocity, self._drive.command
        top_speed = self._point_speed(max(abs(linear), abs(command[0])),
                                      max(abs(angular), abs(command[1])))
        return self._clearance - top_speed * duration > RELEASE_DISTANCE

    def _step(self, dt: float) -> None:
        """Advance the robot and the clock by dt (s), with every collision check."""
        if self.command_timeout is not None and \
                self._time_ns - self._command_time_ns > self.command_timeout * 1e9:
            self._drive.set_command(0.0, 0.0)
        pose, blocked_after, nearest = self._move(dt)
        contact_time = self.time + (dt if blocked_after is None else blocked_after)
        self._time_ns += round(dt * 1e9)
        self._settle(pose, blocked_after, nearest, contact_time)

    def _settle(self, pose: tuple[float, float, float], blocked_after: float | None,
                nearest: tuple[float, int], contact_time: float | None = None) -> None:
        """
        Put the robot at ``pose`` (blocked ``blocked_after`` s into the step, or None).

        ``nearest`` is (gap m, index) of the nearest footprint there; a new contact is logged
        at ``contact_time`` (s; default now). Then the trajectory's sample, and the viewer.
        """
        self._drive.pose = pose
        if blocked_after is not None:
            self._drive.halt()
        self._clearance, index = nearest
        if blocked_after is not None or self._clearance <= CONTACT_DISTANCE:
            if not self._in_contact:
                self.collisions.append(Collision(
                    self.time if contact_time is None else contact_time, pose[0], pose[1],
                    self._owners[index]))
            self._in_contact = True
        elif self._clearance > RELEASE_DISTANCE:
            self._in_contact = False
        if self.trajectory is not None:
            self.trajectory.append((self.time, *pose, *self._drive.velocity, self._clearance))
        if self.viewer is not None:
            self.viewer.show_robot(pose)

    def _move(self, dt: float) -> tuple[tuple[float, float, float], float | None,
                                        tuple[float, int]]:
        """
        Return the robot's pose after dt (s) of driving, when (s) it was blocked, or None.

        And (gap m, index) of the nearest obstacle footprint to that pose. The move is checked
        in pieces short enough not to jump over a thin wall.
        """
        linear, angular = self._drive.accelerate(dt)
        pose = self._drive.pose
        floor = self._floor
        pieces, piece = self._pieces(linear, angular, dt)
        for index in range(pieces):
            candidate = integrate_arc(pose, linear, angular, piece)
            gap, nearest, clear = floor.probe(candidate)
            if clear:
                pose = candidate
                continue
            free = self._last_free_fraction(pose, linear, angular, piece)
            stop = integrate_arc(pose, linear, angular, free * piece)
            blocked_after = (index + free) * piece
            if floor.round:
                # A round robot turns freely in contact: it keeps turning for the rest of the
                # step.
                stop = (stop[0], stop[1], wrap_angle(stop[2] + angular * (dt - blocked_after)))
            return stop, blocked_after, floor.clearance(stop)
        if not floor.round:
            gap, nearest = floor.clearance(pose)
        return pose, None, (gap, nearest)

    def _move_clear(self, dt: float) -> tuple[float, float, float]:
        """Return the robot's pose after dt (s) of driving where nothing can block it."""
        linear, angular = self._drive.accelerate(dt)
        pose = self._drive.pose
        pieces, piece = self._pieces(linear, angular, dt)
        for _ in range(pieces):  # in the pieces of _move: the same pose to the last bit
            pose = integrate_arc(pose, linear, angular, piece)
        return pose

    def _pieces(self, linear: float, angular: float, dt: float) -> tuple[int, float]:
        """Return how many pieces a move at (v m/s, w rad/s) for dt s is checked in, and each s."""
        longest = MAX_MOVE_PER_CHECK * self._floor.inscribed_radius
        pieces = max(1, math.ceil(self._point_speed(linear, angular) * dt / longest))
        return pieces, dt / pieces

    def _point_speed(self, linear: float, angular: float) -> float:
        """Return the top speed (m/s) of any point of the robot's outline at (v, w)."""
        if self._floor.round:
            return abs(linear)
        return abs(linear) + self._floor.robot_radius * abs(angular)

    def _last_free_fraction(self, pose: tuple[float, float, float], linear: float,
                            angular: float, dt: float) -> float:
        """
        Return the largest fraction of the move (pose, v, w, dt) that keeps the robot free.

        Conservative advancement first: no point of the robot moves farther than its top speed
        times dt, so advancing by the current gap never overshoots the contact (exact in one
        or two steps head-on, and free when already touching); bisection finishes grazing
        approaches.
        """
        probe = self._floor.probe
        length = self._point_speed(linear, angular) * dt
        free = 0.0
        gap = probe(pose)[0]
        for _ in range(CONTACT_ADVANCES):
            if gap <= CONTACT_RESOLUTION:
                return free
            trial_fraction = free + gap / length
            if trial_fraction >= 1.0:
                break
            trial_gap, _, clear = probe(integrate_arc(pose, linear, angular,
                                                      trial_fraction * dt))
            if not clear:
                break
            free, gap = trial_fraction, trial_gap
        blocked = 1.0
        while (blocked - free) * length > CONTACT_RESOLUTION:
            middle = 0.5 * (free + blocked)
            if probe(integrate_arc(pose, linear, angular, middle * dt))[2]:
                free = middle
            else:
                blocked = middle
        return free

    def scan(self) -> LaserScanData:
        """Return a lidar scan from the robot's current pose, stamped with the current time."""
        scan = self._lidar.scan(self._drive.pose, self.time)
        if self.viewer is not None:
            starts, ends = self._lidar.ray_segments(self._drive.pose, scan.ranges)
            self.viewer.show_scan(starts, ends, np.isfinite(scan.ranges))
        return scan

    def clearance(self) -> float:
        """Return the distance (m) from the robot's body to the nearest obstacle outline."""
        return self._clearance

    def close(self) -> None:
        """Disconnect from pybullet; the simulator cannot scan afterwards."""
        self._finalizer()

    def __enter__(self) -> 'Simulator':
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def _disconnect(client: int) -> None:
    if pybullet.isConnected(physicsClientId=client):
        pybullet.disconnect(physicsClientId=client)
