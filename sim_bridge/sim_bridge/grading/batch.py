"""
A batch of graded runs: each in its child process, resumed from signed results, tabled.

:func:`grade_runs` runs a batch's jobs (at most ``workers`` at once, each bounded by
:mod:`sim_bridge.grading.isolate`), reusing a run already finished with the same inputs when its
saved result's signature holds (:mod:`sim_bridge.grading.grader_state`); :class:`BatchProgress`
shows the batch's progress; :func:`format_table` is the pass/fail table the grade command
(:mod:`sim_bridge.commands.grade`, where the command line is described) prints.
"""

from collections.abc import Callable, Iterable
from dataclasses import asdict
import hashlib
import json
import os
from pathlib import Path
import select
import shutil
import sys
import time
from typing import Any, TextIO

from sim_bridge.common.console import ProgressBar, text_table
from sim_bridge.common.text import (
    first_line, format_measured, one_line, PathNames, printable, reason)
from sim_bridge.grading import marks
from sim_bridge.grading.grader_state import ResultSigner
from sim_bridge.grading.isolate import Child
from sim_bridge.grading.limits import Job, Limits
from sim_bridge.grading.runs import GradeJob, RESULT_NAME, RunReport
from sim_bridge.grading.scenario import ScenarioRun
from sim_bridge.runner.boundary.outside.node_sandbox import is_kit_file, student_files
from sim_bridge.runner.targets import split_target
from sim_bridge.simulation.world import World, WorldError

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

    def __init__(self, total: int, total_sim_s: float = 0.0, stream: TextIO | None = None,
                 enabled: bool = True, clock: Callable[[], float] = time.monotonic) -> None:
        self.total = total
        self.total_sim_s = total_sim_s
        self.enabled = enabled
        #: The bar (rich's, drawn on a terminal only) and the lines above it; None: unseen.
        self.bar: ProgressBar | None = ProgressBar(  # on the stderr of the moment
            stream if stream is not None else sys.stderr, draw=enabled)
        self.live = self.bar.live
        self.done = 0
        self.done_sim_s = 0.0
        self.resumed_sim_s = 0.0
        self.running: dict[str, float] = {}
        #: What the grader could not do (an output not written): each said in one line.
        self.faults: list[str] = []
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
        self._try(lambda bar: bar.write_line(printable(line)))
        self._draw()

    def fault(self, line: str) -> None:
        """Print a line saying what the grader could not do; the batch then fails."""
        self.faults.append(line)
        self.note(f'error: {line}')

    def time_left_s(self) -> float | None:
        """Return the estimated wall seconds left (None before any pace is known)."""
        simulated = self.done_sim_s - self.resumed_sim_s + sum(self.running.values())
        elapsed = self.clock() - self.wall_start
        if simulated <= 0 or elapsed <= 0:
            return None
        remaining = self.total_sim_s - self.done_sim_s - sum(self.running.values())
        return max(remaining, 0.0) * elapsed / simulated

    def _draw(self) -> None:
        if not self.live:
            return
        if self.done >= self.total:
            self._try(ProgressBar.close)
            return
        done_sim = self.done_sim_s + sum(self.running.values())
        share = done_sim / self.total_sim_s if self.total_sim_s > 0 else self.done / self.total
        left = self.time_left_s()
        status = (f'{self.done}/{self.total} runs, {min(share, 1.0):.0%} of the simulated time'
                  + (f', about {format_duration(left)} left' if left is not None else '')
                  + (f" (running: {', '.join(self.running)})" if self.running else ''))
        self._try(lambda bar: bar.update(share, status))

    def _try(self, draw: Callable[[ProgressBar], None]) -> None:
        """Draw on the bar; once its stream is gone (piped into ``head``), nothing more."""
        if self.bar is None:
            return
        try:
            draw(self.bar)
        except OSError:  # piped into `head`, which has exited: the batch goes on unseen
            self.bar = None
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
    world and model files (or, for a world that does not load, why) and of all a run reads of
    a submission (a student's node file and its own modules beside it, by name: see
    :func:`sim_bridge.runner.boundary.outside.node_sandbox.student_files`): a run is resumed only
    when none of them changed since it ran.
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
    for path in (Path(scenario.path or ''), *world_files):
        digest.update(file_digest(path))
    for path in node_files:
        read = student_files(path) if path.is_file() and not is_kit_file(path) else {'': path}
        for name, source in read.items():  # all a run reads of a submission, by name
            digest.update(name.encode() + b'\0' + file_digest(source))
    return digest.hexdigest()


def file_digest(path: Path) -> bytes:
    """
    Return the SHA-256 of a file's contents (b'' when it is not a file), a symlink's target first.

    Read in chunks: a file's size costs time, never memory.
    """
    digest = hashlib.sha256(os.fsencode(os.readlink(path)) if path.is_symlink() else b'')
    if path.is_file():
        with open(path, 'rb') as file:
            digest.update(hashlib.file_digest(file, 'sha256').digest())
    return digest.digest()


class ResultRefused(Exception):
    """A saved result does not match its signature: its run is run again, and reported so."""


def finished_report(job: GradeJob, digest: str, signer: ResultSigner,
                    note: Callable[[str], None] = print) -> 'RunReport | None':
    """
    Return the report of ``job`` from an earlier invocation, if it ran with ``digest``.

    Only a result signed by ``signer`` (the grader's key) is reused, and never one that says
    it must be run again (:attr:`RunReport.rerun`: a budget it did not use up itself). One
    that is there but is not a result the grader writes is named with ``note`` and its run is
    run again; one whose signature does not match (edited, or copied from another run's
    folder) is named too, and raises ResultRefused: it is run again and the batch's report
    says so.
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
    signature = saved.pop('signature', None) if isinstance(saved, dict) else None
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
    if not signer.signs(job.out_dir, saved, signature):
        note(f'running {job.name} again: {printable(str(path))} was changed since the grader '
             'wrote it (its signature does not match)')
        raise ResultRefused
    if report.rerun:
        note(f'running {job.name} again: {report.rerun}')
        return None
    report.reused = True
    return report


def save_result(report: 'RunReport', digest: str, signer: ResultSigner,
                names: PathNames | None = None) -> None:
    """Write a finished run's report to its folder, signed, whole or not at all (a Ctrl-C)."""
    path = report.out_dir / RESULT_NAME
    partial = path.with_suffix('.partial')
    saved = json.loads(json.dumps({'fingerprint': digest, 'report': report.as_dict(names)},
                                  allow_nan=False))  # signed as it will read back
    saved['signature'] = signer.signature(report.out_dir, saved)
    partial.write_text(json.dumps(saved, indent=2) + '\n', encoding='utf-8')
    partial.replace(path)


def resumed(jobs: list[GradeJob], digests: list[str], signer: ResultSigner,
            progress: BatchProgress) -> tuple[dict[int, RunReport], set[int]]:
    """Return the reports of ``jobs`` finished earlier, and the jobs whose result was refused."""
    reports, refused = {}, set()
    for index, job in enumerate(jobs):
        try:
            report = finished_report(job, digests[index], signer, progress.note)
        except ResultRefused:
            refused.add(index)
            continue
        if report is not None:
            reports[index] = report
            progress.resume(report)
    return reports, refused


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
    signer = ResultSigner.of_grader(progress.note)
    digests = [fingerprint(job, options, limits) for job in jobs]
    reports, refused = (resumed(jobs, digests, signer, progress) if resume else ({}, set()))
    pending = [index for index in range(len(jobs)) if index not in reports]
    # The longest runs first: the workers then finish at about the same time.
    pending.sort(key=lambda index: -jobs[index].run.scenario.duration_s)
    running: dict[int, Child] = {}
    try:
        while pending or running:
            while pending and len(running) < workers:
                index = pending.pop(0)
                started = start_child(jobs[index], limits, options, progress)
                if isinstance(started, Child):
                    running[index] = started
                else:  # it could not start: the batch goes on without it
                    reports[index] = started
                    progress.finish(jobs[index].name, started)
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
                if child.log_failure is not None:
                    progress.fault(f'cannot write {printable(str(child.log_path))}: '
                                   f'{child.log_failure}')
                reports[index].refused_saved = index in refused
                try:
                    save_result(reports[index], digests[index], signer, names)
                except OSError as error:  # the run's report is still in the batch's
                    progress.fault(f'cannot save {printable(str(job.out_dir / RESULT_NAME))}: '
                                   f'{error.strerror or error}')
                progress.finish(job.name, reports[index])
    finally:
        for child in running.values():
            child.kill()
    return [reports[index] for index in range(len(jobs))]


def start_child(job: GradeJob, limits: Limits, options: dict[str, Any],
                progress: BatchProgress) -> 'Child | RunReport':
    """
    Start ``job``'s run in a child process; return it, or the report of why it cannot start.

    A run whose folder cannot be written (a full or read-only disk) fails alone, and the
    progress names it as a fault of the grader.
    """
    shutil.rmtree(job.out_dir, ignore_errors=True)
    # The child works in a scratch folder: every path it gets is absolute.
    run = ScenarioRun(job.run.scenario.absolute(), job.run.seed)
    try:
        child = Child(Job(run, job.out_dir.resolve(), limits, options))
    except OSError as error:
        why = f'cannot write {printable(str(job.out_dir))}: {error.strerror or error}'
        progress.fault(f'{job.name} not run: {why}')
        return RunReport(job.run, job.out_dir, [], None, f'the run could not start: {why}', 0.0)
    progress.start(job.name)
    return child


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
    return text_table(rows[0], rows[1:], right=[2])


def summary(reports: list[RunReport], tasks: list[marks.TaskMarks] | None = None) -> str:
    """Return the one-line verdict of a batch, with its marks by task, naming the failed runs."""
    failed = [report.run.name for report in reports if not report.passed]
    text = f'{len(reports) - len(failed)} of {len(reports)} runs passed'
    earned = marks.summary(tasks or [])
    text += f', {earned}' if earned else ''
    return text + (f"; failed: {', '.join(failed)}" if failed else '')
