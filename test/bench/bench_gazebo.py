"""
Gazebo's own robots in Gazebo's own worlds: acceptance runs and speed, in one sitting.

Reads ``../shared/gazebo_assets`` in place (see its README; nothing is copied), with Gazebo
Sim's model folders on ``GZ_SIM_RESOURCE_PATH`` and Classic's on ``GAZEBO_MODEL_PATH``, as their
users set them, and prints:

1. each TurtleBot3 (Burger and Waffle, the Sim and the Classic files) in its generation's
   ``turtlebot3_world.world``, spawned where ROBOTIS's launch file spawns it, driven by the
   lab's ``wanderbot`` for ``--duration`` simulated seconds (default 120), recorded: collisions,
   distance driven, and the /scan messages of the bag (how many, ranges per scan, frames);
2. a Burger driven under ``cafe_table``'s top (beside its pedestal) and the construction cone's
   floor size as its SDF's ``<scale>`` makes it;
3. the load time of ``turtlebot3_world.world``; the real-time factor of the Burger run; and the
   real-time factor of the 600 s recorded ``wall_follow`` run in ``wall_follow_box`` (36 beams)
   with this checkout and, with ``--compare CHECKOUT``, another checkout of the project (e.g. a
   ``git worktree`` of the commit before a change), side by side.

``--speed`` measures only the two real-time factors, side by side in one sitting: the Burger
(Sim files) in turtlebot3_world.world with wanderbot (360 beams, meshes, recorded) and the lab
robot's recorded wall_follow in wall_follow_box; the issue's bar is 50x for the Burger. With
``--compare CHECKOUT`` both runs are measured with each checkout's code too, alternately,
``--repeat`` times (default 1); each figure is the best of its repeats. The node's sandbox
must be able to read CHECKOUT: put it inside the venv (``git worktree add .venv/base main``),
whose folder every run sees; elsewhere (/tmp) its node fails to import ``scan_pkg``.

Run: python test/bench/bench_gazebo.py [--assets DIR] [--duration S] [--compare CHECKOUT]
     [--speed [--repeat N]]
"""

import argparse
import math
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores

from sim_bridge.common.run_environment import environment_set
from sim_bridge.runner.run import run_simulation
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World

ROOT = Path(__file__).resolve().parents[2]
ASSETS = ROOT.parent / 'shared' / 'gazebo_assets'
#: Where ROBOTIS's turtlebot3_world launch file spawns the robot (x m, y m, yaw rad).
SPAWN = (-2.0, -0.5, 0.0)
GENERATIONS = {'Sim': ('turtlebot3_gazebo_sim', 'GZ_SIM_RESOURCE_PATH'),
               'Classic': ('turtlebot3_gazebo_classic', 'GAZEBO_MODEL_PATH')}
#: Measures the real-time factor of the recorded wall_follow run in any checkout's code.
WALL_FOLLOW_RTF = """
import sys, tempfile, time
from sim_bridge.runner.run import run_simulation
with tempfile.TemporaryDirectory() as out:
    start = time.perf_counter()
    run_simulation('wall_follow_box', ['wall_follow'], duration_s=float(sys.argv[1]), seed=1,
                   out_dir=out, quiet=True, plot=False)
    print(float(sys.argv[1]) / (time.perf_counter() - start))
"""
#: Measures the real-time factor of the recorded Burger wanderbot run in any checkout's code
#: (the world file and model paths come as arguments and in the environment).
BURGER_RTF = """
import sys, tempfile, time
from sim_bridge.runner.run import run_simulation
with tempfile.TemporaryDirectory() as out:
    start = time.perf_counter()
    run_simulation(sys.argv[2], ['wanderbot'], duration_s=float(sys.argv[1]), seed=1,
                   start=(-2.0, -0.5, 0.0), robot='turtlebot3_burger', out_dir=out,
                   quiet=True, plot=False)
    print(float(sys.argv[1]) / (time.perf_counter() - start))
"""


def model_paths(assets: Path, generation: str) -> dict[str, str]:
    """Return the environment that finds one generation's TurtleBot3 and the shared models."""
    folder, variable = GENERATIONS[generation]
    return {variable: os.pathsep.join((str(assets / folder / 'models'),
                                       str(assets / 'gazebo_models')))}


def scans_in(bag: Path) -> tuple[int, set[int], set[str]]:
    """Return the /scan messages of a bag: how many, their range counts and frames."""
    store = get_typestore(Stores.ROS2_JAZZY)
    counts, frames, total = set(), set(), 0
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic == '/scan']
        for connection, _, data in reader.messages(connections=connections):
            scan = store.deserialize_cdr(data, connection.msgtype)
            total += 1
            counts.add(len(scan.ranges))
            frames.add(scan.header.frame_id)
    return total, counts, frames


def drive_turtlebots(assets: Path, duration_s: float) -> float | None:
    """Print the wanderbot runs; return the Burger's (Sim) real-time factor."""
    print(f'1. wanderbot {duration_s:g} s in turtlebot3_world.world from {SPAWN}')
    print('   robot             files    collisions  driven m  scans  ranges  frames  x real time')
    burger_factor = None
    for generation in GENERATIONS:
        world_file = assets / GENERATIONS[generation][0] / 'worlds' / 'turtlebot3_world.world'
        paths_of_generation = model_paths(assets, generation)
        for robot in ('turtlebot3_burger', 'turtlebot3_waffle'):
            with tempfile.TemporaryDirectory() as out, environment_set(paths_of_generation):
                start = time.perf_counter()
                result = run_simulation(str(world_file), ['wanderbot'], duration_s=duration_s,
                                        seed=1, start=SPAWN, robot=robot, out_dir=out,
                                        quiet=True, plot=False)
                rtf = duration_s / (time.perf_counter() - start)
                total, counts, frames = scans_in(Path(out) / 'run')
            metrics = result.metrics
            if (robot, generation) == ('turtlebot3_burger', 'Sim'):
                burger_factor = rtf
            print(f'   {robot:<17} {generation:<8} {metrics["collisions"]:>10}  '
                  f'{metrics["distance_m"]:>8.2f}  {total:>5}  '
                  f'{",".join(map(str, sorted(counts))):>6}  {",".join(sorted(frames)):>6}  '
                  f'{rtf:>10.1f}')
    return burger_factor


def under_the_table_and_the_cone(assets: Path) -> None:
    """Print a Burger's run under cafe_table's top and the cone's floor size."""
    with tempfile.TemporaryDirectory() as folder, environment_set(model_paths(assets, 'Sim')):
        world_file = Path(folder) / 'cafe.yaml'
        # The table's centre 0.42 m to the robot's left: under its top (0.913 m square), clear
        # of its base plate (0.56 m square, 4 cm high) and column.
        world_file.write_text('robot: {model: turtlebot3_burger, pose: [-1.0, 0.0, 0.0]}\n'
                              'obstacles:\n'
                              '  - {name: table, type: model, model: cafe_table, '
                              'pose: [0.0, 0.42, 0.0]}\n'
                              '  - {name: cone, type: model, model: construction_cone, '
                              'pose: [3.0, 3.0, 0.0]}\n')
        world = World.load(world_file)
        with Simulator(world) as sim:
            sim.set_command(0.2, 0.0)
            for _ in range(1000):
                sim.step(0.01)
            print(f'2. Burger under cafe_table: drove to x = {sim.pose[0]:.2f} m (from -1.00), '
                  f'{len(sim.collisions)} collisions, clearance {sim.clearance():.3f} m')
        table_top = max(shape.z_range()[1] for shape in world.obstacle('table').shapes)
        print(f'   the table top is {table_top:.3f} m up, the Burger '
              f'{max(shape.z_range()[1] for shape in world.robot.shapes):.3f} m tall')
        cone = world.obstacle('cone').footprints
        xs = [x for footprint in cone for x, _ in footprint.outline()]
        print(f'   construction_cone: {max(xs) - min(xs):.3f} m across at the floor '
              "(its DAE is 1.98 inches across, scaled by the SDF's <scale>)")


def load_time(assets: Path) -> None:
    """Print how long turtlebot3_world.world takes to load (best of 3)."""
    world_file = assets / 'turtlebot3_gazebo_sim' / 'worlds' / 'turtlebot3_world.world'
    with environment_set(model_paths(assets, 'Sim')):
        best = math.inf
        for _ in range(3):
            start = time.perf_counter()
            World.load(world_file, robot='turtlebot3_burger', robot_pose=SPAWN)
            best = min(best, time.perf_counter() - start)
    print(f'3. load of turtlebot3_world.world with the Burger: {best * 1000:.0f} ms (best of 3)')


def checkout_rtf(script: str, checkout: Path, arguments: list[str],
                 environment: dict[str, str] | None = None) -> float:
    """Return the real-time factor ``script`` prints, run with ``checkout``'s code."""
    pythonpath = os.pathsep.join((str(checkout / 'sim_bridge'), str(checkout / 'scan_pkg')))
    output = subprocess.run([sys.executable, '-c', script, *arguments],
                            env={**os.environ, **(environment or {}), 'PYTHONPATH': pythonpath},
                            check=True, capture_output=True, text=True).stdout
    return float(output.split()[-1])


def wall_follow_rtf(checkout: Path, duration_s: float) -> float:
    """Return the real-time factor of the recorded wall_follow run with ``checkout``'s code."""
    return checkout_rtf(WALL_FOLLOW_RTF, checkout, [str(duration_s)])


def burger_rtf(assets: Path, checkout: Path, duration_s: float) -> float:
    """Return the real-time factor of the recorded Burger wanderbot run in turtlebot3_world."""
    world_file = assets / 'turtlebot3_gazebo_sim' / 'worlds' / 'turtlebot3_world.world'
    return checkout_rtf(BURGER_RTF, checkout, [str(duration_s), str(world_file)],
                        model_paths(assets, 'Sim'))


def speed(assets: Path, duration_s: float, compare: Path | None, repeat: int) -> None:
    """Print the Burger's and the lab robot's real-time factors, measured one after the other."""
    checkouts = [('this checkout', ROOT)] + ([(str(compare), compare.resolve())]
                                             if compare is not None else [])
    best = {}
    for _ in range(repeat):
        for name, checkout in checkouts:
            figures = (burger_rtf(assets, checkout, duration_s),
                       wall_follow_rtf(checkout, duration_s))
            best[name] = tuple(map(max, zip(best.get(name, figures), figures)))
    for name, (burger, lab) in best.items():
        print(f'{name}:')
        print(f'  Burger, turtlebot3_world, wanderbot, 360 beams, recorded, {duration_s:g} s: '
              f'{burger:.1f}x real time (bar: 50x)')
        print(f'  lab robot, wall_follow_box, wall_follow, 36 beams, recorded, {duration_s:g} s: '
              f'{lab:.1f}x real time')
        print(f'  Burger / lab robot: {burger / lab:.2f}')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--assets', type=Path, default=ASSETS)
    parser.add_argument('--duration', type=float, default=120.0)
    parser.add_argument('--compare', type=Path, metavar='CHECKOUT')
    parser.add_argument('--speed', action='store_true',
                        help='only the two real-time factors, side by side')
    parser.add_argument('--repeat', type=int, default=1,
                        help='with --speed: measure each figure this many times, keep the best')
    args = parser.parse_args()
    if not args.assets.is_dir():
        print(f'no assets folder at {args.assets}; nothing to run')
        return 0
    if args.speed:
        speed(args.assets, args.duration, args.compare, args.repeat)
        return 0
    burger_factor = drive_turtlebots(args.assets, args.duration)
    under_the_table_and_the_cone(args.assets)
    load_time(args.assets)
    print(f'   Burger in turtlebot3_world (360 beams, meshes), recorded: {burger_factor:.1f}x '
          'real time')
    checkouts = [('this checkout', ROOT)]
    if args.compare is not None:
        checkouts.append((str(args.compare), args.compare.resolve()))
    figures = [(name, wall_follow_rtf(path, 600.0)) for name, path in checkouts]
    for name, rtf in figures:
        print(f'   wall_follow 600 s in wall_follow_box, 36 beams, recorded ({name}): '
              f'{rtf:.1f}x real time')
    if len(figures) == 2:
        print(f'   ratio this / compared: {figures[0][1] / figures[1][1]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
