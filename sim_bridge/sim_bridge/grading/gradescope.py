"""
Gradescope: the autograder's ``results.json`` for a graded submission, and ``autograder.zip``.

Gradescope grades each submission in a container of its own (Ubuntu; the autograder
specification: https://gradescope-autograders.readthedocs.io/en/latest/specs/). Its
``autograder.zip`` holds ``setup.sh``, run once when the image is built, and
``run_autograder``, run per submission in ``/autograder`` with the student's files in
``/autograder/submission``; it must write ``/autograder/results/results.json``.

``python -m sim_bridge.grade SCENARIO... --submission DIR --gradescope results.json`` writes
the results (:func:`results`): the marks as the score, a test per point (or per scenario),
ordered by task. ``python -m sim_bridge.commands.autograder build SCENARIO... -o
autograder.zip`` (``./lab autograder``) builds the zip: the kit (the two packages, worlds,
models, ``lab`` and its requirements), the chosen scenario files, ``setup.sh`` (a venv with what
grading needs: the runtime requirements, ROS 2 Jazzy's runtime wheels and the kit; no
development tools) and ``run_autograder``. ``AUTOGRADER_ROOT`` (default ``/autograder``) moves
the root ``run_autograder`` works in, so it can be tried on a folder laid out as Gradescope
lays it out.
"""

from collections.abc import Callable
import json
import os
from pathlib import Path
import re
import stat
from typing import Any
import zipfile

from sim_bridge.common.paths import WORLD_FILE_SUFFIXES, world_names
from sim_bridge.common.text import cap_text, PathNames, printable, reason
from sim_bridge.grading.batch import BatchProgress, format_table
from sim_bridge.grading.isolate import trimmed_environment
from sim_bridge.grading.marks import (
    format_marks, summary as marks_summary, task_marks, TaskMarks, total)
from sim_bridge.grading.runs import GradeJob, RunReport
from sim_bridge.grading.scenario import load_scenarios, Scenario, ScenarioError

#: The most bytes of one test's output in results.json (the reason, the table, tracebacks).
OUTPUT_LIMIT_BYTES = 8 * 1024
#: The shortest value of the grader's environment taken for a secret (characters), and what
#: stands for a secret in results.json.
SECRET_MIN_CHARS = 8
HIDDEN = '<hidden>'
#: The failed runs whose reasons a test's output lists before its table.
REASONS_SHOWN = 3
#: What the zip carries of the kit, relative to the workspace's top.
KIT_FILES = ('lab', 'requirements.txt', 'requirements-dev.txt', 'requirements-ros.txt',
             'requirements-ros-dev.txt',
             'scan_pkg', 'sim_bridge', 'worlds', 'models')
#: Folders of the kit left out of the zip: tests, caches and build outputs.
SKIPPED_FOLDERS = {'test', '__pycache__', '.pytest_cache', 'build', 'install', 'log'}
KIT_DIR = 'kit'
SCENARIOS_DIR = 'scenarios'

SETUP_SH = r"""#!/usr/bin/env bash
# Gradescope runs this once, as root, when it builds the autograder's image (Ubuntu 22.04,
# Python 3.10): Python 3 with venv, then a venv in kit/.venv with what grading needs and
# nothing for development: the kit's runtime requirements (requirements.txt), ROS 2 Jazzy's
# runtime wheels (requirements-ros.txt without the ament linters) and the two packages. No
# colcon, no linters, no pytest; no display needed.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
kit=$here/kit
export DEBIAN_FRONTEND=noninteractive
apt-get update
# python3-dev and build-essential: pip compiles pybullet where it has no wheel (Python >= 3.12);
# bubblewrap: the sandbox each student run is in.
apt-get install -y --no-install-recommends python3 python3-venv python3-pip python3-dev \
    build-essential bubblewrap
python3 -m venv "$kit/.venv"
ros=$(grep -v -E '^[[:space:]]*(#|$)|ament-(flake8|pep257)' "$kit/requirements-ros.txt")
# shellcheck disable=SC2086  # one requirement a word
"$kit/.venv/bin/python" -m pip install --quiet --no-cache-dir -r "$kit/requirements.txt" $ros
"$kit/.venv/bin/python" -m pip install --quiet --no-cache-dir --no-deps "$kit/scan_pkg" \
    "$kit/sim_bridge"
# pip builds each package in its folder, where setuptools leaves a copy of it (build/lib: the
# reference nodes, readable by any user) and its egg-info: no run may read them.
rm -rf "$kit/scan_pkg/build" "$kit/sim_bridge/build" "$kit"/scan_pkg/*.egg-info \
    "$kit"/sim_bridge/*.egg-info
"""

RUN_AUTOGRADER = r"""#!/usr/bin/env bash
# Gradescope runs this for each submission: grade $root/submission against the scenarios in
# $root/source/scenarios and write $root/results/results.json (always: a submission that
# cannot be graded gets a score of 0 and says why). AUTOGRADER_ROOT moves the root (tests);
# AUTOGRADER_PYTHON names another Python with the kit's requirements.
root=${AUTOGRADER_ROOT:-/autograder}
kit=$root/source/kit
python=${AUTOGRADER_PYTHON:-$kit/.venv/bin/python}
results=$root/results
mkdir -p "$results"
# A grade of 0 that says why; the texts hold no quote or backslash (they are JSON as they are).
fail() {
    printf '{"score": 0.0, "output": "%s", "output_format": "text", "tests": []}\n' "$1" \
        > "$results/results.json"
}
if [ ! -x "$python" ]; then
    fail "The autograder is not set up (its Python is missing: setup.sh did not finish).\
 Please tell your instructor."
    exit 0
fi
cd "$root"
# Runs without namespaces (PARTLY sandboxed) see this machine's files as another user does:
# they must reach the kit and its venv, and must not read the scenarios.
chmod o+x "$root" "$root/source"
chmod -R go-rwx "$root/source/scenarios"
# The kit in the zip, whatever else the Python has installed. No bags nor plots: Gradescope
# shows results.json alone.
export PYTHONPATH=$kit/scan_pkg:$kit/sim_bridge${PYTHONPATH:+:$PYTHONPATH}
export MPLBACKEND=Agg
"$python" -m sim_bridge.grade "$root/source/scenarios" --submission "$root/submission" \
    --gradescope "$results/results.json" --out "$results/graded" --jobs "$(nproc)" \
    --no-record --no-plot --quiet
status=$?
# The grader writes results.json whatever happens; a non-empty one is the grade.
[ -s "$results/results.json" ] || fail "The grader stopped (exit status $status) before it\
 wrote the results. Please tell your instructor."
exit 0
"""


class StudentNames(PathNames):
    """
    What a student may read of the grader's texts: ``names``' paths, and no grader secret.

    Each value of the grader's environment that a run is not given (a token, a key: see
    :func:`sim_bridge.grading.isolate.trimmed_environment`) and that is SECRET_MIN_CHARS or
    longer is replaced by HIDDEN wherever it appears, a run's own output included (a node can
    read its process's first environment in ``/proc/self/environ``).
    """

    def __init__(self, names: PathNames, environ: dict[str, str] | None = None) -> None:
        super().__init__(names.folders)
        environ = os.environ if environ is None else environ
        given = trimmed_environment(Path('.'), environ)
        hidden = sorted({value for name, value in environ.items()
                         if name not in given and len(value) >= SECRET_MIN_CHARS
                         and os.path.abspath(value) not in names.folders},
                        key=len, reverse=True)
        self.secrets = re.compile('|'.join(map(re.escape, hidden))) if hidden else None

    def __call__(self, text: str) -> str:
        """Return ``text`` without the grader's secrets, its folders named (see PathNames)."""
        if self.secrets is not None:
            text = self.secrets.sub(HIDDEN, text)
        return super().__call__(text)


def results(reports: list[RunReport], scenarios: list[Scenario],
            table: Callable[[list[RunReport]], str], names: PathNames | None = None,
            notes: list[str] = ()) -> dict[str, Any]:
    """
    Return Gradescope's results of one submission's graded runs.

    The score is the marks (:mod:`sim_bridge.grading.marks`). A task marked by the handout's points
    has a test per point, named ``task 2: no collision``, scoring the point's marks, its
    output saying why it was lost and the rule it is judged by, and a test of its runs for
    information (``task 2: runs (for information)``: no score, no status) with their ``table``
    (grade's pass/fail table). Another task has a test per scenario, named ``task 1:
    scan_ahead``, scoring its share of its task's marks (a scenario without marks scores 0 of
    0), passing when every run of it passed (so when it earns all its marks), its output saying
    why the runs failed, how the task is marked and the runs' ``table``. No test's status
    contradicts its score. Tests are ordered by task, without the grader's paths (``names``),
    each output cut to OUTPUT_LIMIT_BYTES.
    """
    names = StudentNames(names or PathNames({}))
    entries = [report.as_dict(names) for report in reports]
    tasks = task_marks(scenarios, entries)
    tests = []
    for task in tasks:
        runs = [report for report in reports if report.run.scenario.name in task.scenarios]
        if task.points:
            tests += [_test(f'{task.title}: {point.point}', point.earned, point.marks,
                            not point.lost,
                            [point.why() or f'shown in every run ({point.runs})',
                             *([f'rule: {point.rule}'] if point.rule else [])])
                      for point in task.points]
            passed = sum(report.passed for report in runs)
            lines = [f'{passed} of {len(runs)} runs met every criterion of their scenario '
                     "(for information: the marks are the points' tests)", task.rule(), '',
                     names(table(runs)), *tracebacks(runs, names)]
            tests.append(_test(f'{task.title}: runs (for information)', 0.0, 0.0, None,
                               lines))
            continue
        for scenario in task.scenarios:
            tests.append(_scenario_test(task, scenario, reports, entries, table, names))
    earned, _ = total(tasks)
    runs_passed = sum(report.passed for report in reports)
    output = [marks_summary(tasks) or 'no scenario carries marks',
              f'for information: {runs_passed} of {len(reports)} runs met every criterion of '
              'their scenario (the marks are the tests below)', *map(printable, notes)]
    return {'score': round(earned, 4), 'output': '\n'.join(output), 'output_format': 'text',
            'visibility': 'visible', 'tests': tests}


def _test(name: str, score: float, maximum: float, passed: bool | None,
          lines: list[str]) -> dict[str, Any]:
    """
    Return one test of results.json: its marks (rounded), status and output.

    ``passed`` None: a test for information, with no marks and no status, so that no test
    contradicts the score (Gradescope shows it neither passed nor failed).
    """
    test = {'name': name, 'score': round(score, 4), 'max_score': round(maximum, 4),
            'output': cap_text('\n'.join(lines), OUTPUT_LIMIT_BYTES), 'visibility': 'visible'}
    if passed is not None:
        test['status'] = 'passed' if passed else 'failed'
    return test


def _scenario_test(task: TaskMarks, scenario: str, reports: list[RunReport],
                   entries: list[dict[str, Any]], table: Callable[[list[RunReport]], str],
                   names: PathNames) -> dict[str, Any]:
    """Return the test of one scenario of a task not marked by points (see results)."""
    runs = [report for report in reports if report.run.scenario.name == scenario]
    passed = sum(report.passed for report in runs)
    score, maximum = task.share(len(runs), passed)
    failed = [entry for entry in entries if entry['scenario'] == scenario
              and not entry['passed']]
    lines = [f'{passed} of {len(runs)} runs passed'
             + (f', {format_marks(score)} of {format_marks(maximum)} marks'
                if task.marks is not None else '')]
    lines += [f"{entry['run']}: {reason(entry)}" for entry in failed[:REASONS_SHOWN]]
    if len(failed) > REASONS_SHOWN:
        lines.append(f'... and {len(failed) - REASONS_SHOWN} more failed runs')
    lines += [task.rule(), '', names(table(runs))]
    lines += tracebacks(runs, names)
    # Passed when every run passed: for a scenario with marks, when it earns them all.
    return _test(f'{task.title}: {scenario}', score, maximum,
                 bool(runs) and passed == len(runs), lines)


def tracebacks(reports: list[RunReport], names: PathNames) -> list[str]:
    """Return the first failed run's traceback (a node's, or the run's), with a heading."""
    for report in reports:
        node_errors = (report.metrics or {}).get('node_errors') or []
        for text in [error.get('traceback') for error in node_errors] + [report.traceback]:
            if text:
                return ['', f'traceback of {report.run.name}:', names(text)]
    return []


class GradescopeProgress(BatchProgress):
    """
    A batch's progress that keeps Gradescope's ``results.json`` up to date as its runs end.

    After each run (finished now, or earlier and resumed), ``path`` gets the results of the
    runs finished so far, each run not yet finished failing as not graded: when Gradescope
    stops the grader at its time limit, or the grader is stopped, the student still has the
    tests of every run that finished.
    """

    def __init__(self, jobs: list[GradeJob], missing: list[RunReport],
                 scenarios: list[Scenario], path: Path, names: PathNames,
                 enabled: bool = True) -> None:
        super().__init__(len(jobs), sum(job.run.scenario.duration_s for job in jobs),
                         enabled=enabled)
        self.jobs, self.missing, self.scenarios = jobs, missing, scenarios
        self.path, self.names = path, names
        self.finished: dict[Path, RunReport] = {}

    def resume(self, report: RunReport) -> None:
        """Note a run finished by an earlier invocation, and write the results so far."""
        super().resume(report)
        self.finished[report.out_dir] = report
        self.write_results('the grading has not reached this run yet')

    def finish(self, name: str, report: RunReport) -> None:
        """Note that a run ended, and write the results so far."""
        super().finish(name, report)
        self.finished[report.out_dir] = report
        self.write_results('the grading has not reached this run yet')

    def write_results(self, why_not_graded: str, stopped: bool = False) -> None:
        """
        Write the results of the runs finished so far; the others fail, saying why.

        ``stopped``: the grading was stopped; its output says so first.
        """
        reports = [self.finished.get(job.out_dir) or RunReport(
            job.run, job.out_dir, [], None, f'not graded: {why_not_graded}', 0.0)
            for job in self.jobs]
        try:
            write_results(self.path, results(reports + self.missing, self.scenarios,
                                             format_table, self.names,
                                             [why_not_graded] if stopped else []))
        except OSError as error:  # the final write says it, once
            self.note(f'cannot write {printable(str(self.path))}: {error.strerror or error}')


def failed_results(why: str) -> dict[str, Any]:
    """Return the results of a submission that could not be graded: 0, and why."""
    why = StudentNames(PathNames({}))(why)
    return {'score': 0.0, 'output': f'The submission could not be graded: {printable(why)}',
            'output_format': 'text', 'tests': []}


def write_results(path: Path, document: dict[str, Any]) -> None:
    """Write results.json whole or not at all (a reader never sees half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + '.partial')
    partial.write_text(json.dumps(document, indent=2, allow_nan=False) + '\n', encoding='utf-8')
    partial.replace(path)


def build(scenario_paths: list[str], out: Path, root: Path) -> list[str]:
    """
    Write ``autograder.zip`` at ``out`` from the workspace ``root``; return its file names.

    ScenarioError when a scenario does not load or names its world by a file's path (the
    zip carries the chosen scenario files and the kit's worlds, nothing else).
    """
    scenarios = load_scenarios(scenario_paths)
    for scenario in scenarios:
        world = Path(scenario.world)
        if world.suffix in WORLD_FILE_SUFFIXES or world.parent != Path('.'):
            raise ScenarioError(
                f'{scenario.path}: world: {scenario.world} is a file; the autograder carries '
                "the scenario files and the kit's worlds only: name a world of worlds/ "
                f"({', '.join(world_names())})")
    out.parent.mkdir(parents=True, exist_ok=True)
    names = []
    with zipfile.ZipFile(out, 'w', zipfile.ZIP_DEFLATED) as archive:
        def add(name: str, data: bytes, executable: bool = False) -> None:
            info = zipfile.ZipInfo(name, date_time=(2024, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            mode = 0o755 if executable else 0o644
            info.external_attr = (stat.S_IFREG | mode) << 16
            archive.writestr(info, data)
            names.append(name)

        add('setup.sh', SETUP_SH.encode(), executable=True)
        add('run_autograder', RUN_AUTOGRADER.encode(), executable=True)
        for scenario in scenarios:
            add(f'{SCENARIOS_DIR}/{scenario.path.name}', scenario.path.read_bytes())
        for entry in KIT_FILES:
            for path in sorted(kit_files(root / entry)):
                add(f'{KIT_DIR}/{path.relative_to(root).as_posix()}', path.read_bytes(),
                    executable=os.access(path, os.X_OK))
    return names


def kit_files(path: Path) -> list[Path]:
    """Return the files of the kit below ``path`` (a file or folder), skipping tests and caches."""
    if path.is_file():
        return [path]
    files = []
    for folder, subfolders, filenames in os.walk(path):
        subfolders[:] = [name for name in subfolders
                         if name not in SKIPPED_FOLDERS and not name.startswith('.')
                         and not name.endswith('.egg-info')]
        files += [Path(folder) / name for name in filenames if not name.endswith('.pyc')]
    return files
