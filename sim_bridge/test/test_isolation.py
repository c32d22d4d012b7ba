"""
Graded runs in child processes: each failure kind fails its own run only, with its reason.

One batch holds a passing run and a run per failure kind (an infinite loop, a sleep, unbounded
memory, ``sys.exit``, ``os._exit``, a segfault, a syntax error, a missing module); every run
is a real child process on real rclpy, with a short stall limit so the batch stays quick.
"""

from dataclasses import replace
from pathlib import Path
import re

import pytest

from sim_bridge import isolate
from sim_bridge.grade import BatchProgress, grade_runs, GradeJob, RESULT_NAME
from sim_bridge.isolate import exit_reason, Limits, trimmed_environment
from sim_bridge.scenario import scenario_from_dict

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
MISBEHAVING = FIXTURES / 'misbehaving_node.py'
STALL_S = 3.0
#: Every line of the misbehaving node's scan callback that a stop may interrupt.
IN_CALLBACK = re.compile(r'misbehaving_node\.py:\d+: ')


def scenario(name: str, node: str, **params):
    return scenario_from_dict({
        'world': 'obstacles', 'nodes': [node], 'duration': 2.0, 'seed': 1,
        'params': {'misbehaver': params} if params else {},
        'criteria': ['len(node_errors) == 0', 'collisions == 0']}, name)


def jobs_of(tmp_path, scenarios):
    return [GradeJob(run, tmp_path / run.name) for each in scenarios for run in each.runs()]


@pytest.fixture(scope='module')
def batch(tmp_path_factory):
    """Grade the failure kinds beside a passing run, two children at once."""
    folder = tmp_path_factory.mktemp('batch')
    (folder / 'syntax_error.py').write_text('def broken(:\n    pass\n')
    kinds = [scenario('passing', 'scan_ahead'),
             *(scenario(how.replace('.', '_'), str(MISBEHAVING), how=how)
               for how in ('loop', 'sleep', 'memory', 'sys.exit', 'os._exit', 'segfault')),
             scenario('syntax_error', str(folder / 'syntax_error.py')),
             scenario('missing_module', str(FIXTURES / 'missing_import_node.py'))]
    reports = grade_runs(jobs_of(folder / 'out', kinds), workers=2,
                         limits=Limits(stall_s=STALL_S), quiet=True, record=True, plot=True)
    return {report.run.scenario.name: report for report in reports}


def test_the_passing_run_passes_beside_every_failure(batch):
    assert len(batch) == 9
    assert batch['passing'].passed, batch['passing'].error
    assert [name for name, report in batch.items() if report.passed] == ['passing']
    assert (batch['passing'].out_dir / 'metrics.json').is_file()
    assert (batch['passing'].out_dir / RESULT_NAME).is_file()


@pytest.mark.parametrize('kind', ['loop', 'sleep'])
def test_a_callback_that_never_returns_is_stopped_with_its_outputs(batch, kind):
    report = batch[kind]
    assert report.error is None
    [error] = report.metrics['node_errors']
    assert error['error'].startswith(
        f"no reply for {STALL_S:g} s: node 'misbehaver' did not return from its /scan callback")
    assert IN_CALLBACK.search(error['error'])
    assert report.metrics['sim_time_s'] == pytest.approx(0.5)
    assert (report.out_dir / 'trajectory.png').is_file()
    assert (report.out_dir / 'run' / 'metadata.yaml').is_file()


def test_unbounded_memory_fails_at_the_memory_limit(batch):
    [error] = batch['memory'].metrics['node_errors']
    assert "node 'misbehaver' raised MemoryError" in error['error']
    assert error['error'].endswith('(memory limit 2 GiB reached in its /scan callback)')
    assert 'self.hoard.append' in error['error']


def test_sys_exit_in_a_callback_fails_the_run_naming_it(batch):
    [error] = batch['sys_exit'].metrics['node_errors']
    assert error['error'].startswith("node 'misbehaver' raised SystemExit (sys.exit(3)) at ")
    assert error['traceback'].startswith('Traceback (most recent call last):')
    assert 'in on_scan' in error['traceback'] and 'sys.exit(3)' in error['traceback']


def test_os_exit_fails_the_run_with_the_exit_status_and_its_log(batch):
    report = batch['os__exit']
    assert report.error == 'exit status 4'
    assert report.metrics is None
    assert (report.out_dir / 'params.yaml').is_file()
    assert (report.out_dir / isolate.LOG_NAME).is_file()


def test_a_segfault_fails_the_run_with_the_signal_and_the_stack(batch):
    report = batch['segfault']
    assert report.error == 'killed by SIGSEGV'
    assert 'Fatal Python error: Segmentation fault' in report.traceback
    assert 'misbehaving_node.py' in report.traceback


def test_files_that_cannot_be_imported_fail_their_runs_with_the_reason(batch):
    assert 'SyntaxError' in batch['syntax_error'].error
    assert 'syntax_error.py' in batch['syntax_error'].error
    assert "No module named 'turtle_magic'" in batch['missing_module'].error


def test_every_report_names_its_run_and_folder(batch):
    for name, report in batch.items():
        assert report.run.name == f'{name}/seed_1'
        assert report.out_dir.name == 'seed_1' and report.out_dir.parent.name == name


def test_the_wall_clock_budget_stops_a_run_that_sleeps(tmp_path):
    [report] = grade_runs(jobs_of(tmp_path, [scenario('slow', str(MISBEHAVING), how='sleep')]),
                          limits=Limits(timeout_s=4.0), quiet=True, record=False, plot=False)
    [error] = report.metrics['node_errors']
    assert error['error'].startswith("wall-clock budget of 4 s used up: node 'misbehaver' did "
                                     'not return from its /scan callback')


def test_a_node_that_hangs_while_starting_is_stopped_naming_its_constructor(tmp_path):
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('hang', str(MISBEHAVING), how='hang_at_start')]),
        limits=Limits(stall_s=2.0, startup_s=3.0), quiet=True, record=False, plot=False)
    [error] = report.metrics['node_errors']
    # Before its constructor returns, a node is known by its TARGET.
    assert error['error'].startswith(
        f"no reply for 3 s: node '{MISBEHAVING}' did not return from its constructor at ")
    assert error['error'].endswith('misbehaving_node.py:28: time.sleep(3600.0)')
    assert report.metrics['sim_time_s'] == 0.0
    assert (report.out_dir / 'metrics.json').is_file()


def test_a_node_that_swallows_the_stop_is_aborted_with_its_stack(tmp_path, monkeypatch):
    monkeypatch.setattr(isolate, 'GRACE_S', 1.0)
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('stubborn', str(MISBEHAVING), how='stubborn')]),
        limits=Limits(stall_s=2.0), quiet=True, record=False, plot=False)
    assert report.error == ('no reply for 2 s; the run did not stop when asked '
                            '(killed by SIGABRT)')
    assert 'Fatal Python error: Aborted' in report.traceback
    assert 'in on_scan' in report.traceback


def test_a_finished_batch_is_resumed_and_an_interrupted_one_keeps_its_finished_runs(tmp_path):
    class InterruptAfterFirst(BatchProgress):

        def finish(self, name, report):
            super().finish(name, report)
            raise KeyboardInterrupt

    jobs = jobs_of(tmp_path, [scenario('first', 'scan_ahead'), scenario('second', 'scan_ahead')])
    with pytest.raises(KeyboardInterrupt):
        grade_runs(jobs, workers=1, progress=InterruptAfterFirst(2, enabled=False),
                   quiet=True, record=False, plot=False)
    assert (jobs[0].out_dir / RESULT_NAME).is_file()
    assert not (jobs[1].out_dir / RESULT_NAME).exists()
    first_result = (jobs[0].out_dir / RESULT_NAME).stat().st_mtime_ns
    progress = BatchProgress(2, enabled=False)
    reports = grade_runs(jobs, progress=progress, quiet=True, record=False, plot=False)
    assert [report.passed for report in reports] == [True, True]
    assert (jobs[0].out_dir / RESULT_NAME).stat().st_mtime_ns == first_result
    assert progress.resumed_sim_s == 2.0
    # Changed inputs (a longer run) are run again.
    longer = replace(scenario('first', 'scan_ahead'), duration_s=3.0)
    [rerun] = grade_runs(jobs_of(tmp_path, [longer]), quiet=True, record=False, plot=False)
    assert rerun.metrics['sim_time_s'] == pytest.approx(3.0)


def test_a_child_gets_a_trimmed_environment_and_a_scratch_home(tmp_path):
    environ = {'PATH': '/usr/bin', 'ROS_DOMAIN_ID': '7', 'AWS_SECRET_ACCESS_KEY': 'x',
               'HOME': '/home/teacher', 'LC_ALL': 'C.UTF-8', 'XDG_CACHE_HOME': '/cache'}
    child = trimmed_environment(tmp_path, environ)
    assert child['PATH'] == '/usr/bin' and child['ROS_DOMAIN_ID'] == '7'
    assert child['LC_ALL'] == 'C.UTF-8'
    assert 'AWS_SECRET_ACCESS_KEY' not in child
    assert child['HOME'] == child['TMPDIR'] == str(tmp_path)
    assert child['MPLCONFIGDIR'] == '/cache/matplotlib'


@pytest.mark.parametrize('returncode, says', [
    (3, 'exit status 3'), (0, 'exit status 0'), (-11, 'killed by SIGSEGV'),
    (-9, 'killed by SIGKILL')])
def test_exit_reasons(returncode, says):
    assert exit_reason(returncode) == says


def test_budget_grows_with_the_simulated_duration():
    assert Limits().budget_s(600.0) == isolate.BUDGET_BASE_S + 600.0 * isolate.BUDGET_PER_SIM_S
    assert Limits(timeout_s=5.0).budget_s(600.0) == 5.0
