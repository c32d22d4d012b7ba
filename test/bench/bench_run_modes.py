"""
Benchmark the two ways a run goes: stepped in the runner's process, or the node as its own process.

1. One scenario both ways: the lab's wanderbot in ``room`` for ``--duration`` simulated
   seconds (default 10), stepped (``run_simulation``, as the runner decides for it) and as its
   own process against the live simulator (``run_as_process``: the same file's ``main()``, as a
   file the runner cannot step runs), best of ``--repeats`` (default 2: the first stepped run
   pays for rclpy's and pybullet's start). Printed side by side: wall seconds, real-time
   factor, CPU seconds of this process and its children, and the distance driven.
2. Grading throughput of a class that mixes both: ``--students`` node files (default 8), half
   that the runner steps (an avoider on a helper base class, a publish-on-change driver) and
   half run as their own process (a spin_once loop, a node on a MultiThreadedExecutor),
   each graded on one 10 s scenario with ``grade_runs`` and ``--jobs 2``; beside it, a class
   of as many stepped files. Students per minute.

Run: python test/bench/bench_run_modes.py [--duration S] [--repeats N] [--students N]
"""

import argparse
from pathlib import Path
import resource
import tempfile
import time

from scan_pkg import wanderbot
from sim_bridge.common.run_environment import keep_dds_in_process
from sim_bridge.grading.batch import grade_runs
from sim_bridge.grading.runs import GradeJob
from sim_bridge.grading.scenario import scenario_from_dict
from sim_bridge.runner.node_styles import Decision
from sim_bridge.runner.options import prepare_run, RunSpec
from sim_bridge.runner.process_run import run_as_process
from sim_bridge.runner.run import run_simulation
from sim_bridge.runner.targets import run_mode

FIXTURES = Path(__file__).resolve().parents[2] / 'sim_bridge' / 'test' / 'fixtures'
WORLD = 'room'
STEPPED_FILES = ('helper_base_avoider.py', 'on_change_driver.py')
PROCESS_FILES = ('spin_once_loop.py', 'multithreaded_driver.py')
CLASS_DURATION_S = 10.0


def cpu_seconds() -> float:
    """Return the CPU seconds (user + system) of this process and its ended children."""
    return sum(usage.ru_utime + usage.ru_stime for usage in (
        resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)))


def one_run(process: bool, duration_s: float) -> tuple[float, float, dict]:
    """Run wanderbot in WORLD, stepped or as its own process; return (wall s, CPU s, metrics)."""
    target = wanderbot.__file__
    with tempfile.TemporaryDirectory() as folder:
        wall, cpu = time.perf_counter(), cpu_seconds()
        if process:
            spec = RunSpec(WORLD, (target,), duration_s=duration_s, seed=1, out_dir=folder,
                           quiet=True, plot=False)
            result = run_as_process(spec, prepare_run(spec), target, Decision(False, 'benchmark'))
        else:
            assert run_mode(target).steppable
            result = run_simulation(WORLD, [target], duration_s=duration_s, seed=1,
                                    out_dir=folder, quiet=True, plot=False)
        return time.perf_counter() - wall, cpu_seconds() - cpu, result.metrics


def grade_class(files: list[str], workers: int) -> tuple[float, int]:
    """Grade each node file on one scenario with ``workers`` children; return (wall s, passed)."""
    jobs = []
    with tempfile.TemporaryDirectory() as folder:
        for index, name in enumerate(files):
            scenario = scenario_from_dict({
                'world': 'obstacles', 'nodes': [str(FIXTURES / name)],
                'duration': CLASS_DURATION_S, 'seed': index,
                'criteria': ['len(node_errors) == 0', 'collisions == 0']}, f'student_{index}')
            jobs += [GradeJob(run, Path(folder) / run.name) for run in scenario.runs()]
        start = time.perf_counter()
        reports = grade_runs(jobs, workers=workers, resume=False, quiet=True, record=True,
                             plot=True)
        return time.perf_counter() - start, sum(report.passed for report in reports)


def main() -> None:
    """Measure and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--duration', type=float, default=10.0)
    parser.add_argument('--repeats', type=int, default=2)
    parser.add_argument('--students', type=int, default=8)
    args = parser.parse_args()
    keep_dds_in_process()
    print(f'wanderbot in {WORLD}, {args.duration:g} s simulated, recording on:')
    print(f"{'mode':>8}  {'wall s':>7}  {'x real time':>11}  {'CPU s':>6}  {'driven m':>8}")
    walls = {}
    for mode, process in (('stepped', False), ('process', True)):
        wall, cpu, metrics = min((one_run(process, args.duration) for _ in range(args.repeats)),
                                 key=lambda timing: timing[0])
        walls[mode] = wall
        print(f"{mode:>8}  {wall:7.2f}  {metrics['sim_time_s'] / wall:11.1f}  {cpu:6.2f}  "
              f"{metrics['distance_m']:8.2f}")
    print(f"stepped vs process: {walls['process'] / walls['stepped']:.1f}x faster")
    half = args.students // 2
    mixed = [STEPPED_FILES[i % 2] for i in range(half)]
    mixed += [PROCESS_FILES[i % 2] for i in range(args.students - half)]
    stepped = [STEPPED_FILES[i % 2] for i in range(args.students)]
    print(f'\nGrading a class of {args.students} (one {CLASS_DURATION_S:g} s run each, '
          'recording and plots on), --jobs 2:')
    print(f"{'class':>22}  {'wall s':>7}  {'passed':>6}  {'students/min':>12}")
    for label, files in ((f'{half} stepped + {args.students - half} process', mixed),
                         (f'{args.students} stepped', stepped)):
        wall, passed = grade_class(files, 2)
        print(f'{label:>22}  {wall:7.1f}  {passed:>6}  {len(files) / wall * 60:12.1f}')


if __name__ == '__main__':
    main()
