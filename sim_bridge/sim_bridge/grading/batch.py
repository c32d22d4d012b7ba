"""
Grade nodes against scenario files: run each scenario's seeds and judge its criteria.

``python -m sim_bridge.grade scenarios/`` runs every scenario in the folder through the
runner (``sim_bridge.runner.run.run_simulation``, real rclpy), each run in a child process of its
own bounded in time and memory (:mod:`sim_bridge.grading.isolate`), shows a progress bar over the
batch, prints a pass/fail table with what was measured per criterion, writes ``report.json``,
``report.html`` and each run's outputs (metrics, plot, recording, log) below ``--out``, and
exits non-zero when any run fails. ``--node-override path/to/student.py`` grades someone
else's node on the same scenarios; ``--submissions DIR`` grades a whole class
(:mod:`sim_bridge.grading.class_batch`), ``--submission DIR`` one student's folder the same way,
and ``--gradescope results.json`` writes Gradescope's results too
(:mod:`sim_bridge.grading.gradescope`); the scenarios' marks (:mod:`sim_bridge.grading.marks`) are
in the summary line and every report. A second invocation with the same ``--out`` resumes: runs
already finished with the same inputs are not run again. See :mod:`sim_bridge.grading.scenario` for
the scenario format.
"""

from collections.abc import Callable, Iterable
from dataclasses import asdict
import hashlib
import json
from pathlib import Path
import select
import shutil
import sys
import time
from typing import Any, TextIO

from sim_bridge.common.text import (
    first_line, format_measured, one_line, PathNames, printable, reason)
from sim_bridge.grading import marks
from sim_bridge.grading.isolate import Child
from sim_bridge.grading.limits import Job, Limits
from sim_bridge.grading.runs import GradeJob, RESULT_NAME, RunReport
from sim_bridge.grading.scenario import ScenarioRun
from sim_bridge.runner.targets import split_target
from sim_bridge.simulation.world import World, WorldError

BAR_WIDTH = 24
#: The most characters of an error or warning in a row of the printed table.
TABLE_TEXT_CHARS = 160
#: Wall seconds between two looks at the running children.
POLL_S = 0.2


class BatchProgress:
    """
    Report progress over a batch of runs on a text stream (stderr), with the time left.

    On a terminal, one bar line is redrawn in place: runs done, the share of the batch's
    simulated seconds done (finished runs plus the running ones' progress) and an estimate of
    the wall time left from the pace so far; elsewhere (CI logs) a plain line is printed as
    each run ends. Runs resumed from an earlier invocation count as done but not for the pace.
    """

    def __init__(self, total: int, total_sim_s: float = 0.0, stream: TextIO = sys.stderr,
                 enabled: bool = True, clock: Callable[[], float] = time.monotonic) -> None:
        self.total = total
        self.total_sim_s = total_sim_s
        self.stream = stream
        self.enabled = enabled
        self.live = enabled and stream.isatty()
        self.done = 0
        self.done_sim_s = 0.0
        self.resumed_sim_s = 0.0
        self.running: dict[str, float] = {}
        self.clock = clock
        self.wall_start = clock()

    def resume(self, report: 'RunReport') -> None:
        """Note a run finished by an earlier invocation."""
        self.done += 1
        self.done_sim_s += report.run.scenario.duration_s
        self.resumed_sim_s += report.run.scenario.duration_s

    def start(self, name: str) -> None:
        """Note that the run called ``name`` (its job's :attr:`GradeJob.name`) begins."""
        self.running[name] = 0.0
        self._draw()

    def advance(self, name: str, sim_s: float) -> None:
        """Note that the run called ``name`` has simulated ``sim_s`` seconds."""
        self.running[name] = sim_s
        self._draw()

    def finish(self, name: str, report: 'RunReport') -> None:
        """
        Note that the run called ``name`` ended and print its one-line outcome.

        The line gives the simulated time the run reached and, for a failed run, why in a
        few words: ``FAIL ana/box/seed_1: SyntaxError: ... (0 of 76.2 s sim in 0.4 s)``.
        """
        self.running.pop(name, None)
        self.done += 1
        self.done_sim_s += report.run.scenario.duration_s
        if not self.enabled:
            return
        verdict = 'PASS' if report.passed else 'FAIL'
        why = '' if report.passed else f': {reason(report.as_dict())}'
        line = (f'[{self.done:{len(str(self.total))}d}/{self.total}] {verdict} '
                f'{one_line(name)}{why} ({round(report.sim_time_s, 1):g} of '
                f'{report.run.scenario.duration_s:g} s sim in {report.wall_time_s:.1f} s)')
        left = self.time_left_s()
        if left is not None and self.done < self.total:
            line += f', about {format_duration(left)} left'
        self.note(line)

    def note(self, line: str) -> None:
        """Print a line above the bar (also when the progress is not shown: a warning)."""
        self._write(('\r\033[K' if self.live else '') + printable(line) + '\n')
        self._draw()

    def time_left_s(self) -> float | None:
        """Return the estimated wall seconds left (None before any pace is known)."""
        simulated = self.done_sim_s - self.resumed_sim_s + sum(self.running.values())
        elapsed = self.clock() - self.wall_start
        if simulated <= 0 or elapsed <= 0:
            return None
        remaining = self.total_sim_s - self.done_sim_s - sum(self.running.values())
        return max(remaining, 0.0) * elapsed / simulated

    def _draw(self) -> None:
        if not self.live or self.done >= self.total:
            return
        done_sim = self.done_sim_s + sum(self.running.values())
        share = done_sim / self.total_sim_s if self.total_sim_s > 0 else self.done / self.total
        filled = round(BAR_WIDTH * min(share, 1.0))
        left = self.time_left_s()
        self._write(f"\r\033[K[{'#' * filled}{'.' * (BAR_WIDTH - filled)}] "
                    f'{self.done}/{self.total} runs, {share:.0%} of the simulated time'
                    + (f', about {format_duration(left)} left' if left is not None else '')
                    + (f" (running: {', '.join(self.running)})" if self.running else ''))

    def _write(self, text: str) -> None:
        if self.stream is None:
            return
        try:
            self.stream.write(text)
            self.stream.flush()
        except OSError:  # piped into `head`, which has exited: the batch goes on unseen
            self.stream = None
            self.live = False


def format_duration(seconds: float) -> str:
    """Return a duration (s) as a person reads it: '45 s', '3 min 20 s', '1 h 5 min'."""
    seconds = round(seconds)
    if seconds < 60:
        return f'{seconds} s'
    if seconds < 3600:
        return f'{seconds // 60} min {seconds % 60} s'
    return f'{seconds // 3600} h {seconds % 3600 // 60} min'


def fingerprint(job: GradeJob, options: dict[str, Any], limits: Limits) -> str:
    """
    Return a digest of everything a run's outcome depends on.

    The scenario's settings, the runner options and limits, and the contents of the scenario,
    world, model and node files (or, for a world that does not load, why): a run is resumed
    only when none of them changed since it ran.
    """
    scenario = job.run.scenario
    digest = hashlib.sha256(json.dumps({
        'run': job.run.name, 'seed': job.run.seed, 'params': job.run.params,
        'world': scenario.world, 'nodes': scenario.nodes, 'duration_s': scenario.duration_s,
        'start': scenario.start, 'robot': scenario.robot, 'remap': scenario.remap,
        'setpoint': scenario.setpoint,
        'drive': [segment.as_dict() for segment in scenario.drive],
        'criteria': [criterion.text for criterion in scenario.criteria],
        'options': options, 'limits': asdict(limits)}, sort_keys=True, default=str).encode())
    try:
        world_files = World.load(scenario.world).sources
    except (OSError, WorldError) as error:  # the run fails on it, as it does when run
        world_files = ()
        digest.update(str(error).encode())
    node_files = [Path(split_target(node)[0]) for node in scenario.nodes]
    for path in (Path(scenario.path or ''), *world_files, *node_files):
        if path.is_file():
            digest.update(path.read_bytes())
    return digest.hexdigest()


def finished_report(job: GradeJob, digest: str,
                    note: Callable[[str], None] = print) -> 'RunReport | None':
    """
    Return the report of ``job`` from an earlier invocation, if it ran with ``digest``.

    A result file that is there but is not one the grader wrote is named with ``note`` and
    its run is run again.
    """
    path = job.out_dir / RESULT_NAME
    try:
        saved = json.loads(path.read_text(encoding='utf-8'))
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as error:
        note(f'running {job.name} again: {printable(str(path))} does not read as JSON '
             f'({first_line(str(error))})')
        return None
    if isinstance(saved, dict) and saved.get('fingerprint') != digest:
        return None  # a result of other inputs: the run is due again
    try:
        if not isinstance(saved, dict):
            raise ValueError(f'expected a mapping, got {type(saved).__name__}')
        report = RunReport.from_dict(job.run, job.out_dir, saved.get('report'))
    except ValueError as error:
        note(f'running {job.name} again: {printable(str(path))} is not a run result '
             f'({error})')
        return None
    report.reused = True
    return report


def save_result(report: 'RunReport', digest: str, names: PathNames | None = None) -> None:
    """Write a finished run's report to its folder, whole or not at all (a Ctrl-C)."""
    path = report.out_dir / RESULT_NAME
    partial = path.with_suffix('.partial')
    partial.write_text(json.dumps({'fingerprint': digest, 'report': report.as_dict(names)},
                                  indent=2, allow_nan=False) + '\n', encoding='utf-8')
    partial.replace(path)


def grade_runs(jobs: list[GradeJob], *, workers: int = 1, limits: Limits = Limits(),
               progress: BatchProgress | None = None, resume: bool = True,
               names: PathNames | None = None, **options: Any) -> list[RunReport]:
    """
    Run and judge every job, each in a child process of its own (see sim_bridge.grading.isolate).

    ``workers`` children run at once; ``limits`` bound each in wall-clock time and memory;
    ``options`` go to :func:`run_scenario` in the child. With ``resume``, a job whose folder
    holds the result of a run with the same inputs is not run again (its report's
    :attr:`RunReport.reused` is True); ``names`` names paths in the saved results (see
    :func:`report_names`). The longest runs start
    first; the reports come back in the order of ``jobs``. A KeyboardInterrupt kills the
    running children and propagates; finished runs keep their results.
    """
    progress = progress or BatchProgress(len(jobs), enabled=False)
    reports: dict[int, RunReport] = {}
    digests = [fingerprint(job, options, limits) for job in jobs]
    pending = []
    for index, job in enumerate(jobs):
        report = finished_report(job, digests[index], progress.note) if resume else None
        if report is None:
            pending.append(index)
        else:
            reports[index] = report
            progress.resume(report)
    # The longest runs first: the workers then finish at about the same time.
    pending.sort(key=lambda index: -jobs[index].run.scenario.duration_s)
    running: dict[int, Child] = {}
    try:
        while pending or running:
            while pending and len(running) < workers:
                index = pending.pop(0)
                job = jobs[index]
                shutil.rmtree(job.out_dir, ignore_errors=True)
                # The child works in a scratch folder: every path it gets is absolute.
                run = ScenarioRun(job.run.scenario.absolute(), job.run.seed)
                running[index] = Child(Job(run, job.out_dir.resolve(), limits, options))
                progress.start(job.name)
            select.select(list(running.values()), [], [], POLL_S)
            for index, child in list(running.items()):
                result = child.poll()
                job = jobs[index]
                if result is None:
                    progress.advance(job.name, child.sim_s or 0.0)
                    continue
                del running[index]
                try:
                    reports[index] = RunReport.from_dict(job.run, job.out_dir, result)
                except ValueError as error:  # a child cut off mid-report: the run fails alone
                    reports[index] = RunReport(job.run, job.out_dir, [], None,
                                               f'the run sent no usable report: {error}',
                                               time.monotonic() - child.started)
                try:
                    save_result(reports[index], digests[index], names)
                except OSError as error:  # the run's report is still in the batch's
                    progress.note(f'cannot save {printable(str(job.out_dir / RESULT_NAME))}: '
                                  f'{error.strerror or error}')
                progress.finish(job.name, reports[index])
    finally:
        for child in running.values():
            child.kill()
    return [reports[index] for index in range(len(jobs))]


def format_table(reports: Iterable[RunReport], *, failures_only: bool = False) -> str:
    """
    Return the pass/fail table: one row per criterion of each run, with the measured value.

    A run's error, node errors and warnings (``metrics['warnings']``, which fail nothing) come
    first, each on one line.
    """
    rows = [('run', 'criterion', 'measured', 'result')]
    for report in reports:
        if failures_only and report.passed:
            continue
        name = one_line(report.run.name)
        metrics = report.metrics or {}
        if report.error is not None:
            rows.append((name, f'error: {first_line(report.error, TABLE_TEXT_CHARS)}', '',
                         'FAIL'))
            name = ''
        for node_error in metrics.get('node_errors', []):
            text = first_line(node_error['error'], TABLE_TEXT_CHARS)
            rows.append((name, f'node error: {text}', '', 'FAIL'))
            name = ''
        for warning in metrics.get('warnings') or []:
            rows.append((name, f'warning: {first_line(warning, TABLE_TEXT_CHARS)}', '', 'warn'))
            name = ''
        for result in report.results:
            if failures_only and result.passed:
                continue
            verdict = 'pass' if result.passed else 'FAIL'
            rows.append((name, result.criterion, format_measured(result.criterion, result.value),
                         verdict))
            name = ''
    widths = [max(len(row[column]) for row in rows) for column in range(3)]
    lines = [f'{row[0]:<{widths[0]}}  {row[1]:<{widths[1]}}  {row[2]:>{widths[2]}}  {row[3]}'
             for row in rows]
    lines.insert(1, '-' * len(lines[0]))
    return '\n'.join(line.rstrip() for line in lines)


def summary(reports: list[RunReport], tasks: list[marks.TaskMarks] | None = None) -> str:
    """Return the one-line verdict of a batch, with its marks by task, naming the failed runs."""
    failed = [report.run.name for report in reports if not report.passed]
    text = f'{len(reports) - len(failed)} of {len(reports)} runs passed'
    earned = marks.summary(tasks or [])
    text += f', {earned}' if earned else ''
    return text + (f"; failed: {', '.join(failed)}" if failed else '')
