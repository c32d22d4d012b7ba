"""
Benchmark the stepped runner on real rclpy: real-time factor of a wall-follow run, per stage.

Runs ``sim_bridge.runner.run.run_simulation`` on ``wall_follow_box`` with the ``wall_follow`` node
for 600 simulated seconds (the goal: at least 100x real time with 36 beams, 50x with 1081,
recorded), the beam count set by the bridge's ``lidar_samples`` parameter, and prints side by side,
in one process and one sitting:

1. the pure simulator alone (physics at 100 Hz and a 10 Hz scan, no rclpy), and the runner with
   recording off and on, at 36 and 1081 beams (best of ``--repeats``; plot off);
2. variants at 36 beams, recorded: /clock published every physics step instead of only with a
   message a node hears or when a node's timer is due, and ``rclpy.experimental.EventsExecutor``
   instead of the SingleThreadedExecutor (it has no exact "nothing is ready": it gets a fixed
   number of ``spin_once(timeout_sec=0)`` per step, and the table says whether its runs are
   complete and repeatable: same bag as the kept configuration, twice);
3. unless ``--no-breakdown``, the share of each stage in a run's wall time (exclusive time):
   simulator step (robot, collisions, trace), lidar, the bridge building its messages, rclpy
   (publish, delivery, the executor's waits: the rest of the run, with set-up), the wall_follow
   node's callback, recording (serialise and write) and metrics.

Run: python test/bench/bench_runner.py [--duration S] [--repeats N] [--no-breakdown]
"""

import argparse
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path
import tempfile
import time

import rclpy.executors
from rclpy.experimental import EventsExecutor

from scan_pkg.wall_follow import WallFollow
from sim_bridge.common.paths import find_world
from sim_bridge.ros.bridge import SimBridge
from sim_bridge.runner import run
from sim_bridge.runner.record import BagRecorder
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World

WORLD = 'wall_follow_box'
NODE = 'wall_follow'
SEED = 1
BEAMS = (36, 1081)
GOALS = {36: 100.0, 1081: 50.0}
PHYSICS_RATE, SCAN_RATE = 100, 10
EVENTS_SPINS_PER_STEP = 4
STAGES = ('simulator step', 'lidar', 'bridge messages', 'rclpy + setup', 'wall_follow node',
          'recording', 'metrics')


class StageTimer:
    """Accumulate the exclusive wall time (s) spent in wrapped functions, per stage."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self._nested: list[float] = []
        self._patches: list[tuple[object, str, object]] = []

    def wrap(self, owner: object, name: str, stage: str) -> None:
        """Replace ``owner.name`` (a function or method) by a timed one, until ``restore``."""
        original = owner.__dict__[name]
        nested = self._nested
        seconds = self.seconds
        clock = time.perf_counter

        def timed(*args, **kwargs):
            start = clock()
            nested.append(0.0)
            try:
                return original(*args, **kwargs)
            finally:
                elapsed = clock() - start
                seconds[stage] += elapsed - nested.pop()
                if nested:
                    nested[-1] += elapsed

        self._patches.append((owner, name, original))
        setattr(owner, name, timed)

    def restore(self) -> None:
        """Put every wrapped function back."""
        for owner, name, original in reversed(self._patches):
            setattr(owner, name, original)
        self._patches.clear()


@contextmanager
def patched(owner: object, name: str, value: object):
    """Set ``owner.name`` to ``value`` while the block runs."""
    original = getattr(owner, name)
    setattr(owner, name, value)
    try:
        yield
    finally:
        setattr(owner, name, original)


@contextmanager
def clock_every_step():
    """Make the runner publish /clock every physics step (a node timer always due)."""
    with patched(run, 'next_timer_ns', lambda nodes: 0):
        yield


@contextmanager
def events_executor():
    """Run with rclpy's EventsExecutor, spun a fixed number of times after each step."""
    def spin(executor) -> int:
        for _ in range(EVENTS_SPINS_PER_STEP):
            executor.spin_once(timeout_sec=0)
        return EVENTS_SPINS_PER_STEP

    def make(*, context=None):
        return EventsExecutor(context=context)
    with patched(rclpy.executors, 'SingleThreadedExecutor', make), \
            patched(run, 'spin_until_idle', spin):
        yield


@contextmanager
def timed_stages():
    """Time the runner's stages (see the module text) while the block runs; yield the timer."""
    timer = StageTimer()
    for owner, name, stage in (
            (Simulator, 'step', 'simulator step'), (Simulator, 'scan', 'lidar'),
            (SimBridge, 'step', 'bridge messages'), (SimBridge, 'on_cmd_vel', 'bridge messages'),
            (WallFollow, 'on_scan', 'wall_follow node'),
            (run.RunRecorder, 'on_bridge_message', 'recording'),
            (BagRecorder, 'write', 'recording'), (run, 'compute_metrics', 'metrics')):
        timer.wrap(owner, name, stage)
    try:
        yield timer
    finally:
        timer.restore()


def run_once(beams: int, record: bool, duration_s: float, folder: Path) -> float:
    """Run the benchmark's simulation; return its wall time (s)."""
    start = time.perf_counter()
    result = run.run_simulation(WORLD, [NODE], duration_s=duration_s, seed=SEED,
                                params={run.BRIDGE_NODE: {'lidar_samples': beams}},
                                out_dir=folder, quiet=True, record=record, plot=False)
    wall_s = time.perf_counter() - start
    if not result.ok:
        raise RuntimeError(f'the benchmark run failed: {result.metrics["node_errors"]}')
    return wall_s


def simulator_alone(beams: int, duration_s: float) -> float:
    """Step the pure simulator as the bridge does (no rclpy); return the wall time (s)."""
    world = World.load(find_world(WORLD))
    start = time.perf_counter()
    sim = Simulator(world, seed=SEED, lidar_samples=beams)
    try:
        sim.set_command(0.3, -0.2)
        for step in range(1, round(duration_s * PHYSICS_RATE) + 1):
            sim.step(1.0 / PHYSICS_RATE)
            if step % (PHYSICS_RATE // SCAN_RATE) == 0:
                sim.scan()
                sim.set_command(0.3, -0.2)
    finally:
        sim.close()
    return time.perf_counter() - start


def row(label: str, duration_s: float, wall_s: float, goal: float | None,
        note: str = '') -> None:
    """Print one line of a table."""
    factor = duration_s / wall_s
    verdict = '' if goal is None else f"{goal:>5.0f}x {'met' if factor >= goal else 'MISSED'}"
    print(f'{label:<44}  {wall_s:>7.2f}  {factor:>10.0f}x  {verdict:<11}  {note}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0, help='simulated s (600)')
    parser.add_argument('--repeats', type=int, default=1, help='timed runs per row (1)')
    parser.add_argument('--no-breakdown', action='store_true', help='skip the stage shares')
    args = parser.parse_args()
    duration = args.duration
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        run_once(BEAMS[0], False, 1.0, folder / 'warm-up')  # imports, type store
        print(f'{duration:g} s of {NODE} in {WORLD} (seed {SEED}), plot off; best of '
              f'{args.repeats}')
        print(f'{"configuration":<44}  {"wall s":>7}  {"x real time":>11}  {"goal":<11}')
        for beams in BEAMS:
            row(f'{beams} beams: pure simulator, no rclpy', duration,
                min(simulator_alone(beams, duration) for _ in range(args.repeats)), None)
            for record in (False, True):
                row(f'{beams} beams: run, recording {"on" if record else "off"}', duration,
                    min(run_once(beams, record, duration, folder / 'run')
                        for _ in range(args.repeats)),
                    GOALS[beams] if record else None)
        run_once(BEAMS[0], True, duration, folder / 'kept')
        kept = (folder / 'kept' / 'run' / 'run.mcap').read_bytes()
        for label, variant in (('36 beams: /clock every physics step', clock_every_step),
                               (f'36 beams: EventsExecutor, {EVENTS_SPINS_PER_STEP} spins a '
                                'step', events_executor)):
            with variant():
                walls = [run_once(BEAMS[0], True, duration, folder / name)
                         for name in ('variant', 'again')]
            bags = [(folder / name / 'run' / 'run.mcap').read_bytes()
                    for name in ('variant', 'again')]
            note = ('same bag as kept, twice' if bags[0] == bags[1] == kept else
                    'repeatable, but not the kept bag' if bags[0] == bags[1] else
                    'NOT repeatable')
            row(label, duration, min(walls), None, note)
        if args.no_breakdown:
            return
        configurations = [(beams, record) for beams in BEAMS for record in (False, True)]
        shares, walls = [], []
        for beams, record in configurations:
            with timed_stages() as timer:
                wall_s = run_once(beams, record, duration, folder / 'timed')
            timer.seconds['rclpy + setup'] += wall_s - sum(timer.seconds.values())
            shares.append({stage: timer.seconds[stage] / wall_s for stage in STAGES})
            walls.append(wall_s)
    print('\nshare of the wall time per stage (instrumented runs)')
    labels = [f'{beams} rec {"on" if record else "off"}' for beams, record in configurations]
    print(f'{"stage":<18}' + ''.join(f'{label:>14}' for label in labels))
    for stage in STAGES:
        print(f'{stage:<18}' + ''.join(f'{share[stage]:>14.0%}' for share in shares))
    print(f'{"(wall s)":<18}' + ''.join(f'{wall_s:>14.2f}' for wall_s in walls))


if __name__ == '__main__':
    main()
