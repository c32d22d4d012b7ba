"""
Closed-loop grading: the shipped scenarios pass the real grader, every handout point earned.

Naive nodes fail them, or lose points.

Every seed of every scenario in ``scenarios/`` is one test. The module grades them all at
once as ``python -m sim_bridge.grade --jobs N`` does (``grade_runs``: each run a child process
of its own, in the stepped simulator on real rclpy, N the machine's cores); each test checks
its run's report. Recording and plotting are off except for one run, graded again in this
process with ``run_scenario``, which checks they are written too.
The naive nodes in ``examples/`` (written the way the lab's own solutions are) replace
the scenario's node, as ``--node-override`` does, and must fail on behaviour (a criterion, or a
point of the handout), not by crashing.
``pytest -s`` prints the measured figures as tables when the module ends.
"""

import json
import os
from pathlib import Path
import re

import pytest

from sim_bridge.commands import grade
from sim_bridge.common.text import json_safe
from sim_bridge.grading.batch import grade_runs
from sim_bridge.grading.runs import GradeJob, run_scenario
from sim_bridge.grading.scenario import load_scenarios, ScenarioRun

HERE = Path(__file__).resolve().parent
SCENARIOS = HERE.parent / 'scenarios'
NAIVE_NODES = HERE.parent / 'examples'
NO_NODE_ERRORS = 'len(node_errors) == 0'
COLLISION_FREE = 'collisions == 0'
#: The run graded with its rosbag2 recording and trajectory plot written, as the demo does.
RECORDED_RUN = 'wall_follow_box_cw/seed_1'
#: Scenario name prefix -> naive node files that must each fail that scenario on every seed.
NAIVE_OVERRIDES = {
    'wall_follow_': ('naive_wall_follow.py',), 'wanderbot': ('naive_wanderbot.py',),
    'scan_ahead': ('constant_scan_ahead.py', 'first_beam_scan_ahead.py', 'silent_scan_ahead.py'),
    'scan_around': ('handout_scan_around.py',),
    'closest_obstacle': ('closest_obstacle_from_zero.py',),
}
#: Naive reading node -> what the one-line reason of its failed printed-value criterion says.
NAIVE_REASONS = {
    'constant_scan_ahead.py': 'scan_ahead: range ahead printed 42 at t=',
    'first_beam_scan_ahead.py': 'range ahead printed ',
    'silent_scan_ahead.py': 'no line printed the range ahead (',
    'handout_scan_around.py': 'scan_around: left printed ',
    'closest_obstacle_from_zero.py': "closest_obstacle: closest obstacle's bearing ",
}
#: Scenario name prefix -> the behaviour criteria its naive node passes (it fails all others).
#: Round the post (radius 0.1 m) the naive node's fixed circle, of radius 1.0 m about a point
#: 0.4 m beyond the post's centre, goes round the post 0.35 m clear of it: it does its laps
#: without touching it and passes every criterion, losing the handout's point of the wall
#: distance only (0.5 to 1.3 m from the post: NAIVE_LOSES).
NAIVE_PASSES = {'wall_follow_post_': {'laps <= -1', 'laps >= 1', COLLISION_FREE},
                # The teleop drives the reading nodes' robot: they fail on what they print.
                'scan_': {COLLISION_FREE}, 'closest_obstacle': {COLLISION_FREE}}
#: Scenario name prefix -> a point of the handout its naive node loses whatever it passes.
NAIVE_LOSES = {'wall_follow_': 'keeps the wall at the distance it chose',
               'wanderbot': 'turns more than 90 degrees'}

SHIPPED_RUNS = [run for scenario in load_scenarios([SCENARIOS]) for run in scenario.runs()]
NAIVE_RUNS = [run for scenario in load_scenarios([SCENARIOS])
              for prefix, node_files in NAIVE_OVERRIDES.items()
              if scenario.name.startswith(prefix) for node_file in node_files
              for run in scenario.with_node_override(str(NAIVE_NODES / node_file)).runs()]


def run_id(run: ScenarioRun) -> str:
    """Name a test after its run: ``<node>@<scenario>/seed_<n>``."""
    return f'{Path(run.scenario.nodes[0].partition(":")[0]).stem}@{run.name}'


def number(value, digits: int = 3) -> str:
    """Format a measured number for the tables; '-' when there is none."""
    return '-' if value is None else f'{value:.{digits}f}'


def is_number(text: str) -> bool:
    """Return True for a table cell that shows a number (or '-' for none)."""
    try:
        float(text)
    except ValueError:
        return text == '-'
    return True


def table(title: str, header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    """Return a text table with a title line; columns of numbers are right-aligned."""
    columns = list(zip(header, *rows))
    widths = [max(map(len, column)) for column in columns]
    numeric = [all(map(is_number, column[1:])) for column in columns]
    lines = ['  '.join(cell.rjust(width) if right else cell.ljust(width)
                       for cell, width, right in zip(row, widths, numeric)).rstrip()
             for row in [header, *rows]]
    return '\n'.join([title, lines[0], '-' * len(lines[0]), *lines[1:]])


class Figures:
    """The measured figures of the module's runs, printed as one table per kind of scenario."""

    WALL_FOLLOW = ('run', 'laps', 'first lap s', 'MAE m', 'min clearance m', 'collisions')
    WANDER = ('run', 'collisions', 'turns', 'min turn deg', 'max stationary s', 'coverage')
    OTHER = ('run', 'node errors', 'collisions', 'min clearance m', 'printed lines',
             'scans missed', 'worst error m')
    NAIVE = ('run', 'failed criteria')

    def __init__(self) -> None:
        self.rows: dict[tuple, list[tuple[str, ...]]] = {
            self.WALL_FOLLOW: [], self.WANDER: [], self.OTHER: [], self.NAIVE: []}

    def add(self, report: grade.RunReport) -> None:
        """Add a shipped scenario run's figures to its kind's table."""
        metrics, name = report.metrics, report.run.name
        if name.startswith('wall_follow_'):
            laps = metrics['lap_times_s']
            self.rows[self.WALL_FOLLOW].append((
                name, str(metrics['laps']), number(laps[0] if laps else None, 1),
                number(metrics['wall_distance_m']['mae']), number(metrics['min_clearance_m']),
                str(metrics['collisions'])))
        elif name.startswith('wanderbot'):
            turns = metrics['turns_deg']
            self.rows[self.WANDER].append((
                name, str(metrics['collisions']), str(len(turns)),
                number(min(turns) if turns else None, 1), number(metrics['max_stationary_s'], 2),
                number(metrics['coverage'], 2)))
        else:
            printed = next(iter(metrics['printed'].values()), {})
            self.rows[self.OTHER].append((
                name, str(len(metrics['node_errors'])), str(metrics['collisions']),
                number(metrics['min_clearance_m']), str(printed.get('lines', '-')),
                str(printed.get('missed', '-')), number(printed.get('worst_error_m'))))

    def add_failure(self, label: str, failed: dict[str, str]) -> None:
        """Add a run that had to fail, with the criteria it failed and their measured values."""
        self.rows[self.NAIVE].append((label, ', '.join(
            f'{criterion} [{shown}]' for criterion, shown in failed.items())))

    def __str__(self) -> str:
        titles = {self.WALL_FOLLOW: 'wall_follow (laps < 0: clockwise)',
                  self.WANDER: 'wanderbot in the room, 600 s',
                  self.OTHER: 'scan-reading nodes',
                  self.NAIVE: 'naive nodes (must fail)'}
        return '\n\n'.join(table(titles[header], header, rows)
                           for header, rows in self.rows.items() if rows)


@pytest.fixture(scope='module')
def figures():
    """Collect the module's figures and print them when it ends (seen with ``pytest -s``)."""
    collected = Figures()
    yield collected
    print('\n\n' + str(collected))


def failed_criteria(report: grade.RunReport) -> dict[str, str]:
    """Return each failed criterion of a run with the value measured for it."""
    return {result.criterion: result.shown for result in report.results if not result.passed}


@pytest.fixture(scope='module')
def graded(tmp_path_factory) -> dict[str, grade.RunReport]:
    """Grade every shipped and naive run in child processes, all cores busy; by run id."""
    folder = tmp_path_factory.mktemp('graded')
    runs = {run_id(run): run for run in SHIPPED_RUNS + NAIVE_RUNS}
    reports = grade_runs([GradeJob(run, folder / name) for name, run in runs.items()],
                         workers=os.cpu_count() or 1, resume=False, quiet=True, record=False,
                         plot=False)
    return dict(zip(runs, reports))


@pytest.mark.parametrize('run', SHIPPED_RUNS, ids=run_id)
def test_shipped_scenario_run_passes_every_criterion(run, graded, figures):
    report = graded[run_id(run)]
    assert report.error is None, report.traceback
    figures.add(report)
    assert failed_criteria(report) == {}
    assert [result.criterion for result in report.results] == \
        [criterion.text for criterion in run.scenario.criteria]
    assert [point.reason for point in report.points if not point.earned] == []
    if run.scenario.name == 'wanderbot':
        assert 0.0 < report.metrics['coverage'] <= 1.0


def comparable(metrics: dict) -> dict:
    """Return a run's metrics but for its wall time and its sandbox (its uid, its memory)."""
    return {**metrics, 'wall_time_s': 0, 'real_time_factor': 0,
            'run_mode': {**metrics['run_mode'], 'sandbox': ''}}


def test_a_run_graded_in_process_writes_its_recording_and_plot(tmp_path, graded):
    [run] = [run for run in SHIPPED_RUNS if run.name == RECORDED_RUN]
    report = run_scenario(run, tmp_path, record=True, plot=True)
    assert report.passed, report.error
    # The same run in a child, unrecorded, measured the same: recording changes nothing.
    assert comparable(report.metrics) == comparable(graded[run_id(run)].metrics)
    assert (tmp_path / 'trajectory.png').stat().st_size > 0
    assert (tmp_path / 'run' / 'metadata.yaml').is_file()
    assert [path.stat().st_size > 0 for path in (tmp_path / 'run').glob('*.mcap')] == [True]


@pytest.mark.parametrize('run', NAIVE_RUNS, ids=run_id)
def test_naive_node_runs_to_the_end_but_fails_its_behaviour_criteria(run, graded, figures):
    report = graded[run_id(run)]
    assert report.error is None, report.traceback
    figures.add_failure(run_id(run), failed_criteria(report))
    behaviour = {criterion.text for criterion in run.scenario.criteria} - {NO_NODE_ERRORS}
    assert COLLISION_FREE in behaviour
    passes = next((criteria for prefix, criteria in NAIVE_PASSES.items()
                   if run.scenario.name.startswith(prefix)), set())
    assert failed_criteria(report).keys() == behaviour - passes
    lost = {point.point: point.reason for point in report.points if not point.earned}
    assert failed_criteria(report) or lost
    loses = next((point for prefix, point in NAIVE_LOSES.items()
                  if run.scenario.name.startswith(prefix)), None)
    assert loses is None or loses in lost, lost
    says = NAIVE_REASONS.get(Path(run.scenario.nodes[0]).name)
    if says is not None:
        [why] = [shown for criterion, shown in failed_criteria(report).items()
                 if criterion.startswith('printed_')]
        assert says in why and '\n' not in why


def test_every_naive_node_is_graded_on_every_seed_of_its_scenarios():
    graded = {(Path(run.scenario.nodes[0]).name, run.name) for run in NAIVE_RUNS}
    expected = {(node_file, run.name) for run in SHIPPED_RUNS
                for prefix, node_files in NAIVE_OVERRIDES.items()
                if run.scenario.name.startswith(prefix) for node_file in node_files}
    assert graded == expected
    assert {node_file for node_file, _ in graded} == {
        node_file for node_files in NAIVE_OVERRIDES.values() for node_file in node_files}


def test_grader_cli_fails_an_int_in_a_float_field_naming_the_field(tmp_path, capsys, figures):
    node_file = NAIVE_NODES / 'int_twist.py'
    exit_code = grade.main([str(SCENARIOS / 'scan_ahead.yaml'), '--node-override',
                            str(node_file), '--out', str(tmp_path), '--quiet'])
    assert exit_code == 1
    assert re.search(rf'{re.escape(NO_NODE_ERRORS)}\s+1\s+FAIL', capsys.readouterr().out)
    report = json.loads((tmp_path / grade.REPORT_NAME).read_text())
    assert report['node_overrides'] == [str(node_file)]
    [run] = report['runs']
    names = grade.report_names(tmp_path)  # a report names paths as a student may read them
    assert run['nodes'] == [names.path(node_file)] and not run['passed'] and run['error'] is None
    # Its run ends at its first command, and it prints no range ahead: no other reason to fail.
    assert [criterion['criterion'] for criterion in run['criteria']
            if not criterion['passed']] == [NO_NODE_ERRORS, 'printed_range_ahead: max_error_m '
                                            '0.06, min_matched_fraction 0.9']
    [error] = run['metrics']['node_errors']
    figures.add_failure(f'int_twist@{run["run"]}', {NO_NODE_ERRORS: error['error']})
    assert error['node'] == 'straight_ahead'
    assert "The 'z' field must be of type 'float'" in error['error']
    assert 'angular.z = ' in error['error'] and 'int_twist.py' in error['error']
    out_dir = tmp_path / 'scan_ahead' / 'seed_1'
    assert json_safe(json.loads((out_dir / 'metrics.json').read_text()), names) == run['metrics']
    assert (out_dir / 'trajectory.png').is_file() and (out_dir / 'run' / 'metadata.yaml').is_file()
