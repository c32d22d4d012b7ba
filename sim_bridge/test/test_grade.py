"""
The grader's logic with a stand-in simulator: judging, errors, progress, table, report, exit.

Runs in child processes are tested in test_isolation.py; here ``grade_runs`` is replaced by
in-process runs of the stand-in, so each test is about one piece of the grader.
"""

import contextlib
import io
import json
import os
from pathlib import Path
import signal
from types import SimpleNamespace

import pytest

from sim_bridge.commands import grade
from sim_bridge.commands.grade import main
from sim_bridge.common import paths
from sim_bridge.common.text import TEXT_LIMIT_BYTES
from sim_bridge.grading import batch
from sim_bridge.grading.batch import BatchProgress, format_duration, format_table, summary
from sim_bridge.grading.grader_state import ResultSigner
from sim_bridge.grading.runs import GradeJob, run_scenario, write_report
from sim_bridge.grading.scenario import scenario_from_dict

SCENARIO = {
    'world': 'wall_follow_box', 'nodes': ['wall_follow'], 'duration': 30.0, 'seeds': [1, 2, 3],
    'start': 'mirrored', 'params': {'wall_follow': {'side': 'left', 'seed': '$seed'}},
    'criteria': ['laps >= 1', 'collisions == 0', 'len(node_errors) == 0'],
}


CALLS = []
#: A signer of saved results with a key of the tests'.
SIGNER = ResultSigner(bytes(32))


def fake_simulate(world, targets, **options):
    """Stand in for run_simulation: seed 2 collides once, seed 3 never completes a lap."""
    CALLS.append((world, targets, options))
    seed = options['seed']
    if options['progress']:
        options['progress'](15.0, options['duration_s'])
    return SimpleNamespace(metrics={'laps': 0 if seed == 3 else 1, 'sim_time_s': 30.0,
                                    'collisions': 1 if seed == 2 else 0, 'node_errors': []})


def broken_simulate(world, targets, **options):
    raise LookupError("unknown world 'nowhere'")


@pytest.fixture
def runs():
    return scenario_from_dict(SCENARIO, 'box_ccw').runs()


def test_a_run_gets_the_scenario_settings_and_is_judged(tmp_path, runs):
    report = run_scenario(runs[0], tmp_path / 'seed_1', simulate=fake_simulate, plot=False)
    world, targets, options = CALLS[-1]
    assert (world, targets) == ('wall_follow_box', ['wall_follow'])
    assert (options['seed'], options['duration_s'], options['start']) == (1, 30.0, 'mirrored')
    assert options['params'] == {'wall_follow': {'side': 'left', 'seed': 1}}
    assert (options['out_dir'], options['plot'], options['record']) == (
        tmp_path / 'seed_1', False, True)
    assert report.passed
    assert [result.passed for result in report.results] == [True, True, True]


def test_a_run_that_cannot_start_fails_with_its_error(tmp_path, runs):
    report = run_scenario(runs[0], tmp_path, simulate=broken_simulate)
    assert not report.passed
    assert report.error == "LookupError: unknown world 'nowhere'"
    assert report.results == [] and report.metrics is None
    assert 'in broken_simulate' in report.traceback


def grade_in_process(jobs, *, progress=None, **options):
    """Stand in for grade_runs: run each job's run_scenario in this process with fake_simulate."""
    reports = []
    for job in jobs:
        reports.append(run_scenario(job.run, job.out_dir, simulate=fake_simulate))
        if progress is not None:
            progress.finish(job.name, reports[-1])
    return reports


def graded(runs, folder):
    return grade_in_process([GradeJob(run, folder / run.name) for run in runs])


def test_summary_names_the_failed_runs(tmp_path, runs):
    reports = graded(runs, tmp_path)
    assert [report.passed for report in reports] == [True, False, False]
    assert summary(reports) == '1 of 3 runs passed; failed: box_ccw/seed_2, box_ccw/seed_3'


def test_progress_prints_a_line_per_run_outside_a_terminal(tmp_path, runs):
    stream = io.StringIO()
    progress = BatchProgress(3, 90.0, stream)
    for report in graded(runs, tmp_path):
        progress.start(report.run.name)
        progress.finish(report.run.name, report)
    lines = stream.getvalue().splitlines()
    assert [line.split(' (')[0] for line in lines] == [
        '[1/3] PASS box_ccw/seed_1', '[2/3] FAIL box_ccw/seed_2: collisions == 0',
        '[3/3] FAIL box_ccw/seed_3: laps >= 1']
    assert lines[0].endswith(' s left') and lines[1].endswith(' s left')
    assert not lines[2].endswith('left')
    assert '\r' not in stream.getvalue()


class Terminal(io.StringIO):

    def isatty(self):
        return True


class Clock:

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_progress_redraws_one_bar_with_the_time_left_on_a_terminal(tmp_path, runs):
    clock, stream = Clock(), Terminal()
    progress = BatchProgress(3, 90.0, stream, clock=clock)
    first, second, _ = graded(runs, tmp_path)
    progress.start(first.run.name)
    clock.now = 10.0
    progress.advance(first.run.name, 15.0)   # 15 simulated s in 10 wall s: 75 s left take 50 s
    assert stream.getvalue().endswith(
        '0/3 runs, 17% of the simulated time, about 50 s left (running: box_ccw/seed_1)')
    clock.now = 20.0
    progress.finish(first.run.name, first)              # 30 s in 20 s: 60 s left take 40 s
    assert '[1/3] PASS box_ccw/seed_1 (30 of 30 s sim in ' in stream.getvalue()
    assert stream.getvalue().endswith('1/3 runs, 33% of the simulated time, about 40 s left')
    assert '\u2501' in stream.getvalue()  # rich's bar, redrawn in place


def test_resumed_runs_count_as_done_but_not_for_the_pace(tmp_path, runs):
    clock = Clock()
    progress = BatchProgress(3, 90.0, enabled=False, clock=clock)
    first, second, _ = graded(runs, tmp_path)
    progress.resume(first)
    assert progress.time_left_s() is None
    clock.now = 10.0
    progress.advance(second.run.name, 15.0)  # 15 s in 10 s this time; 45 s left
    assert progress.time_left_s() == pytest.approx(30.0)


@pytest.mark.parametrize('seconds, text', [
    (0.4, '0 s'), (59.4, '59 s'), (200, '3 min 20 s'), (3900, '1 h 5 min')])
def test_durations_read_as_a_person_says_them(seconds, text):
    assert format_duration(seconds) == text


def test_table_lists_each_criterion_with_its_measured_value(tmp_path, runs):
    reports = graded(runs, tmp_path)
    reports.append(run_scenario(runs[0], tmp_path, simulate=broken_simulate))
    lines = format_table(reports).splitlines()
    assert lines[0].split() == ['run', 'criterion', 'measured', 'result']
    assert lines[2].split() == ['box_ccw/seed_1', 'laps', '>=', '1', '1', 'pass']
    assert lines[3].split() == ['collisions', '==', '0', '0', 'pass']
    assert lines[6].split()[-3:] == ['0', '1', 'FAIL']
    assert lines[-1].split() == ['box_ccw/seed_1', 'error:', 'LookupError:', 'unknown', 'world',
                                 "'nowhere'", 'FAIL']
    failures = format_table(reports, failures_only=True).splitlines()
    assert [line.split()[0] for line in failures[2:]] == [
        'box_ccw/seed_2', 'box_ccw/seed_3', 'box_ccw/seed_1']


def test_table_shows_the_error_of_a_node_that_failed(tmp_path, runs):
    def simulate_failing_node(world, targets, **options):
        error = "node 'follower' published /cmd_vel: field 'angular.z' must be float"
        return SimpleNamespace(metrics={'laps': 0, 'collisions': 0,
                                        'node_errors': [{'node': 'follower', 'error': error}]})

    report = run_scenario(runs[0], tmp_path, simulate=simulate_failing_node)
    lines = format_table([report], failures_only=True).splitlines()
    assert "node error: node 'follower' published /cmd_vel: field 'angular.z'" in lines[2]
    assert lines[2].endswith('FAIL')


def test_a_coloured_error_reaches_the_table_and_the_page_as_inert_text(tmp_path, runs):
    def simulate_coloured_error(world, targets, **options):
        error = "node 'follower' raised ValueError: \x1b[2J\x1b[91mTOO CLOSE\x1b[0m\r\x00"
        return SimpleNamespace(metrics={'laps': 0, 'collisions': 0,
                                        'node_errors': [{'node': 'follower', 'error': error}]})

    report = run_scenario(runs[0], tmp_path, simulate=simulate_coloured_error)
    table = format_table([report], failures_only=True)
    assert 'raised ValueError: \\x1b[2J\\x1b[91mTOO' in table
    assert not any(char in table for char in '\x1b\r\x00')
    write_report([report], tmp_path / 'report.json')
    saved = json.loads((tmp_path / 'report.json').read_text())
    assert '\\x0d\\x00' in saved['runs'][0]['metrics']['node_errors'][0]['error']


def test_report_is_json_with_every_run_and_the_verdict(tmp_path, runs):
    reports = graded(runs[:2], tmp_path)
    write_report(reports, tmp_path / 'report.json', overrides=['ana.py'])
    document = json.loads((tmp_path / 'report.json').read_text())
    assert document['passed'] is False
    assert document['summary'] == {'runs': 2, 'passed': 1, 'failed': 1, 'reused': 0}
    assert document['node_overrides'] == ['ana.py']
    second = document['runs'][1]
    assert (second['run'], second['seed'], second['passed']) == ('box_ccw/seed_2', 2, False)
    assert second['criteria'][1] == {'criterion': 'collisions == 0', 'passed': False,
                                     'value': 1, 'shown': '1'}
    assert second['params'] == {'wall_follow': {'side': 'left', 'seed': 2}}


def scenario_file(folder: Path, **changes) -> Path:
    path = folder / 'box_ccw.yaml'
    path.write_text(json.dumps({**SCENARIO, **changes}))
    return path


def test_main_exits_non_zero_and_writes_the_report_when_a_run_fails(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(grade, 'grade_runs', grade_in_process)
    status = main([str(scenario_file(tmp_path)), '--out', str(tmp_path / 'out'), '--quiet'])
    out = capsys.readouterr().out
    assert status == 1
    assert '1 of 3 runs passed' in out and 'box_ccw/seed_2' in out
    assert 'box_ccw/seed_1' not in out.split('1 of 3')[0]
    assert json.loads((tmp_path / 'out' / grade.REPORT_NAME).read_text())['summary']['runs'] == 3


class ClosedPipe(io.StringIO):
    """A stream piped into ``head``, which has read its lines and exited."""

    def write(self, text):
        raise BrokenPipeError(32, 'Broken pipe')

    def fileno(self):
        return 1


def test_a_console_piped_into_head_that_has_exited_costs_no_run_and_no_report(
        tmp_path, monkeypatch):
    monkeypatch.setattr(grade, 'grade_runs', grade_in_process)
    monkeypatch.setattr(grade.sys, 'stderr', ClosedPipe())  # the progress lines' stream
    monkeypatch.setattr(grade.os, 'dup2', lambda *fds: None)  # pytest's own stdout stays
    with contextlib.redirect_stdout(ClosedPipe()):
        status = main([str(scenario_file(tmp_path)), '--out', str(tmp_path / 'out')])
    assert status == 1
    document = json.loads((tmp_path / 'out' / grade.REPORT_NAME).read_text())
    assert document['summary'] == {'runs': 3, 'passed': 1, 'failed': 2, 'reused': 0}
    assert (tmp_path / 'out' / grade.PAGE_NAME).is_file()


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM, signal.SIGHUP],
                         ids=['ctrl_c', 'sigterm', 'sighup'])
def test_a_stop_while_the_reports_are_written_is_an_interruption_not_a_traceback(
        tmp_path, monkeypatch, capsys, signum):
    monkeypatch.setattr(grade, 'grade_runs', grade_in_process)

    def stopped_while_writing(*args, **kwargs):
        os.kill(os.getpid(), signum)  # Ctrl-C, a CI job's timeout, a closed ssh session

    monkeypatch.setattr(grade, 'write_report', stopped_while_writing)
    # Ctrl-C as Python's own handler takes it, even where this test process was started with
    # SIGINT ignored (in the background by a shell without job control: `./lab test &`).
    interrupt_handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        status = main([str(scenario_file(tmp_path)), '--out', str(tmp_path / 'out')])
    finally:
        signal.signal(signal.SIGINT, interrupt_handler)
    assert status == 128 + signum
    err = capsys.readouterr().err
    assert 'interrupted: 3 of 3 runs finished; the same command again resumes' in err
    assert 'Traceback' not in err
    assert signal.getsignal(signal.SIGTERM) is signal.getsignal(signal.SIGHUP) is signal.SIG_DFL


def test_main_exits_zero_when_every_run_passes(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(grade, 'grade_runs', grade_in_process)
    status = main([str(scenario_file(tmp_path, seeds=[1])), '--out', str(tmp_path / 'out'),
                   '--node-override', 'students/ana.py'])
    assert status == 0
    out = capsys.readouterr().out
    assert 'laps >= 1' in out and '1 of 1 runs passed' in out
    document = json.loads((tmp_path / 'out' / grade.REPORT_NAME).read_text())
    assert document['runs'][0]['nodes'] == ['students/ana.py']


def test_main_refuses_a_bad_scenario_naming_file_and_field(tmp_path, capsys):
    path = scenario_file(tmp_path, duration=0)
    assert main([str(path), '--out', str(tmp_path / 'out')]) == 2
    assert capsys.readouterr().err == (
        f'error: {path}: duration: must be a positive number of seconds, at most 86400 (a day), '
        'got 0\n')
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('options, says', [
    (['--jobs', '0'], '--jobs must be at least 1'),
    (['--timeout', '0'], '--timeout must be a positive number, got 0.0'),
    (['--stall-timeout', 'inf'], '--stall-timeout must be a positive number, got inf'),
    (['--memory-limit', '-1'], '--memory-limit must be a positive number, got -1.0'),
    (['--submissions', 'nowhere'], '--submissions nowhere: not a folder'),
    (['--timeout', 'nan'], '--timeout must be a positive number, got nan'),
    (['--submissions', 'box_ccw.yaml'], '--submissions box_ccw.yaml: not a folder'),
    (['--submissions', 'empty'], '--submissions empty: no student folders in it'),
    (['--submissions', 'loose'], '--submissions loose: no student folders in it'),
])
def test_main_refuses_bad_options_naming_them(tmp_path, capsys, options, says, monkeypatch):
    path = scenario_file(tmp_path)
    monkeypatch.chdir(tmp_path)
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'loose' / '.ana').mkdir(parents=True)  # hidden: no student
    (tmp_path / 'loose' / 'wall_follow.py').write_text('')  # a file, not a student's folder
    assert main([str(path), '--out', str(tmp_path / 'out'), *options]) == 2
    assert capsys.readouterr().err == f'error: {says}\n'


def test_a_run_is_resumed_only_while_its_world_and_models_are_unchanged(tmp_path, monkeypatch):
    models = tmp_path / 'models'
    post = models / 'my_post'
    post.mkdir(parents=True)
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(models))
    world = tmp_path / 'world.yaml'
    world.write_text('obstacles:\n  - {name: p, type: model, model: my_post, pose: [2, 0]}\n')
    [run] = scenario_from_dict({'world': str(world), 'nodes': ['scan_ahead'], 'duration': 1.0,
                                'criteria': ['collisions == 0']}, 'post').runs()
    job = GradeJob(run, tmp_path / 'out')

    def digest():
        return batch.fingerprint(job, {}, batch.Limits())

    missing_model = digest()
    shipped_post = paths.models_dir() / 'obstacle_post' / 'model.sdf'
    (post / 'model.sdf').write_text(shipped_post.read_text())
    found = digest()
    assert found != missing_model
    assert digest() == found
    (post / 'model.sdf').write_text(shipped_post.read_text().replace('0.1', '0.2'))
    assert digest() not in (found, missing_model)


@pytest.mark.parametrize('key, value', [
    ('robot', 'turtlebot3_burger'), ('remap', ['/robot/scan:=/scan']),
    ('setpoint', {'wall_distance_m': 0.4}),
    ('drive', [{'duration': 2.0, 'linear': 0.2, 'angular': 0.0},
               {'duration': 9.0, 'linear': 0.1, 'angular': 0.0,
                'until': {'within_m': 0.4, 'of': 'box'}}])])
def test_a_scenarios_robot_remap_and_setpoint_reach_the_run_and_its_fingerprint(
        key, value, tmp_path):
    plain = scenario_from_dict(SCENARIO, 'box_ccw')
    changed = scenario_from_dict({**SCENARIO, key: value}, 'box_ccw')

    def digest(scenario):
        return batch.fingerprint(GradeJob(scenario.runs()[0], tmp_path), {}, batch.Limits())

    assert digest(changed) != digest(plain)
    CALLS.clear()
    report = run_scenario(changed.runs()[0], tmp_path, simulate=fake_simulate)
    options = CALLS[-1][2]
    given = {'robot': options['robot'], 'remap': list(options['remap']),
             'setpoint': {'wall_distance_m': options['setpoint']},
             'drive': [segment.as_dict() for segment in options['drive'] or ()]}
    assert given[key] == value
    assert report.as_dict()[key] == value


def test_a_run_that_never_started_says_why_and_that_it_simulated_nothing(tmp_path, runs):
    stream = io.StringIO()
    progress = BatchProgress(1, 30.0, stream)
    report = run_scenario(runs[0], tmp_path, simulate=broken_simulate)
    progress.finish('ana/box_ccw/seed_1', report)
    assert stream.getvalue().startswith(
        "[1/1] FAIL ana/box_ccw/seed_1: LookupError: unknown world 'nowhere' "
        '(0 of 30 s sim in ')


def test_measured_values_read_with_their_units(tmp_path, runs):
    def simulate_close_call(world, targets, **options):
        return SimpleNamespace(metrics={'laps': 1, 'collisions': 0, 'node_errors': [],
                                        'min_clearance_m': 2.873e-09})

    scenario = scenario_from_dict({**SCENARIO, 'criteria': ['min_clearance_m >= 0.05']}, 'c')
    report = run_scenario(scenario.runs()[0], tmp_path, simulate=simulate_close_call)
    assert format_table([report]).splitlines()[2].split() == [
        'c/seed_1', 'min_clearance_m', '>=', '0.05', '0.000', 'm', 'FAIL']


def test_warnings_are_shown_and_fail_nothing(tmp_path, runs, run_warnings):
    warning = "node 'wall_follow' was given parameters it does not declare: speed"

    def simulate_with_a_warning(world, targets, **options):
        return SimpleNamespace(metrics={'laps': 1, 'collisions': 0, 'node_errors': [],
                                        'warnings': [warning]})

    report = run_scenario(runs[0], tmp_path, simulate=simulate_with_a_warning)
    assert report.passed
    lines = format_table([report]).splitlines()
    assert lines[2].split() == ['box_ccw/seed_1', 'warning:', *warning.split(), 'warn']
    write_report([report], tmp_path / 'report.json')
    [run] = json.loads((tmp_path / 'report.json').read_text())['runs']
    assert run_warnings(run['metrics']['warnings']) == [warning]


@pytest.mark.parametrize('params, start, shown', [
    ({'wall_follow': {'gain': float('inf')}}, None, [{'wall_follow': {'gain': 'inf'}}, None]),
    ({'wall_follow': {'gain': float('nan')}}, None, [{'wall_follow': {'gain': 'nan'}}, None]),
    ({}, [0.0, float('-inf'), 0.0], [{}, [0.0, '-inf', 0.0]]),
])
def test_a_scenario_with_inf_or_nan_is_saved_and_reported(tmp_path, params, start, shown):
    scenario = scenario_from_dict({**SCENARIO, 'params': params, 'start': start}, 'odd')
    job = GradeJob(scenario.runs()[0], tmp_path / 'run')
    job.out_dir.mkdir()
    report = run_scenario(job.run, job.out_dir, simulate=fake_simulate)
    batch.save_result(report, 'digest', SIGNER)
    assert batch.finished_report(job, 'digest', SIGNER).passed
    write_report([report], tmp_path / 'report.json')
    entry = json.loads((tmp_path / 'report.json').read_text())['runs'][0]
    assert [entry['params'], entry['start']] == shown


@pytest.mark.parametrize('saved, says', [
    ('[1, 2]', 'not a run result (expected a mapping, got list)'),
    ('{"fingerprint": "digest", "report": []}',
     'not a run result (expected a mapping, got list)'),
    ('{"fingerprint": "digest"}', 'not a run result (expected a mapping, got NoneType)'),
    ('{"fingerprint": "digest", "report": {"criteria": {}, "metrics": null, "error": null, '
     '"traceback": null, "wall_time_s": 1}}', "not a run result ('criteria' is dict)"),
    ('{"fingerprint": "digest", "report": {"criteria": [{"criterion": 1}], "metrics": null, '
     '"error": null, "traceback": null, "wall_time_s": 1}}',
     'criteria[0] is not a judged criterion'),
    ('{"fingerprint": "digest", "report": {"criteria": [], "metrics": {"node_errors": [1]}, '
     '"error": null, "traceback": null, "wall_time_s": 1}}',
     "metrics 'node_errors'[0] is not a node error"),
    ('{"fingerprint": "dig', 'does not read as JSON'),
])
def test_a_result_file_of_the_wrong_shape_is_run_again_naming_the_file(
        tmp_path, runs, saved, says):
    job = GradeJob(runs[0], tmp_path / 'run')
    job.out_dir.mkdir()
    (job.out_dir / batch.RESULT_NAME).write_text(saved)
    notes = []
    assert batch.finished_report(job, 'digest', SIGNER, notes.append) is None
    [note] = notes
    assert note.startswith(f'running box_ccw/seed_1 again: {job.out_dir / batch.RESULT_NAME} ')
    assert says in note


def test_texts_in_a_report_are_cut_to_a_stated_size(tmp_path, runs):
    huge = 'x' * 50_000_000

    def simulate_huge_node_error(world, targets, **options):
        return SimpleNamespace(metrics={'laps': 1, 'collisions': 0, 'node_errors': [
            {'node': 'n', 'error': huge, 'traceback': huge}]})

    report = run_scenario(runs[0], tmp_path, simulate=simulate_huge_node_error)
    report.traceback = huge
    entry = report.as_dict()
    assert len(json.dumps(entry)) < 4 * TEXT_LIMIT_BYTES
    cut = f'\n... {50_000_000 - TEXT_LIMIT_BYTES} bytes cut ...\n'
    assert cut in entry['traceback'] and cut in entry['metrics']['node_errors'][0]['error']
    assert cut in entry['metrics']['node_errors'][0]['traceback']


def test_main_says_which_runs_were_reused_and_which_results_are_not_in_the_batch(
        tmp_path, monkeypatch, capsys):
    def grade_reusing(jobs, **options):
        reports = grade_in_process(jobs)
        reports[0].reused = True
        return reports

    monkeypatch.setattr(grade, 'grade_runs', grade_reusing)
    out = tmp_path / 'out'
    (out / 'other' / 'seed_1').mkdir(parents=True)
    (out / 'other' / 'seed_1' / batch.RESULT_NAME).write_text('{}')
    main([str(scenario_file(tmp_path)), '--out', str(out), '--quiet'])
    stdout = capsys.readouterr().out
    reused = '1 of 3 runs reused from an earlier invocation'
    stray = 'this folder also holds the results of 1 runs not in this batch (other/seed_1)'
    assert reused in stdout and stray in stdout
    page = (out / grade.PAGE_NAME).read_text()
    assert reused in page and stray in page
    assert json.loads((out / grade.REPORT_NAME).read_text())['summary']['reused'] == 1


def test_main_writes_the_page_when_the_json_report_cannot_be_written(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(grade, 'grade_runs', grade_in_process)
    out = tmp_path / 'out'
    (out / grade.REPORT_NAME).mkdir(parents=True)  # in the way of the report
    assert main([str(scenario_file(tmp_path)), '--out', str(out), '--quiet']) == 1
    captured = capsys.readouterr()
    assert f'error: cannot write {out / grade.REPORT_NAME}: Is a directory' in captured.err
    assert (out / grade.PAGE_NAME).stat().st_size > 0
    assert f'report: {out / grade.PAGE_NAME}' in captured.out


def test_a_run_a_node_ended_early_fails_saying_when_and_who(tmp_path, runs):
    ended_by = "node 'quitter' shut ROS down (rclpy.shutdown()) in its timer callback"

    def quitting_simulate(world, targets, **options):
        return SimpleNamespace(metrics={'laps': 1, 'sim_time_s': 3.0, 'collisions': 0,
                                        'node_errors': [], 'ended_by': ended_by})

    report = run_scenario(runs[0], tmp_path, simulate=quitting_simulate)
    assert all(result.passed for result in report.results)
    assert not report.passed
    assert report.error == f'the run ended at 3.0 s of its 30 s: {ended_by}'


def test_a_run_is_resumed_only_while_every_file_it_reads_of_the_submission_is_unchanged(
        tmp_path):
    # A hostile student grades a node whose logic is in a helper module beside it, then
    # swaps the helper: the run reads the new helper, so the signed result cannot be reused.
    student = tmp_path / 'student'
    student.mkdir()
    (student / 'wall_follow.py').write_text('from helper import main\n')
    helper = student / 'helper.py'
    helper.write_text('def main():\n    pass\n')
    [run] = scenario_from_dict({'world': 'obstacles', 'nodes': [str(student / 'wall_follow.py')],
                                'duration': 1.0, 'criteria': ['collisions == 0']},
                               'follow').runs()

    def digest():
        return batch.fingerprint(GradeJob(run, tmp_path / 'out'), {}, batch.Limits())

    first = digest()
    assert digest() == first
    helper.write_text('def main():\n    print("changed")\n')
    changed = digest()
    (student / 'helper2.py').write_text('')  # a module more the run can import
    added = digest()
    (student / 'notes.txt').write_text('not copied into the run')
    assert len({first, changed, added}) == 3
    assert digest() == added
