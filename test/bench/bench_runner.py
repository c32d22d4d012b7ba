"""
Benchmark the lockstep runner: real-time factor of a wall-follow run at 36 and 1081 beams.

Runs ``sim_bridge.run.run_simulation`` on ``wall_follow_box`` with the ``wall_follow`` node for
600 simulated seconds (the issue's goal: at least 500x real time with 36 beams, 100x with
1081), the beam count set by the bridge's ``lidar_samples`` parameter, with the rosbag2
recording off and on, and prints one row per configuration side by side: simulated s, wall s,
x real time (the best of ``--repeats`` runs; the plot is off, as it is a fixed cost after the
run).

Then, unless ``--no-breakdown``, each configuration runs once more with the main stages timed
(exclusive time: a stage's own time without the stages it calls) and the table shows each
stage's share of that run's wall time: the simulator's step (robot, collisions, the trace for
the metrics), the lidar (ray casts, noise), the bridge building its messages, the wall_follow
node, the runner's observer (scans kept for the plot), the recording, the metrics, and
lockstep (publish checks, copies, delivery, timers; the rest of the run, with setup). The
timing wrappers add a little time of their own, so those runs are slower than the first
table's.

Run: python test/bench/bench_runner.py [--duration S] [--repeats N] [--no-breakdown]
"""

import argparse
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path
import tempfile
import time

from sim_bridge import lockstep, run
from sim_bridge.record import BagRecorder
from sim_bridge.simulator import Simulator

WORLD = 'wall_follow_box'
NODE = 'wall_follow'
SEED = 1
BEAMS = (36, 1081)
GOALS = {36: 500.0, 1081: 100.0}
STAGES = ('simulator step', 'lidar', 'bridge messages', 'wall_follow node', 'runner observer',
          'recording', 'metrics', 'lockstep + setup')


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
def timed_stages():
    """Time the runner's stages (see the module text) while the block runs; yield the timer."""
    with lockstep.installed_runtime():
        from sim_bridge.bridge import SimBridge
        from sim_bridge.lockstep.rclpy.publisher import Publisher
        from scan_pkg.wall_follow import WallFollow
    timer = StageTimer()
    for owner, name, stage in (
            (Simulator, 'step', 'simulator step'), (Simulator, 'scan', 'lidar'),
            (SimBridge, 'step', 'bridge messages'), (SimBridge, 'on_cmd_vel', 'bridge messages'),
            (WallFollow, 'on_scan', 'wall_follow node'),
            (Publisher, 'publish', 'lockstep + setup'),
            (run.Observer, '__call__', 'runner observer'), (BagRecorder, 'write', 'recording'),
            (run, 'compute_metrics', 'metrics')):
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0, help='simulated s (600)')
    parser.add_argument('--repeats', type=int, default=1, help='timed runs per row (1)')
    parser.add_argument('--no-breakdown', action='store_true', help='skip the stage shares')
    args = parser.parse_args()
    configurations = [(beams, record) for beams in BEAMS for record in (False, True)]
    with tempfile.TemporaryDirectory() as folder:
        run_once(BEAMS[0], False, 1.0, Path(folder) / 'warm-up')  # imports, type store
        print(f'{args.duration:g} s of {NODE} in {WORLD} (seed {SEED}), plot off; '
              f'best of {args.repeats}')
        print(f'{"beams":>5}  {"recording":<9}  {"sim s":>6}  {"wall s":>6}  '
              f'{"x real time":>11}  {"goal":>5}')
        for beams, record in configurations:
            wall_s = min(run_once(beams, record, args.duration, Path(folder) / 'run')
                         for _ in range(args.repeats))
            factor = args.duration / wall_s
            verdict = 'met' if factor >= GOALS[beams] else 'MISSED'
            print(f'{beams:>5}  {"on" if record else "off":<9}  {args.duration:>6g}  '
                  f'{wall_s:>6.2f}  {factor:>10.0f}x  {GOALS[beams]:>4.0f}x {verdict}')
        if args.no_breakdown:
            return
        shares, walls = [], []
        for beams, record in configurations:
            with timed_stages() as timer:
                wall_s = run_once(beams, record, args.duration, Path(folder) / 'timed')
            timer.seconds['lockstep + setup'] += wall_s - sum(timer.seconds.values())
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
