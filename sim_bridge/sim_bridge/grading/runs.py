"""
What a grading is made of: a job, its run judged, its report, and the batch's report files.

A :class:`GradeJob` is one seed of a scenario with its output folder; :func:`run_scenario` runs
it with the stepped runner and judges the scenario's criteria into a :class:`RunReport`, whose
:meth:`RunReport.as_dict` is the run's entry in ``result.json`` and ``report.json`` (strict
JSON, bounded texts: :mod:`sim_bridge.common.text`). The grader (:mod:`sim_bridge.grading.batch`),
a class's batch (:mod:`sim_bridge.grading.class_batch`) and each run's child process
(:mod:`sim_bridge.grading.isolate`) all build on this module, which imports none of them.
"""

from collections.abc import Callable, Iterable
from dataclasses import dataclass
import json
import os
from pathlib import Path
import sys
import time
import traceback
from typing import Any

from sim_bridge.common.errors import RunError
from sim_bridge.common.text import (
    cap_text, first_line, json_safe, outcome, PathNames, printable)
from sim_bridge.grading.criteria import CriterionResult
from sim_bridge.grading.marks import as_dict as marks_as_dict, TaskMarks
from sim_bridge.grading.scenario import ScenarioRun
from sim_bridge.grading.task_points import judge_points, Point, unearned_points
from sim_bridge.runner.run import run_simulation

#: Each run's captured output (stdout and stderr of its process), in its folder.
LOG_NAME = 'log.txt'
REPORT_NAME = 'report.json'
PAGE_NAME = 'report.html'
#: Each run's folder gets its report here when it ends; a later invocation resumes from it.
RESULT_NAME = 'result.json'

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
    #: True when the run was finished by an earlier invocation and its result read back.
    reused: bool = False
    #: True when an earlier invocation's result was there but changed since (run again).
    refused_saved: bool = False

    @property
    def passed(self) -> bool:
        """Return True when the run completed and every criterion holds."""
        return self.error is None and all(result.passed for result in self.results)

    @property
    def points(self) -> list[Point]:
        """
        Return the handout's points of the scenario's ``points:`` judged on this run.

        A run that failed as a whole (not submitted, could not start, ended early) shows no
        point: each is lost for that reason; a point a node that raised did not show is lost
        for its node error. Judged from the metrics, so a report read back
        judges them the same way. Empty for a scenario without points.
        """
        point_set = self.run.scenario.points
        if point_set is None:
            return []
        if self.error is not None or self.metrics is None:
            return unearned_points(point_set, first_line(self.error or 'no metrics'))
        points = judge_points(point_set, self.metrics)
        node_errors = self.metrics.get('node_errors') or []
        if node_errors:  # what the node did not show, it did not show for this reason
            why = first_line(f"node error: {node_errors[0].get('error')}")
            points = [point if point.earned else Point(point.point, False, why, point.rule)
                      for point in points]
        return points

    @property
    def sim_time_s(self) -> float:
        """Return the simulated seconds (s) the run reached: 0 for one that never started."""
        sim_s = (self.metrics or {}).get('sim_time_s')
        return float(sim_s) if isinstance(sim_s, (int, float)) else 0.0

    @classmethod
    def from_dict(cls, run: ScenarioRun, out_dir: Path, entry: Any) -> 'RunReport':
        """
        Return the report of ``run`` from its JSON entry (:meth:`as_dict`).

        Its texts are bounded (:func:`json_safe`); ValueError says what in an entry that
        :meth:`as_dict` did not write is wrong.
        """
        problem = entry_problem(entry)
        if problem is not None:
            raise ValueError(problem)
        entry = json_safe(entry)
        return cls(run, out_dir, [CriterionResult(**result) for result in entry['criteria']],
                   entry['metrics'], entry['error'], entry['wall_time_s'], entry['traceback'])

    def as_dict(self, names: PathNames | None = None) -> dict[str, Any]:
        """
        Return the run's entry of the JSON report, valid strict JSON with bounded texts.

        ``names`` replaces the grader's absolute paths in paths and texts (see
        :func:`report_names`); without it, paths are as the grader has them.
        """
        scenario = self.run.scenario
        names = names or PathNames({})
        log = self.out_dir / LOG_NAME

        def path(value: Path | str) -> str:
            return names.path(value) if os.path.exists(value) else names(str(value))

        entry = {
            'run': self.run.name, 'scenario': scenario.name,
            'file': path(scenario.path) if scenario.path else None,
            'world': path(scenario.world), 'nodes': [path(node) for node in scenario.nodes],
            'seed': self.run.seed, 'duration_s': scenario.duration_s,
            'params': self.run.params, 'start': scenario.start, 'robot': scenario.robot,
            'remap': list(scenario.remap), 'setpoint': scenario.setpoint,
            'drive': [segment.as_dict() for segment in scenario.drive], 'passed': self.passed,
            'error': self.error, 'traceback': self.traceback,
            'criteria': [result.as_dict() for result in self.results],
            'points': [point.as_dict() for point in self.points],
            'out_dir': names.path(self.out_dir), 'wall_time_s': self.wall_time_s,
            'metrics': self.metrics, 'log': names.path(log) if log.is_file() else None,
            'reused': self.reused,
        }
        entry['outcome'] = outcome(entry)
        return json_safe(entry, lambda text: cap_text(names(text)))


def entry_problem(entry: Any) -> str | None:
    """Return what makes ``entry`` not a run entry :meth:`RunReport.as_dict` writes, or None."""
    if not isinstance(entry, dict):
        return f'expected a mapping, got {type(entry).__name__}'
    kinds = {'criteria': list, 'metrics': (dict, type(None)), 'error': (str, type(None)),
             'traceback': (str, type(None)), 'wall_time_s': (int, float)}
    for key, kind in kinds.items():
        if key not in entry:
            return f"no '{key}'"
        if not isinstance(entry[key], kind) or isinstance(entry[key], bool):
            return f"'{key}' is {type(entry[key]).__name__}"
    for index, result in enumerate(entry['criteria']):
        if not (isinstance(result, dict) and set(result) == {'criterion', 'passed', 'value',
                                                             'shown'}
                and isinstance(result['criterion'], str) and isinstance(result['shown'], str)
                and isinstance(result['passed'], bool)):
            return f'criteria[{index}] is not a judged criterion'
    metrics = entry['metrics'] or {}
    for key, fields in (('node_errors', ('node', 'error')), ('warnings', None)):
        items = metrics.get(key, [])
        if not isinstance(items, list):
            return f"metrics '{key}' is {type(items).__name__}"
        for index, item in enumerate(items):
            good = (isinstance(item, str) if fields is None else isinstance(item, dict)
                    and all(isinstance(item.get(name), str) for name in fields))
            if not good:
                kind = 'text' if fields is None else 'node error'
                return f"metrics '{key}'[{index}] is not a {kind}"
    return None


def run_scenario(run: ScenarioRun, out_dir: Path, *, simulate: Simulate | None = None,
                 quiet: bool = True, record: bool = True, plot: bool = True,
                 progress: Callable[[float, float], None] | None = None) -> RunReport:
    """
    Run one seed of a scenario with ``simulate`` (default: the stepped runner) and judge it.

    A run that cannot start (bad world, target or parameter) or whose runner crashes is
    reported with its error and fails; a node raising during the run is in the metrics'
    ``node_errors`` and fails the criteria that look at it; a run a node ended early fails
    (:func:`ended_early`).
    """
    if simulate is None:
        simulate = run_simulation
    scenario = run.scenario
    wall_start = time.perf_counter()
    try:
        result = simulate(scenario.world, list(scenario.nodes), duration_s=scenario.duration_s,
                          seed=run.seed, params=run.params, out_dir=out_dir,
                          start=scenario.start, robot=scenario.robot, remap=scenario.remap,
                          setpoint=scenario.setpoint.get('wall_distance_m'),
                          printed=scenario.printed, quiet=quiet, record=record, plot=plot,
                          drive=scenario.drive or None,
                          progress=progress)
    except Exception as error:  # one broken run must not stop the batch
        # A run that cannot start keeps the node's part of the traceback (its import failed),
        # or none (bad input); a crash of the runner keeps all of it.
        kept = error.traceback if isinstance(error, RunError) else traceback.format_exc()
        return RunReport(run, out_dir, [], None, f'{type(error).__name__}: {error}',
                         time.perf_counter() - wall_start, kept)
    return RunReport(run, out_dir, scenario.judge(result.metrics), result.metrics,
                     ended_early(result.metrics, scenario.duration_s),
                     time.perf_counter() - wall_start)


def ended_early(metrics: dict[str, Any], duration_s: float) -> str | None:
    """
    Return why a run that a node ended (``rclpy.shutdown()``) before ``duration_s`` (s) fails.

    The runner ends such a run as the node's process would end, not as a node error; a grade
    still needs the whole scenario, or a node could pass by quitting before it is tested.
    """
    if not metrics.get('ended_by'):
        return None
    return (f"the run ended at {metrics['sim_time_s']:.1f} s of its {duration_s:g} s: "
            f"{metrics['ended_by']}")


@dataclass(frozen=True)
class GradeJob:
    """A run to grade, its output folder, and what the progress calls it (default: the run's)."""

    run: ScenarioRun
    out_dir: Path
    label: str = ''

    @property
    def name(self) -> str:
        """Return what the progress calls the run: its label, or ``<scenario>/seed_<n>``."""
        return self.label or self.run.name


def reuse_notes(reports: list[RunReport], out: Path) -> list[str]:
    """
    Say which outputs below ``out`` are not from this invocation's runs.

    Runs reused from an earlier invocation (their inputs unchanged), and results of runs
    that are not in this batch (a batch of other scenarios graded into the same ``out``).
    """
    notes = []
    reused = sum(report.reused for report in reports)
    if reused:
        notes.append(f'{reused} of {len(reports)} runs reused from an earlier invocation into '
                     'this folder (their inputs did not change; --fresh runs them again)')
    refused = [report.run.name for report in reports if report.refused_saved]
    if refused:
        shown = ', '.join(printable(name) for name in refused[:3])
        notes.append(f'1 saved result was run again: it was changed since the grader wrote it '
                     f'({shown})' if len(refused) == 1 else
                     f'{len(refused)} saved results were run again: they were changed since '
                     f"the grader wrote them ({shown}{', ...' if len(refused) > 3 else ''})")
    ours = {os.path.abspath(report.out_dir) for report in reports}
    others = sorted(os.path.relpath(path.parent, out) for path in out.rglob(RESULT_NAME)
                    if os.path.abspath(path.parent) not in ours)
    if others:
        shown = ', '.join(printable(name) for name in others[:3])
        notes.append(f'this folder also holds the results of {len(others)} runs not in this '
                     f"batch ({shown}{', ...' if len(others) > 3 else ''}); they are not in "
                     'this report')
    return notes


def write_report(reports: list[RunReport], path: Path, *, overrides: Iterable[str] = (),
                 names: PathNames | None = None, notes: Iterable[str] = (),
                 marks: list[TaskMarks] | None = None) -> None:
    """
    Write the JSON report of a batch; ``names`` names its paths (see report_names).

    ``marks`` (:func:`sim_bridge.grading.marks.task_marks`) add the batch's marks per task and in
    all.
    """
    document = {
        'passed': all(report.passed for report in reports),
        'summary': {'runs': len(reports), 'passed': sum(report.passed for report in reports),
                    'failed': sum(not report.passed for report in reports),
                    'reused': sum(report.reused for report in reports)},
        'notes': [printable(note) for note in notes],
        'node_overrides': [printable(override) for override in overrides],
        'runs': [report.as_dict(names) for report in reports],
    }
    if marks is not None:
        document['marks'] = marks_as_dict(marks)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2, allow_nan=False) + '\n', encoding='utf-8')


def write_outputs(writers: dict[Path, Callable[[Path], Any]]) -> list[Path]:
    """
    Write each file with its writer, on to the next when one fails; return the unwritten.

    Each failure is printed on stderr in one line naming the file: a batch's other outputs
    never depend on one of them.
    """
    unwritten = []
    for path, write in writers.items():
        try:
            write(path)
        except Exception as error:  # noqa: B902 whatever it was, the other files are written
            unwritten.append(path)
            why = error.strerror if isinstance(error, OSError) and error.strerror else error
            print(f'error: cannot write {printable(os.fspath(path))}: {printable(str(why))}',
                  file=sys.stderr)
    return unwritten
