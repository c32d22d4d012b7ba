"""
Graded runs in child processes: each failure kind fails its own run only, with its reason.

One batch holds a passing run and a run per failure kind (an infinite loop, a sleep, unbounded
memory, ``sys.exit``, ``os._exit``, a segfault, a syntax error, a missing module); every run
is a real child process on real rclpy, with a short stall limit so the batch stays quick.
"""

from dataclasses import replace
import io
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

import pytest

from sim_bridge.common import paths
from sim_bridge.grading import isolate, limits
from sim_bridge.grading.batch import BatchProgress, grade_runs
from sim_bridge.grading.isolate import (
    CappedLog, exit_reason, LOG_HEAD_BYTES, log_tail, LOG_TAIL_BYTES, LOG_TAIL_READ,
    trimmed_environment)
from sim_bridge.grading.isolated_child import process_exists
from sim_bridge.grading.limits import Limits
from sim_bridge.grading.runs import GradeJob, RESULT_NAME
from sim_bridge.grading.scenario import scenario_from_dict
from sim_bridge.runner.boundary.outside import sandbox_host
from sim_bridge.runner.boundary.outside.sandbox import isolation_mode

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
MISBEHAVING = FIXTURES / 'misbehaving_node.py'
HELPER_STARTER = FIXTURES / 'helper_process_node.py'
#: What a capped log says where it cut the output.
CUT = re.compile(r"\n\[\.\.\. [\d.]+ MiB of output cut here: a run's log keeps the first "
                 r'512\.0 KiB and the last 512\.0 KiB of it \.\.\.\]\n')
#: What helper_process_node.py prints when it starts.
STARTED = re.compile(r'node pid (\d+), helper pid (\d+)\n')
#: Wall seconds a test waits for something a child does (it starts rclpy and pybullet).
WAIT_S = 120.0
STALL_S = 3.0
#: Every line of the misbehaving node's scan callback that a stop may interrupt.
IN_CALLBACK = re.compile(r'misbehaving_node\.py:\d+: ')


def scenario(name: str, node: str, node_name: str = 'misbehaver', **params):
    return scenario_from_dict({
        'world': 'obstacles', 'nodes': [node], 'duration': 2.0, 'seed': 1,
        'params': {node_name: params} if params else {},
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


def test_the_passing_run_passes_beside_every_failure(batch, run_warnings):
    assert len(batch) == 9
    assert batch['passing'].passed, batch['passing'].error
    # A callback sleeping an hour sleeps an hour of simulated time, as on Gazebo: the 2 s run
    # ends with the node asleep, and nothing failed.
    assert [name for name, report in batch.items() if report.passed] == ['passing', 'sleep']
    assert (batch['passing'].out_dir / 'metrics.json').is_file()
    assert (batch['passing'].out_dir / RESULT_NAME).is_file()
    # The runner's own threads are not named.
    assert not run_warnings(batch['passing'].metrics['warnings'])


def test_a_callback_that_never_returns_is_stopped_with_its_outputs(batch):
    report = batch['loop']
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


def test_a_node_that_closes_its_console_fails_with_its_own_error(tmp_path):
    # Not quiet, as the grader runs: the runner writes the node's traceback on the console.
    closes = scenario('closes', str(FIXTURES / 'closes_stderr_node.py'))
    [report] = grade_runs(jobs_of(tmp_path, [closes]), limits=Limits(stall_s=STALL_S),
                          quiet=False, record=False, plot=False)
    assert report.error is None
    [error] = report.metrics['node_errors']
    assert error['error'].startswith("node 'quiet' raised RuntimeError: no wall in sight at ")


def test_os_exit_fails_the_run_with_the_exit_status_and_its_log(batch):
    report = batch['os__exit']
    [error] = report.metrics['node_errors']  # its process ended: the run's outputs are whole
    assert 'the node process ended (exit status 4)' in error['error']
    assert (report.out_dir / 'metrics.json').is_file()
    assert (report.out_dir / isolate.LOG_NAME).is_file()


def test_a_segfault_fails_the_run_with_the_signal_and_the_stack(batch):
    [error] = batch['segfault'].metrics['node_errors']
    assert 'the node process was killed by SIGSEGV' in error['error']
    assert 'Fatal Python error: Segmentation fault' in error['traceback']
    assert 'misbehaving_node.py' in error['traceback']


def test_files_that_cannot_be_imported_fail_their_runs_with_the_reason(batch):
    assert 'SyntaxError' in batch['syntax_error'].error
    assert 'syntax_error.py' in batch['syntax_error'].error
    assert "No module named 'turtle_magic'" in batch['missing_module'].error


def test_every_report_names_its_run_and_folder(batch):
    for name, report in batch.items():
        assert report.run.name == f'{name}/seed_1'
        assert report.out_dir.name == 'seed_1' and report.out_dir.parent.name == name


def test_the_wall_clock_budget_stops_a_run_that_sleeps(tmp_path):
    [report] = grade_runs(jobs_of(tmp_path, [scenario('slow', str(MISBEHAVING), how='loop')]),
                          limits=Limits(timeout_s=4.0), quiet=True, record=False, plot=False)
    [error] = report.metrics['node_errors']
    assert error['error'].startswith("wall-clock budget of 4 s used up: node 'misbehaver' did "
                                     'not return from its /scan callback')


def test_a_run_out_of_budget_with_little_cpu_is_run_again_never_reused(tmp_path):
    # Its node waits in the kernel (as a run starved by busy neighbours waits for a CPU): the
    # budget is not its own doing, and a resumed batch runs it again.
    jobs = jobs_of(tmp_path, [scenario('starved', str(MISBEHAVING), how='block'),
                              scenario('passing', 'scan_ahead')])
    grading = {'limits': Limits(timeout_s=20.0, stall_s=60.0), 'quiet': True, 'record': False,
               'plot': False}
    starved, passing = grade_runs(jobs, **grading)
    [error] = starved.metrics['node_errors']
    assert error['error'].startswith('wall-clock budget of 20 s used up')
    assert re.fullmatch(r'it had \d+\.\d s of CPU in its wall-clock budget of 20 s: the '
                        r'machine was busy, so its result is not kept', starved.rerun)
    assert passing.passed and passing.rerun is None
    notes = io.StringIO()
    again = grade_runs(jobs, progress=BatchProgress(2, stream=notes, enabled=False), **grading)
    assert [report.reused for report in again] == [False, True]
    assert again[0].rerun and 'running starved/seed_1 again: it had ' in notes.getvalue()


def test_a_node_that_hangs_while_starting_is_stopped_naming_its_constructor(tmp_path):
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('hang', str(MISBEHAVING), how='hang_at_start')]),
        limits=Limits(stall_s=2.0, startup_s=3.0), quiet=True, record=False, plot=False)
    [error] = report.metrics['node_errors']
    # Before its constructor returns, a node is known by its TARGET.
    assert error['error'] == (
        "no reply for 3 s: node 'misbehaving_node' did not return from its main() at "
        f"{MISBEHAVING}:28: while self.how == 'hang_at_start':")
    assert report.metrics['sim_time_s'] == 0.0
    assert (report.out_dir / 'metrics.json').is_file()


def test_a_node_that_swallows_every_exception_is_stopped_all_the_same(tmp_path):
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('stubborn', str(MISBEHAVING), how='stubborn')]),
        limits=Limits(stall_s=2.0), quiet=True, record=False, plot=False)
    assert report.error is None  # its run was never in its process: it stopped when asked
    [error] = report.metrics['node_errors']
    assert error['error'].startswith("no reply for 2 s: node 'misbehaver' did not return from "
                                     'its /scan callback at ')


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
    assert Limits().budget_s(600.0) == limits.BUDGET_BASE_S + 600.0 * limits.BUDGET_PER_SIM_S
    assert Limits(timeout_s=5.0).budget_s(600.0) == 5.0


@pytest.mark.parametrize('node', ['scan_ahead', str(FIXTURES / 'spin_once_loop.py'),
                                  str(FIXTURES / 'sleepy_timer.py')])
def test_every_jobs_budget_is_the_stepped_one_whatever_its_node_files_style(tmp_path, node):
    run = replace(scenario('budget', node), duration_s=100.0).runs()[0]
    assert limits.Job(run, tmp_path, Limits()).budget_s == (
        limits.BUDGET_BASE_S + limits.BUDGET_PER_SIM_S * 100.0)
    assert Limits(timeout_s=5.0).budget_s(600.0) == 5.0  # --timeout decides


def test_a_run_keeps_the_variables_that_locate_gazebo_models_and_worlds(tmp_path):
    environ = {'GZ_SIM_RESOURCE_PATH': '/models', 'GAZEBO_MODEL_PATH': '/classic',
               'IGN_GAZEBO_RESOURCE_PATH': '/ign', 'GAZEBO_RESOURCE_PATH': '/worlds',
               'GZ_SIM_SYSTEM_PLUGIN_PATH': '/plugins'}
    child = trimmed_environment(tmp_path, environ)
    kept = {**environ, 'GZ_SIM_SYSTEM_PLUGIN_PATH': None}
    assert {name: child.get(name) for name in environ} == kept


def test_a_model_found_through_gz_sim_resource_path_is_found_in_a_graded_run(
        tmp_path, monkeypatch):
    post = tmp_path / 'models' / 'my_post'
    post.mkdir(parents=True)
    (post / 'model.sdf').write_text(
        (paths.models_dir() / 'obstacle_post' / 'model.sdf').read_text())
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path / 'models'))
    world = tmp_path / 'world.yaml'
    world.write_text('obstacles:\n  - {name: p, type: model, model: my_post, pose: [2, 1]}\n')
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario_from_dict({
            'world': str(world), 'nodes': ['scan_ahead'], 'duration': 1.0,
            'criteria': ['len(node_errors) == 0']}, 'post')]),
        quiet=True, record=False, plot=False)
    assert report.error is None and report.passed


def test_a_memory_error_at_import_names_the_memory_limit(tmp_path):
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('table', str(FIXTURES / 'lookup_table_node.py'))]),
        quiet=True, record=False, plot=False)
    assert 'fails to import: MemoryError' in report.error
    assert '(memory limit 2 GiB reached' in report.error


def test_a_capped_log_keeps_its_head_and_tail_and_says_how_much_was_cut(tmp_path):
    log = CappedLog(tmp_path / 'log.txt', head=10, tail=6)
    for chunk in (b'0123456', b'789abcdefghij', b'klmnop'):
        log.write(chunk)
    log.close()
    assert (tmp_path / 'log.txt').read_bytes() == (
        b"0123456789\n[... 10 bytes of output cut here: a run's log keeps the first 10 bytes and "
        b'the last 6 bytes of it ...]\nklmnop')


def test_log_tail_reads_only_the_end_of_a_log(tmp_path):
    path = tmp_path / 'log.txt'
    path.write_text('x' * (3 * LOG_TAIL_READ) + '\nlast line\n')
    assert log_tail(path) == 'last line'
    path.write_text('y' * (3 * LOG_TAIL_READ))
    assert log_tail(path) == 'y' * LOG_TAIL_READ


@pytest.fixture(scope='module')
def chatty(tmp_path_factory):
    """Grade a node printing 50 MB of lines and one printing a 50 MB line before os._exit."""
    folder = tmp_path_factory.mktemp('chatty')
    reports = grade_runs(
        jobs_of(folder, [scenario(how.replace('_', '-'), str(FIXTURES / 'chatty_node.py'),
                                  'chatty', how=how) for how in ('lines', 'one_line')]),
        workers=2, quiet=True, record=False, plot=False)
    return {report.run.scenario.name: report for report in reports}


def test_a_node_printing_50_mb_gets_a_log_of_its_head_and_tail(chatty):
    report = chatty['lines']
    assert report.passed, report.error
    log = (report.out_dir / isolate.LOG_NAME).read_text()
    cut = CUT.search(log)
    assert cut, log[:200]
    head, tail = log[:cut.start()], log[cut.end():]
    assert len(head.encode()) == LOG_HEAD_BYTES and len(tail.encode()) == LOG_TAIL_BYTES
    assert 'scan 0: ' in head and 'done printing the scan' in tail
    assert float(re.search(r'([\d.]+) MiB', cut.group()).group(1)) > 45


def test_a_50_mb_line_before_os_exit_is_cut_in_the_log_and_the_report(chatty):
    report = chatty['one-line']
    [error] = report.metrics['node_errors']
    assert 'the node process ended (exit status 1)' in error['error']
    log = report.out_dir / isolate.LOG_NAME
    assert log.stat().st_size < LOG_HEAD_BYTES + LOG_TAIL_BYTES + 200
    assert CUT.search(log.read_text())
    assert error['traceback'].endswith('x' * 100) and len(error['traceback']) <= LOG_TAIL_READ


def started_processes(log: Path) -> list[int]:
    """
    Return the pids helper_process_node.py printed to a run's log: the node's, the helper's.

    In a run's own pid namespace (a bubblewrap sandbox) they are that namespace's: the pids
    here are those of the live processes :func:`host_pids` finds for them.
    """
    found = STARTED.search(log.read_text()) if log.is_file() else None
    return [int(pid) for pid in found.groups()] if found else []


def host_pids(printed: list[int]) -> list[int]:
    """Return the pids here of the live processes helper_process_node.py printed ``printed`` of."""
    if not isolation_mode().bwrap:
        return printed
    found = []
    for status in Path('/proc').glob('[0-9]*/status'):
        try:
            levels = next(line for line in status.read_text().splitlines()
                          if line.startswith('NSpid:')).split()[1:]
            command = (status.parent / 'cmdline').read_bytes()
        except (OSError, StopIteration):
            continue
        if len(levels) > 1 and int(levels[-1]) in printed and (
                command == b'sleep\0' + b'300\0' or b'helper_process_node' in command):
            found.append(int(levels[0]))
    return found


def wait_until(condition, timeout_s: float = WAIT_S) -> bool:
    """Wait (bounded) until ``condition()`` holds; tell whether it did."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


@pytest.fixture
def no_strays():
    """Kill, after the test, any process a test's run left (so a failure leaves no sleep 300)."""
    pids = []
    yield pids
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


@pytest.mark.parametrize('how', ['finish', 'os._exit'])
def test_a_process_a_node_starts_in_a_session_of_its_own_ends_with_the_run(
        tmp_path, how, no_strays):
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('helper', str(HELPER_STARTER), 'helper_starter', how=how)]),
        quiet=True, record=False, plot=False)
    assert report.passed if how == 'finish' else 'exit status 5' in \
        report.metrics['node_errors'][0]['error']
    started = started_processes(report.out_dir / isolate.LOG_NAME)
    no_strays.extend(host_pids(started))
    assert len(started) == 2
    assert [pid for pid in host_pids(started) if process_exists(pid)] == []


def test_a_thread_a_node_leaves_running_ends_with_the_run_and_is_named(tmp_path, run_warnings):
    [report] = grade_runs(
        jobs_of(tmp_path, [scenario('threaded', str(FIXTURES / 'thread_node.py'))]),
        limits=Limits(stall_s=STALL_S), quiet=True, record=False, plot=False)
    assert report.passed, report.error
    [warning] = run_warnings(report.metrics['warnings'])
    assert re.fullmatch(r"node thread 'Thread-\d+ \(control_loop\)', in control_loop at "
                        r'thread_node\.py:\d+ was still running when the run ended; it was '
                        r'stopped \(.*\)', warning), warning


def grader(tmp_path: Path, *options: str) -> subprocess.Popen:
    """
    Start ``python -m sim_bridge.grade`` on two hanging runs of helper_process_node.py.

    Its temporary folder is ``tmp_path/tmp``, its stderr ``tmp_path/stderr.txt`` (a file: a
    pipe would stay open as long as any process that inherited it runs).
    """
    (tmp_path / 'hang.yaml').write_text(
        f'world: obstacles\nnodes: [{HELPER_STARTER}]\nduration: 3600.0\nseeds: [1, 2]\n'
        'params: {helper_starter: {how: hang}}\ncriteria: [collisions == 0]\n')
    (tmp_path / 'tmp').mkdir()
    with open(tmp_path / 'stderr.txt', 'w') as stderr:
        return subprocess.Popen(
            [sys.executable, '-m', 'sim_bridge.grade', str(tmp_path / 'hang.yaml'), '--out',
             str(tmp_path / 'out'), '--stall-timeout', '600', '--quiet', '--no-record',
             '--no-plot', *options], env={**os.environ, 'TMPDIR': str(tmp_path / 'tmp')},
            stdout=subprocess.DEVNULL, stderr=stderr)


def run_log(tmp_path: Path, seed: int) -> Path:
    return tmp_path / 'out' / 'hang' / f'seed_{seed}' / isolate.LOG_NAME


def started_runs(tmp_path: Path) -> list[int]:
    """Return the pids printed by both runs of :func:`grader`, once both printed them."""
    pids = [started_processes(run_log(tmp_path, seed)) for seed in (1, 2)]
    return pids[0] + pids[1] if all(pids) else []


def scratch_folders(tmp_path: Path) -> list[str]:
    """Return the runs' scratch folders in the graders' scratch parents of :func:`grader`."""
    return [f'{parent.name}/{run}' for parent in (tmp_path / 'tmp').iterdir()
            if parent.name.startswith(sandbox_host.SCRATCH_PREFIX) and parent.is_dir()
            for run in os.listdir(parent)]


def test_sigterm_interrupts_the_grader_as_ctrl_c_and_ends_every_process_of_its_runs(
        tmp_path, no_strays):
    process = grader(tmp_path, '--jobs', '2')
    try:
        assert wait_until(lambda: started_runs(tmp_path)), (tmp_path / 'stderr.txt').read_text()
        no_strays.extend(host_pids(started_runs(tmp_path)))
        # Each run's scratch and its node process's sandbox: all of them go with the grader.
        assert len(scratch_folders(tmp_path)) >= 2
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=WAIT_S)
    finally:
        process.kill()
    assert process.returncode == 128 + signal.SIGTERM
    assert (tmp_path / 'stderr.txt').read_text().endswith(
        'interrupted: 0 of 2 runs finished; the same command again resumes from there\n')
    assert wait_until(lambda: not any(map(process_exists, no_strays)), 10.0)
    assert scratch_folders(tmp_path) == []


def test_a_killed_graders_runs_end_with_it_and_its_scratch_goes_at_the_next_start(
        tmp_path, no_strays):
    process = grader(tmp_path)
    try:
        assert wait_until(lambda: started_processes(run_log(tmp_path, 1))), \
            (tmp_path / 'stderr.txt').read_text()
        no_strays.extend(host_pids(started_processes(run_log(tmp_path, 1))))
    finally:
        process.kill()
        process.wait()
    assert wait_until(lambda: not any(map(process_exists, no_strays)), 30.0)
    # The run's scratch, and its node's sandbox's if the node had started: left behind.
    assert scratch_folders(tmp_path)
    sandbox_host.remove_leftover_scratch(tmp_path / 'tmp')
    assert scratch_folders(tmp_path) == []
