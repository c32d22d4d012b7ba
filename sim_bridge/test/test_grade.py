"""The grader's batch logic with a stand-in simulator: judging, errors, table, report, exit."""

import io
import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from sim_bridge import grade
from sim_bridge.grade import (BatchProgress, format_table, grade_runs, main, run_scenario,
                              summary, write_report)
from sim_bridge.scenario import scenario_from_dict

SCENARIO = {
    'world': 'wall_follow_box', 'nodes': ['wall_follow'], 'duration': 30.0, 'seeds': [1, 2, 3],
    'start': 'mirrored', 'params': {'wall_follow': {'side': 'left', 'seed': '$seed'}},
    'criteria': ['laps >= 1', 'collisions == 0', 'len(node_errors) == 0'],
}


CALLS = []


def fake_simulate(world, targets, **options):
    """Stand in for run_simulation: seed 2 collides once, seed 3 never completes a lap."""
    CALLS.append((world, targets, options))
    seed = options['seed']
    if options['progress']:
        options['progress'](15.0, options['duration_s'])
    return SimpleNamespace(metrics={'laps': 0 if seed == 3 else 1,
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


def test_every_run_is_graded_in_order_into_its_own_folder(tmp_path, runs):
    reports = grade_runs(runs, tmp_path, simulate=fake_simulate)
    assert [report.passed for report in reports] == [True, False, False]
    assert [report.out_dir for report in reports] == [
        tmp_path / 'box_ccw' / f'seed_{seed}' for seed in (1, 2, 3)]
    assert summary(reports) == '1 of 3 runs passed; failed: box_ccw/seed_2, box_ccw/seed_3'


def test_progress_prints_a_line_per_run_outside_a_terminal(tmp_path, runs):
    stream = io.StringIO()
    grade_runs(runs, tmp_path, simulate=fake_simulate, progress=BatchProgress(3, stream))
    lines = stream.getvalue().splitlines()
    assert [line.split(' (')[0] for line in lines] == [
        '[1/3] PASS box_ccw/seed_1', '[2/3] FAIL box_ccw/seed_2', '[3/3] FAIL box_ccw/seed_3']
    assert '\r' not in stream.getvalue()


def test_progress_redraws_one_bar_on_a_terminal(tmp_path, runs):
    class Terminal(io.StringIO):

        def isatty(self):
            return True

    stream = Terminal()
    grade_runs(runs[:1], tmp_path, simulate=fake_simulate, progress=BatchProgress(1, stream))
    text = stream.getvalue()
    assert '\r\033[K[............' in text
    assert '0/1 box_ccw/seed_1 15/30 s' in text
    assert text.endswith('PASS box_ccw/seed_1 (30 s sim in ' + text.split(' in ')[-1])


def test_table_lists_each_criterion_with_its_measured_value(tmp_path, runs):
    reports = grade_runs(runs, tmp_path, simulate=fake_simulate)
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


def test_report_is_json_with_every_run_and_the_verdict(tmp_path, runs):
    reports = grade_runs(runs[:2], tmp_path, simulate=fake_simulate)
    write_report(reports, tmp_path / 'report.json', overrides=['ana.py'])
    document = json.loads((tmp_path / 'report.json').read_text())
    assert document['passed'] is False
    assert document['summary'] == {'runs': 2, 'passed': 1, 'failed': 1}
    assert document['node_overrides'] == ['ana.py']
    second = document['runs'][1]
    assert (second['run'], second['seed'], second['passed']) == ('box_ccw/seed_2', 2, False)
    assert second['criteria'][1] == {'criterion': 'collisions == 0', 'passed': False,
                                     'value': 1, 'shown': '1'}
    assert second['params'] == {'wall_follow': {'side': 'left', 'seed': 2}}


def test_runs_can_go_in_parallel_processes(tmp_path, runs):
    reports = grade_runs(runs, tmp_path, jobs=2, simulate=fake_simulate)
    assert [report.passed for report in reports] == [True, False, False]


def scenario_file(folder: Path, **changes) -> Path:
    path = folder / 'box_ccw.yaml'
    path.write_text(json.dumps({**SCENARIO, **changes}))
    return path


def test_main_exits_non_zero_and_writes_the_report_when_a_run_fails(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr('sim_bridge.run.run_simulation', fake_simulate)
    status = main([str(scenario_file(tmp_path)), '--out', str(tmp_path / 'out'), '--quiet'])
    out = capsys.readouterr().out
    assert status == 1
    assert '1 of 3 runs passed' in out and 'box_ccw/seed_2' in out
    assert 'box_ccw/seed_1' not in out.split('1 of 3')[0]
    assert json.loads((tmp_path / 'out' / grade.REPORT_NAME).read_text())['summary']['runs'] == 3


def test_main_exits_zero_when_every_run_passes(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr('sim_bridge.run.run_simulation', fake_simulate)
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
        f'error: {path}: duration: must be a positive number of seconds, got 0\n')
    assert not (tmp_path / 'out').exists()
