"""
Benchmark the grader: throughput with one and two child processes, and a child's overhead.

Grades a fixed batch of shipped scenarios (scan_ahead once, wall_follow round the box
clockwise and the L counter-clockwise, 3 seeds each: 7 runs, 467 simulated seconds) through
``sim_bridge.grading.batch.grade_runs`` with ``--jobs 1`` and ``--jobs 2``, fresh each time, and
prints side by side: wall seconds, scenario runs per minute and simulated seconds per wall second.
Then the per-run overhead of a child process: the same run (scan_ahead, 10 s) in this process
(``run_scenario``) and in a child (``grade_runs``: forked from the server that has the runner
imported), best of ``--repeats``, and the difference; beside it, what a fresh interpreter per
run would pay before its first step: importing the modules the fork server preloads.

Run: python test/bench/bench_grade.py [--repeats N] [--no-record]
"""

import argparse
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from sim_bridge.common.run_environment import keep_dds_in_process
from sim_bridge.grading.batch import grade_runs
from sim_bridge.grading.isolated_child import PRELOADED
from sim_bridge.grading.runs import GradeJob, run_scenario
from sim_bridge.grading.scenario import load_scenarios

SCENARIOS = Path(__file__).resolve().parents[2] / 'scenarios'
BATCH = ('scan_ahead.yaml', 'wall_follow_box_cw.yaml', 'wall_follow_l_shape_ccw.yaml')
OVERHEAD_SCENARIO = 'scan_ahead.yaml'


def batch_throughput(workers: int, options: dict) -> tuple[float, int, float]:
    """Grade the BATCH with ``workers`` children; return (wall s, runs, simulated s)."""
    runs = [run for scenario in load_scenarios([SCENARIOS / name for name in BATCH])
            for run in scenario.runs()]
    with tempfile.TemporaryDirectory() as folder:
        jobs = [GradeJob(run, Path(folder) / run.name) for run in runs]
        start = time.perf_counter()
        reports = grade_runs(jobs, workers=workers, resume=False, **options)
        wall = time.perf_counter() - start
    failed = [report.run.name for report in reports if not report.passed]
    if failed:
        raise SystemExit(f'runs failed: {failed}')
    return wall, len(runs), sum(run.scenario.duration_s for run in runs)


def overhead(repeats: int, options: dict) -> tuple[float, float]:
    """Return the best wall seconds of one run in this process and in a child."""
    [run] = load_scenarios([SCENARIOS / OVERHEAD_SCENARIO])[0].runs()
    in_process, child = float('inf'), float('inf')
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            start = time.perf_counter()
            assert run_scenario(run, Path(folder) / 'in', **options).passed
            in_process = min(in_process, time.perf_counter() - start)
            start = time.perf_counter()
            [report] = grade_runs([GradeJob(run, Path(folder) / 'child')], resume=False,
                                  **options)
            assert report.passed
            child = min(child, time.perf_counter() - start)
    return in_process, child


def fresh_interpreter_imports(repeats: int) -> float:
    """Return the best wall seconds a new Python takes to import what the fork server has."""
    best = float('inf')
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, '-c', f"import {', '.join(PRELOADED)}"], check=True,
                       capture_output=True)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    """Measure and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--no-record', action='store_true')
    args = parser.parse_args()
    keep_dds_in_process()
    options = {'quiet': True, 'record': not args.no_record, 'plot': True}
    print(f"Grading throughput ({', '.join(BATCH)}; recording "
          f"{'off' if args.no_record else 'on'}, plots on)")
    print(f"{'jobs':>4}  {'wall s':>7}  {'runs':>4}  {'runs/min':>8}  {'sim s/wall s':>12}")
    walls = {}
    for workers in (1, 2):
        wall, runs, simulated = batch_throughput(workers, options)
        walls[workers] = wall
        print(f'{workers:>4}  {wall:7.1f}  {runs:>4}  {runs / wall * 60:8.1f}  '
              f'{simulated / wall:12.1f}')
    print(f'jobs 2 vs jobs 1: {walls[1] / walls[2]:.2f}x faster')
    in_process, child = overhead(args.repeats, options)
    print(f'\nOne run of {OVERHEAD_SCENARIO} (10 s simulated), best of {args.repeats}:')
    print(f'  in this process  {in_process:6.2f} s')
    print(f'  in a child       {child:6.2f} s')
    print(f'  overhead         {child - in_process:6.2f} s per run '
          f'({child / in_process:.1f}x)')
    print(f'  a fresh interpreter per run would first import for '
          f'{fresh_interpreter_imports(args.repeats):.2f} s')


if __name__ == '__main__':
    main()
