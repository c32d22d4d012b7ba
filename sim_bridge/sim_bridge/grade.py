"""
Grade nodes against scenario files: run each scenario's seeds and judge its criteria.

``python -m sim_bridge.grade test/scenarios/`` runs every scenario in the folder through the
runner (``sim_bridge.run.run_simulation``, real rclpy), shows a progress bar over the batch,
prints a pass/fail table with what was measured per criterion, writes ``report.json`` and
each run's outputs (metrics, plot, recording) below ``--out``, and exits non-zero when any run
fails. ``--node-override path/to/student.py`` grades someone else's node on the same scenarios.
See :mod:`sim_bridge.scenario` for the scenario format.
"""

import argparse
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
import json
import multiprocessing
import os
from pathlib import Path
import sys
import time
import traceback
from typing import Any, TextIO

from sim_bridge.scenario import CriterionResult, load_scenarios, ScenarioError, ScenarioRun

DEFAULT_OUT = Path('out') / 'grade'
REPORT_NAME = 'report.json'
BAR_WIDTH = 24

#: A run of the simulator: (world, targets, keyword options) -> RunResult with ``metrics``.
Simulate = Callable[..., Any]


@dataclass
class RunReport:
    """The outcome of one scenario run: its criteria results, or the error that stopped it."""

    run: ScenarioRun
    out_dir: Path
    results: list[CriterionResult]
    metrics: dict[str, Any] | None
    error: str | None
    wall_time_s: float
    traceback: str | None = None

    @property
    def passed(self) -> bool:
        """Return True when the run completed and every criterion holds."""
        return self.error is None and all(result.passed for result in self.results)

    def as_dict(self) -> dict[str, Any]:
        """Return the run's entry of the JSON report."""
        scenario = self.run.scenario
        return {
            'run': self.run.name, 'scenario': scenario.name,
            'file': str(scenario.path) if scenario.path else None, 'world': scenario.world,
            'nodes': list(scenario.nodes), 'seed': self.run.seed,
            'duration_s': scenario.duration_s, 'params': self.run.params,
            'start': scenario.start, 'passed': self.passed, 'error': self.error,
            'traceback': self.traceback,
            'criteria': [result.as_dict() for result in self.results],
            'out_dir': str(self.out_dir), 'wall_time_s': self.wall_time_s,
            'metrics': self.metrics,
        }


def run_scenario(run: ScenarioRun, out_dir: Path, *, simulate: Simulate | None = None,
                 quiet: bool = True, record: bool = True, plot: bool = True,
                 progress: Callable[[float, float], None] | None = None) -> RunReport:
    """
    Run one seed of a scenario with ``simulate`` (default: the stepped runner) and judge it.

    A run that cannot start (bad world, target or parameter) or whose runner crashes is
    reported with its error and fails; a node raising during the run is in the metrics'
    ``node_errors`` and fails the criteria that look at it.
    """
    if simulate is None:
        from sim_bridge.run import run_simulation as simulate
    scenario = run.scenario
    wall_start = time.perf_counter()
    try:
        result = simulate(scenario.world, list(scenario.nodes), duration_s=scenario.duration_s,
                          seed=run.seed, params=run.params, out_dir=out_dir,
                          start=scenario.start, quiet=quiet, record=record, plot=plot,
                          progress=progress)
    except Exception as error:  # one broken run must not stop the batch
        return RunReport(run, out_dir, [], None, f'{type(error).__name__}: {error}',
                         time.perf_counter() - wall_start, traceback.format_exc())
    return RunReport(run, out_dir, scenario.judge(result.metrics), result.metrics, None,
                     time.perf_counter() - wall_start)


class BatchProgress:
    """
    Report progress over a batch of runs on a text stream (stderr).

    On a terminal, one bar line is redrawn in place (with the sim time of the current run);
    elsewhere (CI logs) a plain line is printed as each run ends.
    """

    def __init__(self, total: int, stream: TextIO = sys.stderr, enabled: bool = True) -> None:
        self.total = total
        self.stream = stream
        self.enabled = enabled
        self.live = enabled and stream.isatty()
        self.done = 0
        self.current = ''

    def start(self, run: ScenarioRun) -> None:
        """Note that ``run`` begins."""
        self.current = run.name
        self._draw(0.0)

    def advance(self, sim_s: float, duration_s: float) -> None:
        """Note the current run's progress in simulated seconds (the runner's callback)."""
        fraction = sim_s / duration_s if duration_s > 0 else 0.0
        self._draw(fraction, f' {sim_s:.0f}/{duration_s:.0f} s')

    def finish(self, report: RunReport) -> None:
        """Note that a run ended and print its one-line outcome."""
        self.done += 1
        if not self.enabled:
            return
        verdict = 'PASS' if report.passed else 'FAIL'
        line = (f'[{self.done:{len(str(self.total))}d}/{self.total}] {verdict} '
                f'{report.run.name} ({report.run.scenario.duration_s:g} s sim in '
                f'{report.wall_time_s:.1f} s)')
        self.stream.write(('\r\033[K' if self.live else '') + line + '\n')
        self.stream.flush()

    def _draw(self, fraction: float, detail: str = '') -> None:
        if not self.live:
            return
        share = (self.done + min(max(fraction, 0.0), 1.0)) / self.total
        filled = round(BAR_WIDTH * share)
        self.stream.write(f"\r\033[K[{'#' * filled}{'.' * (BAR_WIDTH - filled)}] "
                          f'{self.done}/{self.total} {self.current}{detail}')
        self.stream.flush()


def _run_in_worker(job: tuple) -> RunReport:
    run, out_dir, options = job
    return run_scenario(run, out_dir, **options)


def grade_runs(runs: list[ScenarioRun], out_dir: Path, *, jobs: int = 1,
               progress: BatchProgress | None = None, **options: Any) -> list[RunReport]:
    """
    Run and judge every run, each writing below ``out_dir/<scenario>/seed_<n>``.

    ``jobs`` > 1 runs that many in parallel processes; ``options`` go to :func:`run_scenario`.
    Returns the reports in the order of ``runs``.
    """
    progress = progress or BatchProgress(len(runs), enabled=False)
    folders = [out_dir / run.name for run in runs]
    if jobs <= 1:
        reports = []
        for run, folder in zip(runs, folders):
            progress.start(run)
            reports.append(run_scenario(run, folder, progress=progress.advance, **options))
            progress.finish(reports[-1])
        return reports
    context = multiprocessing.get_context('spawn')
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        reports = []
        for report in pool.map(_run_in_worker,
                               [(run, folder, options) for run, folder in zip(runs, folders)]):
            progress.finish(report)
            reports.append(report)
        return reports


def format_table(reports: Iterable[RunReport], *, failures_only: bool = False) -> str:
    """Return the pass/fail table: one row per criterion of each run, with the measured value."""
    rows = [('run', 'criterion', 'measured', 'result')]
    for report in reports:
        if failures_only and report.passed:
            continue
        name = report.run.name
        if report.error is not None:
            rows.append((name, f'error: {report.error}', '', 'FAIL'))
        for node_error in (report.metrics or {}).get('node_errors', []):
            rows.append((name, f"node error: {node_error['error']}", '', 'FAIL'))
            name = ''
        for result in report.results:
            if failures_only and result.passed:
                continue
            verdict = 'pass' if result.passed else 'FAIL'
            rows.append((name, result.criterion, result.shown, verdict))
            name = ''
    widths = [max(len(row[column]) for row in rows) for column in range(3)]
    lines = [f'{row[0]:<{widths[0]}}  {row[1]:<{widths[1]}}  {row[2]:>{widths[2]}}  {row[3]}'
             for row in rows]
    lines.insert(1, '-' * len(lines[0]))
    return '\n'.join(line.rstrip() for line in lines)


def summary(reports: list[RunReport]) -> str:
    """Return the one-line verdict of a batch, naming the failed runs."""
    failed = [report.run.name for report in reports if not report.passed]
    text = f'{len(reports) - len(failed)} of {len(reports)} runs passed'
    return text + (f"; failed: {', '.join(failed)}" if failed else '')


def write_report(reports: list[RunReport], path: Path, *, overrides: Iterable[str] = ()) -> None:
    """Write the JSON report of a batch."""
    document = {
        'passed': all(report.passed for report in reports),
        'summary': {'runs': len(reports), 'passed': sum(report.passed for report in reports),
                    'failed': sum(not report.passed for report in reports)},
        'node_overrides': list(overrides),
        'runs': [report.as_dict() for report in reports],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2, allow_nan=False) + '\n', encoding='utf-8')


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser of the grader."""
    parser = argparse.ArgumentParser(
        prog='python -m sim_bridge.grade',
        description='Run scenario files in the simulator and judge their criteria.')
    parser.add_argument('scenarios', nargs='+', metavar='SCENARIO',
                        help='a scenario file, or a folder of them (e.g. test/scenarios/)')
    parser.add_argument('--node-override', action='append', default=[], metavar='TARGET',
                        help='run TARGET (a console script, module or path.py[:Class]) instead '
                        "of the scenario's node of the same name (or its only node); "
                        'NODE=TARGET replaces node NODE only; repeatable')
    parser.add_argument('--out', type=Path, default=DEFAULT_OUT, metavar='DIR',
                        help=f'folder for {REPORT_NAME} and the outputs of each run '
                        f'(default {DEFAULT_OUT})')
    parser.add_argument('--jobs', type=int, default=1, metavar='N',
                        help='runs in parallel processes (default 1)')
    parser.add_argument('--quiet', action='store_true',
                        help='no progress; the table lists failures only')
    parser.add_argument('--logs', action='store_true', help="show the nodes' log lines")
    parser.add_argument('--no-record', action='store_true', help='skip the rosbag2 recordings')
    parser.add_argument('--no-plot', action='store_true', help='skip the trajectory plots')
    return parser


def main(argv: list[str] | None = None) -> int:
    """Grade the scenarios named on the command line; return 0 when every run passed."""
    args = build_parser().parse_args(argv)
    if args.jobs < 1:
        print('error: --jobs must be at least 1', file=sys.stderr)
        return 2
    try:
        scenarios = load_scenarios(args.scenarios)
        for override in args.node_override:
            scenarios = [scenario.with_node_override(override) for scenario in scenarios]
    except ScenarioError as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    runs = [run for scenario in scenarios for run in scenario.runs()]
    progress = BatchProgress(len(runs), enabled=not args.quiet)
    reports = grade_runs(runs, args.out, jobs=args.jobs, progress=progress,
                         quiet=not args.logs, record=not args.no_record, plot=not args.no_plot)
    write_report(reports, args.out / REPORT_NAME, overrides=args.node_override)
    table = format_table(reports, failures_only=args.quiet)
    if not args.quiet or not all(report.passed for report in reports):
        print(table)
    print(summary(reports))
    print(f'report: {os.fspath(args.out / REPORT_NAME)}')
    return 0 if all(report.passed for report in reports) else 1


if __name__ == '__main__':
    sys.exit(main())
