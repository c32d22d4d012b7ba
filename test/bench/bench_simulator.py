"""
Benchmark the simulator core and print the figures, alternatives side by side.

Run: ``python test/bench/bench_simulator.py`` (a few seconds). Measures, in the room world:

1. the per-step collision check: the analytic footprint check the simulator uses against a
   vectorised numpy variant and pybullet's getClosestPoints / getContactPoints;
2. one ray cast batch at 36, 360 and 1081 beams: meshes (used) against pybullet primitives,
   Python lists against numpy arrays as input, numThreads 1 against 0 (Bullet's choice; used
   from lidar.THREADED_FROM_BEAMS beams on), and the ways to turn pybullet's result tuples
   into an array;
3. Simulator.step and Simulator.scan, and the real-time factor of stepping the robot at
   100 Hz with a 10 Hz scan at 36 and 1081 beams (goal: >= 500x and >= 100x).

Figures are the best of a few repeats (the least disturbed by other processes).
"""

from dataclasses import replace
from operator import itemgetter
import time
import timeit

import numpy as np
import pybullet

from sim_bridge.simulation.geometry import FootprintSet
from sim_bridge.simulation.lidar import build_scene, Lidar
from sim_bridge.simulation.simulator import BulletOptions, Simulator
from sim_bridge.simulation.world import World

WORLD = 'room'
BEAM_COUNTS = (36, 360, 1081)


def best_us(function, number: int, repeat: int = 3) -> float:
    """Return the best time of one call (µs) over ``repeat`` runs of ``number`` calls."""
    return min(timeit.repeat(function, number=number, repeat=repeat)) / number * 1e6


def path_points(count: int) -> list[tuple[float, float]]:
    """Return robot positions on a loop through the room's free space (m)."""
    angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return [(float(3.2 * np.cos(a)), float(2.3 * np.sin(a))) for a in angles]


def bench_collision_check(world: World) -> None:
    print(f'\n1. Collision check per step ({len(world.footprints())} footprints), µs per check')
    points = path_points(500)
    footprints = FootprintSet(world.footprints())
    radius = world.robot.radius

    def analytic() -> None:
        for x, y in points:
            footprints.nearest(x, y)

    def vectorised() -> None:
        for x, y in points:
            footprints.distance(np.array((x, y)))

    client = pybullet.connect(pybullet.DIRECT)
    bodies = build_scene(client, world.shapes(), floor_size=world.floor_size)[1:]
    shape = pybullet.createCollisionShape(pybullet.GEOM_CYLINDER, radius=radius, height=0.15,
                                          physicsClientId=client)
    robot = pybullet.createMultiBody(0.0, shape, basePosition=(0.0, 0.0, 0.1),
                                     physicsClientId=client)

    def closest_points() -> None:
        for x, y in points:
            pybullet.resetBasePositionAndOrientation(robot, (x, y, 0.1), (0, 0, 0, 1),
                                                     physicsClientId=client)
            for body in bodies:
                pybullet.getClosestPoints(robot, body, 0.0, physicsClientId=client)

    def contact_points() -> None:
        for x, y in points:
            pybullet.resetBasePositionAndOrientation(robot, (x, y, 0.1), (0, 0, 0, 1),
                                                     physicsClientId=client)
            pybullet.performCollisionDetection(physicsClientId=client)
            pybullet.getContactPoints(robot, physicsClientId=client)

    rows = [('analytic FootprintSet.nearest, pure Python (used)', analytic),
            ('analytic FootprintSet.distance, numpy, 1 point', vectorised),
            ('pybullet getClosestPoints, robot vs each body', closest_points),
            ('pybullet performCollisionDetection + getContactPoints', contact_points)]
    for label, function in rows:
        print(f'   {label:62s} {best_us(function, 2) / len(points):8.2f}')
    pybullet.disconnect(client)


def bench_ray_casts(world: World) -> None:
    print('\n2. One batch of rays from the room centre, µs per batch')
    pose = (0.0, -0.5, 0.3)
    clients = {}
    for meshes in (True, False):
        clients[meshes] = pybullet.connect(pybullet.DIRECT)
        build_scene(clients[meshes], world.shapes(), floor_size=world.floor_size,
                    meshes=meshes)
    header = ''.join(f'{count:>10d}' for count in BEAM_COUNTS)
    print(f'   {"beams:":58s}{header}')
    rows = {}
    for count in BEAM_COUNTS:
        config = replace(world.robot.lidar, samples=count, noise_stddev=0.0)
        lidar = Lidar(clients[True], config, np.random.default_rng(0))
        origin = lidar.origin(pose)
        starts_list = [origin] * count
        starts_array = np.tile(origin, (count, 1))
        cos_yaw, sin_yaw = np.cos(pose[2]), np.sin(pose[2])
        reach = lidar._reach
        ends = np.column_stack((origin[0] + cos_yaw * reach[:, 0] - sin_yaw * reach[:, 1],
                                origin[1] + sin_yaw * reach[:, 0] + cos_yaw * reach[:, 1],
                                origin[2] + reach[:, 2]))
        ends_list = ends.tolist()
        number = max(5, 6000 // count)

        def cast(client, starts, stops, threads=1):
            return lambda: pybullet.rayTestBatch(starts, stops, numThreads=threads,
                                                 physicsClientId=client)

        results = pybullet.rayTestBatch(starts_list, ends_list, physicsClientId=clients[True])
        fraction = itemgetter(2)
        measured = [
            ('meshes, numpy arrays in, numThreads=1 (used below 100 beams)',
             cast(clients[True], starts_array, ends)),
            ('meshes, lists in (conversion not counted)',
             cast(clients[True], starts_list, ends_list)),
            ('meshes, list of starts with an array of ends',
             cast(clients[True], starts_list, ends)),
            ('meshes, numpy arrays in, numThreads=0 (used from 100 beams)',
             cast(clients[True], starts_array, ends, threads=0)),
            ('pybullet primitives, numpy arrays in',
             cast(clients[False], starts_array, ends)),
            ('  conversion for lists: ends.tolist()', ends.tolist),
            ('  result: np.fromiter(map(itemgetter(2), r), float, n) (used)',
             lambda: np.fromiter(map(fraction, results), float, count)),
            ('  result: the same, dtype= and count= as keywords',
             lambda: np.fromiter(map(fraction, results), dtype=float, count=count)),
            ('  result: np.array([r[2] for r in ...])',
             lambda: np.array([r[2] for r in results])),
            ('  result: np.array(results, dtype=object)[:, 2]',
             lambda: np.array(results, dtype=object)[:, 2].astype(float)),
            ('Lidar.true_ranges: noise-free distances', lambda: lidar.true_ranges(pose)),
            ('Lidar.scan: whole scan incl. noise (used)', lambda: lidar.scan(pose)),
        ]
        for label, function in measured:
            rows.setdefault(label, []).append(best_us(function, number))
    for label, values in rows.items():
        print(f'   {label:62s}' + ''.join(f'{value:10.1f}' for value in values))
    for client in clients.values():
        pybullet.disconnect(client)


def real_time_factor(world: World, beams: int, seconds: float, command: tuple[float, float],
                     **options) -> tuple[float, float, float, int]:
    """
    Drive ``world`` at 100 Hz with a 10 Hz scan for ``seconds`` (s) of simulated time.

    Returns sim seconds per wall second, µs per step, µs per scan and the collision count.
    """
    simulator = Simulator(world, lidar_samples=beams, **options)
    simulator.set_command(*command)
    steps_per_scan = 10
    scans = 0
    step_time = scan_time = 0.0
    started = time.perf_counter()
    for index in range(int(seconds * 100)):
        before = time.perf_counter()
        simulator.step(0.01)
        after = time.perf_counter()
        step_time += after - before
        if index % steps_per_scan == 0:
            simulator.scan()
            scan_time += time.perf_counter() - after
            scans += 1
    wall = time.perf_counter() - started
    simulator.close()
    return (seconds / wall, step_time / (seconds * 100) * 1e6, scan_time / scans * 1e6,
            len(simulator.collisions))


def bench_real_time(world: World) -> None:
    print('\n3. Stepping at 100 Hz with a 10 Hz scan; best of 3 runs of 10 sim s per row')
    print('   circling: a collision-free 0.5 m circle (v 0.25 m/s, w 0.5 rad/s); pushing: '
          'driving into the east wall and on against it (v 1 m/s)')
    print(f'   {"":48s}{"x real time":>12s}{"µs/step":>9s}{"µs/scan":>9s}{"hits":>6s}')
    circling = (0.25, 0.5)
    pushing = (1.0, 0.0)
    rows = [(36, 500, 'circling (used: numThreads=1)', circling, {}),
            (36, 500, 'circling, numThreads=0', circling,
             {'bullet': BulletOptions(ray_threads=0)}),
            (36, 500, 'circling, pybullet primitives', circling,
             {'bullet': BulletOptions(collision_meshes=False)}),
            (36, 500, 'pushing against a wall', pushing, {}),
            (1081, 100, 'circling (used: numThreads=0)', circling, {}),
            (1081, 100, 'circling, numThreads=1', circling,
             {'bullet': BulletOptions(ray_threads=1)}),
            (1081, 100, 'circling, pybullet primitives', circling,
             {'bullet': BulletOptions(collision_meshes=False)})]
    for beams, goal, label, command, options in rows:
        factor, step, scan, hits = max(real_time_factor(world, beams, 10.0, command, **options)
                                       for _ in range(3))
        print(f'   {beams:4d} beams, {label:36s} goal {goal:3d}x{factor:9.0f}x'
              f'{step:9.1f}{scan:9.1f}{hits:6d}')


def main() -> None:
    world = World.load(WORLD)
    print(f"Simulator benchmark, world '{world.name}'")
    bench_collision_check(world)
    bench_ray_casts(world)
    bench_real_time(world)


if __name__ == '__main__':
    main()
