"""
The simulator alone with TurtleBot3 Burger in turtlebot3_world: its cost per simulated second.

Run: ``python test/bench/bench_burger_simulator.py [--duration S] [--repeat N]
[--compare CHECKOUT]`` (about 10 s per run of the default 300 simulated s).

The case of issue 26's speed point without ROS: Burger (the Gazebo Sim files in
``../shared/gazebo_assets``, read in place) in ``turtlebot3_world.world``, spawned at ROBOTIS's
(-2, -0.5, 0), its 360-beam 5 Hz lidar, 1 ms physics. The :class:`~sim_bridge.simulation.
simulator.Simulator` is stepped as the bridge steps it under the runner: one
``step(0.001, n)`` to each next event of a 20 Hz wanderbot command, 50 Hz odometry and the
5 Hz scan (60 calls per simulated second), a scan when one is due; the drive's limits are the
Burger plugin's (the wanderbot's 0.5 m/s is not capped). The commands come from
scan_pkg's wanderbot core (:class:`scan_pkg.behaviors.wander.Wanderer`) fed with the scans
and the yaw, so the run is the wanderbot's own, and the same command sequence as long as the
simulator's behaviour is unchanged: the fingerprint printed (a hash of every pose, range and
collision) says whether it was.

Prints ms of Simulator.step and of Simulator.scan per simulated second, us per call, and the
simulator's own real-time factor, all in CPU time of the process (pybullet's ray threads
included): on a machine shared with other work, time spent waiting for a processor would
count in wall time. ``--compare CHECKOUT`` runs the same script's measurement
with another checkout's ``sim_bridge`` and ``scan_pkg`` (e.g. ``git worktree add /tmp/base
main``), alternately, ``--repeat`` times (default 3); each figure is the best of its repeats.
"""

import argparse
import hashlib
import json
import os
from pathlib import Path
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parents[2]
#: ../shared/gazebo_assets from the main checkout or a worktree beside it.
ASSETS = next((folder / 'shared' / 'gazebo_assets' for folder in ROOT.parents
               if (folder / 'shared' / 'gazebo_assets').is_dir()),
              ROOT.parent / 'shared' / 'gazebo_assets')
#: Where ROBOTIS's turtlebot3_world launch file spawns the robot (x m, y m, yaw rad).
SPAWN = (-2.0, -0.5, 0.0)
#: Physics step (s) of turtlebot3_world.world (<max_step_size>).
STEP_S = 0.001
#: The wanderbot's command rate (Hz; params/wanderbot.yaml).
COMMAND_RATE = 20


def environment(assets: Path) -> dict[str, str]:
    """Return the model path that finds the Sim generation's TurtleBot3 and the shared models."""
    return {'GZ_SIM_RESOURCE_PATH': os.pathsep.join((
        str(assets / 'turtlebot3_gazebo_sim' / 'models'), str(assets / 'gazebo_models')))}


def event_steps(duration_s: float, rates: tuple[float, ...]) -> list[int]:
    """Return the physics steps (1 ms each) at which something at ``rates`` (Hz) is due."""
    steps_per_second = round(1.0 / STEP_S)
    return sorted({-(-index * steps_per_second // rate)
                   for rate in rates for index in range(1, int(duration_s * rate) + 1)})


def measure(assets: Path, duration_s: float) -> dict:
    """Drive the Burger for ``duration_s`` simulated s; return the figures and a fingerprint."""
    os.environ.update(environment(assets))
    from scan_pkg.behaviors.wander import Wanderer
    from scan_pkg.laser import Scan
    from sim_bridge.simulation.simulator import Simulator
    from sim_bridge.simulation.world import World

    world_file = assets / 'turtlebot3_gazebo_sim' / 'worlds' / 'turtlebot3_world.world'
    world = World.load(str(world_file), robot='turtlebot3_burger', robot_pose=SPAWN)
    # As the bridge makes it: the drive's limits from the Burger's diff-drive plugin.
    simulator = Simulator(world, seed=1, limits=world.robot.drive.limits)
    simulator.trajectory = []
    scan_rate = round(simulator.lidar_config.update_rate)
    odometry_rate = round(world.robot.drive.odometry_rate)
    steps_per_scan = round(1.0 / STEP_S) // scan_rate
    steps_per_command = round(1.0 / STEP_S) // COMMAND_RATE
    wanderer = Wanderer()
    digest = hashlib.sha256()
    step_s = scan_s = 0.0
    calls = scans = done = 0
    for event in event_steps(duration_s, (COMMAND_RATE, odometry_rate, scan_rate)):
        start = time.process_time()
        simulator.step(STEP_S, event - done)
        step_s += time.process_time() - start
        calls += 1
        done = event
        now = event * STEP_S
        if event % steps_per_scan == 0:
            start = time.process_time()
            scan = simulator.scan()
            scan_s += time.process_time() - start
            scans += 1
            digest.update(scan.ranges.tobytes())
            wanderer.update_scan(Scan(scan.ranges, scan.angle_min, scan.angle_increment,
                                      scan.range_min, scan.range_max), now)
        wanderer.update_odom(simulator.pose[2], now)
        if event % steps_per_command == 0:
            simulator.set_command(*wanderer.command(now))
    digest.update(repr((simulator.trajectory, simulator.collisions)).encode())
    simulator.close()
    return {'step_ms': step_s / duration_s * 1e3, 'scan_ms': scan_s / duration_s * 1e3,
            'step_us': step_s / calls * 1e6, 'scan_us': scan_s / scans * 1e6,
            'calls': calls / duration_s, 'scans': scans / duration_s,
            'collisions': len(simulator.collisions), 'pose': simulator.pose,
            'fingerprint': digest.hexdigest()[:16]}


def measure_in(checkout: Path, assets: Path, duration_s: float) -> dict:
    """Return :func:`measure`'s figures, measured with ``checkout``'s code in a new process."""
    pythonpath = os.pathsep.join((str(checkout / 'sim_bridge'), str(checkout / 'scan_pkg')))
    output = subprocess.run(
        [sys.executable, __file__, '--assets', str(assets), '--duration', str(duration_s),
         '--json'], env={**os.environ, 'PYTHONPATH': pythonpath}, check=True,
        capture_output=True, text=True).stdout
    return json.loads(output.splitlines()[-1])


def best_of(runs: list[dict]) -> dict:
    """Return the first run's figures with each cost the least of the runs'."""
    best = dict(runs[0])
    for key in ('step_ms', 'scan_ms', 'step_us', 'scan_us'):
        best[key] = min(run[key] for run in runs)
    return best


def report(name: str, figures: dict) -> None:
    """Print one checkout's figures."""
    step_ms, scan_ms, pose = figures['step_ms'], figures['scan_ms'], figures['pose']
    total = step_ms + scan_ms
    print(f'{name}:')
    print(f'  Simulator.step  {step_ms:6.2f} CPU ms per sim s ({figures["calls"]:.0f} calls, '
          f'{figures["step_us"]:6.1f} us each)')
    print(f'  Simulator.scan  {scan_ms:6.2f} CPU ms per sim s ({figures["scans"]:.0f} scans, '
          f'{figures["scan_us"]:6.1f} us each)')
    print(f'  together        {total:6.2f} CPU ms per sim s: the simulator alone at '
          f'{1000.0 / total:.0f}x real time')
    print(f'  behaviour: {figures["collisions"]} collisions, final pose ({pose[0]:.6f}, '
          f'{pose[1]:.6f}, {pose[2]:.6f}), fingerprint {figures["fingerprint"]}')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--assets', type=Path, default=ASSETS)
    parser.add_argument('--duration', type=float, default=300.0, help='simulated s per run')
    parser.add_argument('--repeat', type=int, default=3, help='runs per checkout; best counts')
    parser.add_argument('--compare', type=Path, metavar='CHECKOUT')
    parser.add_argument('--json', action='store_true', help='one run, its figures as JSON')
    args = parser.parse_args()
    if not (args.assets / 'turtlebot3_gazebo_sim').is_dir():
        print(f'no TurtleBot3 assets in {args.assets}; nothing to run')
        return 0
    if args.json:
        print(json.dumps(measure(args.assets, args.duration)))
        return 0
    checkouts = [('this checkout', ROOT)]
    if args.compare is not None:
        checkouts.append((str(args.compare), args.compare.resolve()))
    runs = {name: [] for name, _ in checkouts}
    for _ in range(args.repeat):
        for name, checkout in checkouts:
            runs[name].append(measure_in(checkout, args.assets, args.duration))
    print(f'Burger in turtlebot3_world, wanderbot core, 360 beams at 5 Hz, 1 ms physics, '
          f'{args.duration:g} sim s, best of {args.repeat}')
    for name, figures in runs.items():
        report(name, best_of(figures))
    if len(checkouts) == 2:
        (_, this), (_, other) = ((name, best_of(runs[name])) for name, _ in checkouts)
        print(f"this / compared: step {this['step_ms'] / other['step_ms']:.2f}, scan "
              f"{this['scan_ms'] / other['scan_ms']:.2f}; same behaviour: "
              f"{this['fingerprint'] == other['fingerprint']}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
