"""
The grader's own process survives any submission and any fault of the machine (issue 24).

A huge node file, a full disk, a read-only ``--out``, a second grader on the same ``--out`` and
absurd limits each fail in one clear line, with a non-zero exit, and every output that can be
written is written. No run can edit a saved grade, lose a live grader its scratch folder, stall
the batch by stopping itself, or leak the grader's secrets into Gradescope's results. Each
grader here is a real ``python -m sim_bridge.grade`` (or its ``main``) grading real runs of a
small node, hostile where the test says so.
"""

import contextlib
import errno
import io
import json
import os
from pathlib import Path
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import pytest

from sim_bridge.commands import grade
from sim_bridge.common.paths import repo_root
from sim_bridge.grading import grader_state, isolate
from sim_bridge.grading.batch import BatchProgress, grade_runs
from sim_bridge.grading.class_batch import CSV_NAME
from sim_bridge.grading.runs import GradeJob, RESULT_NAME, reuse_notes
from sim_bridge.grading.scenario import scenario_from_dict
from sim_bridge.runner.boundary.outside import sandbox_host

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
MOVER = FIXTURES / 'function_node.py'
HELPER_STARTER = FIXTURES / 'helper_process_node.py'
#: Wall seconds a test waits for a grader (it starts rclpy and pybullet in its runs).
WAIT_S = 180.0
QUICK = ('--no-record', '--no-plot', '--quiet')


def scenario_file(folder: Path, node: str = 'scan_ahead', duration: float = 1.0,
                  name: str = 'quick', extra: str = '') -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f'{name}.yaml'
    path.write_text(f'world: obstacles\nnodes: [{node}]\nduration: {duration}\nseed: 1\n'
                    f'criteria: [len(node_errors) == 0]\n{extra}')
    return path


def class_folder(folder: Path, **students: Path | None) -> Path:
    """Make a class: each student's scan_ahead.py a copy of a file, or a 3 GB sparse file."""
    for student, source in students.items():
        (folder / student).mkdir(parents=True)
        node = folder / student / 'scan_ahead.py'
        if source is None:
            with open(node, 'wb') as file:
                file.truncate(3 * 2 ** 30)  # sparse: costs no disk
        else:
            shutil.copy(source, node)
    return folder


def run_grader(*args: str, env: dict | None = None, memory_bytes: int | None = None,
               timeout: float = WAIT_S) -> subprocess.CompletedProcess:
    """Run ``python -m sim_bridge.grade ARGS`` to its end, its address space bounded if asked."""
    def bound() -> None:
        if memory_bytes is not None:
            resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))

    return subprocess.run([sys.executable, '-m', 'sim_bridge.grade', *args], env=env,
                          capture_output=True, text=True, timeout=timeout, preexec_fn=bound)


def said(stderr: str) -> list[str]:
    """Return the grader's lines on stderr (pybullet's banner left out)."""
    return [line for line in stderr.splitlines() if not line.startswith('pybullet build time')]


def assert_one_line_errors(stderr: str) -> None:
    assert 'Traceback' not in stderr, stderr
    assert 'MemoryError' not in stderr, stderr


def test_a_huge_node_file_fails_its_student_in_one_line_and_the_class_is_graded(tmp_path):
    scenario = scenario_file(tmp_path / 'scenarios')
    submissions = class_folder(tmp_path / 'class', ana=None, bob=MOVER)
    out = tmp_path / 'out'
    # A grader bounded to 4 GiB of address space: reading the 3 GB file whole would fail.
    done = run_grader(str(scenario), '--submissions', str(submissions), '--out', str(out),
                      *QUICK, memory_bytes=4 * 2 ** 30)
    assert_one_line_errors(done.stderr)
    assert done.returncode == 1, done.stderr  # a failed run, as every failed run is
    rows = (out / CSV_NAME).read_text().splitlines()
    assert rows[1:] == ['ana,0/1 error,0/1 error', 'bob,1/1,1/1'], rows
    [run] = json.loads((out / 'students' / 'ana' / 'report.json').read_text())['runs']
    assert run['error'] == ('node file too big: scan_ahead.py is 3.0 GiB, over the 8.0 MiB a '
                            'node file may be')


#: A node that raises in its first scan callback.
CRASHER = """import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class Crasher(Node):
    def __init__(self):
        super().__init__('scan_ahead')
        self.create_subscription(LaserScan, 'scan', self.on_scan, 10)

    def on_scan(self, msg):
        raise RuntimeError('crashed on its first scan')


def main(args=None):
    rclpy.init(args=args)
    rclpy.spin(Crasher())
"""


@pytest.mark.parametrize('node', ['too big', 'crashes', 'not submitted', 'passes'])
def test_a_class_exits_1_for_every_kind_of_failed_run_alike(tmp_path, node):
    """docs/instructors.md: 0 when every run passed, 1 when any failed, whatever made it fail."""
    submissions = tmp_path / 'class'
    if node == 'too big':
        class_folder(submissions, ana=None)
    elif node == 'crashes':
        crasher = tmp_path / 'crasher.py'
        crasher.write_text(CRASHER)
        class_folder(submissions, ana=crasher)
    elif node == 'not submitted':
        (submissions / 'ana').mkdir(parents=True)
    else:
        class_folder(submissions, ana=MOVER)
    # It carries marks: a student without its file fails its run (else has none).
    scenario = scenario_file(tmp_path / 'scenarios', extra='task: 1\nmarks: 1\n')
    status = grade.main([str(scenario), '--submissions', str(submissions), '--out',
                         str(tmp_path / 'out'), *QUICK])
    [row] = (tmp_path / 'out' / CSV_NAME).read_text().splitlines()[1:]
    assert status == (0 if node == 'passes' else 1), row
    assert (',1,1/1,' if node == 'passes' else ',0,0/1 ') in row, row


@pytest.mark.parametrize('gib', [1, 0.5])
def test_a_memory_limit_of_1_gib_or_512_mib_runs_an_honest_node(tmp_path, gib):
    out = tmp_path / 'out'
    status = grade.main([str(scenario_file(tmp_path)), '--out', str(out), '--memory-limit',
                         str(gib), '--node-override', str(MOVER), *QUICK])
    [run] = json.loads((out / grade.REPORT_NAME).read_text())['runs']
    assert (status, run['error'], run['metrics']['node_errors']) == (0, None, [])


def test_a_memory_limit_no_node_can_run_in_is_refused_in_one_line_before_any_run(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(grade, 'grade_runs', lambda *args, **options: pytest.fail('ran'))
    status = grade.main([str(scenario_file(tmp_path)), '--out', str(tmp_path / 'out'),
                         '--memory-limit', '0.1', *QUICK])
    [line] = capsys.readouterr().err.splitlines()
    assert status == 2
    assert line == ('error: --memory-limit 0.1 GiB is less than the 0.25 GiB (256 MiB) an '
                    'rclpy node needs to run')


def test_absurd_limits_are_refused_in_one_line_before_any_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(grade, 'grade_runs', lambda *args, **options: pytest.fail('ran'))
    status = grade.main([str(scenario_file(tmp_path)), '--out', str(tmp_path / 'out'),
                         '--memory-limit', '1e12', *QUICK])
    [line] = capsys.readouterr().err.splitlines()
    assert status == 2
    assert line.startswith('error: --memory-limit 1e+12 GiB is more than this machine can '
                           'set as a limit'), line


def started(log: Path) -> bool:
    return log.is_file() and 'helper pid' in log.read_text(errors='replace')


def wait_until(condition, timeout_s: float = WAIT_S) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.1)
    return False


@contextlib.contextmanager
def hanging_grader(tmp_path: Path, out: Path):
    """
    Start a grader on ``out`` whose one run hangs; yield it once its run started.

    The node's hang is a sleep, which lasts simulated time: the run is an hour long, so that
    the grader is still running when the test is done with it.
    """
    scenario = scenario_file(tmp_path / 'hang', str(HELPER_STARTER), 3600.0, 'hang',
                             'params: {helper_starter: {how: hang}}\n')
    (tmp_path / 'tmp').mkdir(exist_ok=True)
    with open(out.parent / f'{out.name}.stderr.txt', 'w') as stderr:
        first = subprocess.Popen(
            [sys.executable, '-m', 'sim_bridge.grade', str(scenario), '--out', str(out),
             '--stall-timeout', '600', *QUICK],
            env={**os.environ, 'TMPDIR': str(tmp_path / 'tmp')},
            stdout=subprocess.DEVNULL, stderr=stderr)
    try:
        assert wait_until(lambda: started(out / 'hang' / 'seed_1' / isolate.LOG_NAME)), (
            (out.parent / f'{out.name}.stderr.txt').read_text())
        yield first
    finally:
        first.kill()
        first.wait()


def test_a_second_grader_on_the_same_out_is_refused_naming_the_first(tmp_path):
    out = tmp_path / 'out'
    with hanging_grader(tmp_path, out) as first:
        second = run_grader(str(scenario_file(tmp_path / 'scenarios')), '--out', str(out),
                            '--timeout', '5', *QUICK)
        assert second.returncode == 2, second.stderr
        assert said(second.stderr) == [f'error: --out {out} is in use by another grader (pid '
                                       f'{first.pid}): wait for it to finish, or give another '
                                       '--out']
        assert first.poll() is None
        assert started(out / 'hang' / 'seed_1' / isolate.LOG_NAME)  # its run's log is intact


@pytest.fixture
def small_disk(tmp_path):
    """Mount a 1 MiB tmpfs (root only); yield its folder."""
    folder = tmp_path / 'disk'
    folder.mkdir()
    mounted = subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=1m', 'tmpfs', str(folder)],
                             capture_output=True)
    if mounted.returncode != 0:
        pytest.skip('cannot mount a tmpfs here (needs root)')
    try:
        yield folder
    finally:
        subprocess.run(['umount', '-l', str(folder)], check=True)


def test_a_read_only_out_is_one_line_and_gradescope_still_gets_its_results(tmp_path,
                                                                           small_disk):
    subprocess.run(['mount', '-o', 'remount,ro', str(small_disk)], check=True)
    results = tmp_path / 'results.json'
    done = run_grader(str(scenario_file(tmp_path / 'scenarios')), '--out',
                      str(small_disk / 'out'), '--submission',
                      str(class_folder(tmp_path / 'class', ana=MOVER) / 'ana'),
                      '--gradescope', str(results), *QUICK)
    assert done.returncode == 2
    assert said(done.stderr) == [f'error: --out {small_disk / "out"}: cannot write: Read-only '
                                 'file system']
    assert 'Read-only file system' in results.read_text()


def test_a_full_disk_fails_the_runs_in_one_line_each_and_no_traceback(tmp_path, small_disk):
    with open(small_disk / 'filler', 'wb') as filler:
        with pytest.raises(OSError) as full:
            filler.write(b'x' * 2 ** 21)
            filler.flush()
    assert full.value.errno == errno.ENOSPC
    results = tmp_path / 'results.json'
    done = run_grader(str(scenario_file(tmp_path / 'scenarios')), '--out',
                      str(small_disk / 'out'), '--submissions',
                      str(class_folder(tmp_path / 'class', ana=MOVER, bob=MOVER)), *QUICK)
    assert_one_line_errors(done.stderr)
    assert done.returncode == 1, done.stderr
    assert 'No space left on device' in done.stderr
    del results


def test_a_disk_that_fills_during_the_runs_costs_those_runs_only(tmp_path, monkeypatch,
                                                                 capfd):
    written = []

    def full_disk_log(self, data):  # the first run's log fills the disk
        written.append(data)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(isolate.CappedLog, 'write', full_disk_log)
    out = tmp_path / 'out'
    status = grade.main([str(scenario_file(tmp_path / 'scenarios')), '--submissions',
                         str(class_folder(tmp_path / 'class', ana=MOVER, bob=MOVER)),
                         '--out', str(out), *QUICK])
    captured = capfd.readouterr()
    assert_one_line_errors(captured.err)
    assert written and status == 1
    rows = (out / CSV_NAME).read_text().splitlines()
    assert len(rows) == 3
    assert 'No space left on device' in captured.err


STOPPER = '''
"""A node that stops itself (SIGSTOP) at its first scan: its process, or its process group."""
import os
import signal

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class Stopper(Node):

    def __init__(self):
        super().__init__('stopper')
        self.whom = self.declare_parameter('whom', 'self').value
        self.create_subscription(LaserScan, 'scan', self.on_scan, 10)

    def on_scan(self, msg):
        if self.whom == 'group':
            os.killpg(0, signal.SIGSTOP)
        else:
            os.kill(os.getpid(), signal.SIGSTOP)


def main():
    rclpy.init()
    rclpy.spin(Stopper())
'''

LEAKER = '''
"""A node that prints its environment and raises with the grader's secrets and paths."""
import os
import sys

import rclpy
from rclpy.node import Node
import sim_bridge


class Leaker(Node):

    def __init__(self):
        super().__init__('leaker')
        print(dict(os.environ))
        with open('/proc/self/environ', 'rb') as environ:
            initial = environ.read().decode(errors='replace')
        raise RuntimeError(f'{initial} {sys.path} {sim_bridge.__file__} {os.getcwd()}')


def main():
    rclpy.init()
    rclpy.spin(Leaker())
'''


def test_an_edited_saved_result_is_run_again_and_the_report_says_so(tmp_path):
    scenario = scenario_from_dict({
        'world': 'obstacles', 'nodes': [str(MOVER)], 'duration': 1.0, 'seed': 1,
        'criteria': ['laps >= 1']}, 'lap')
    jobs = [GradeJob(run, tmp_path / run.name) for run in scenario.runs()]
    [first] = grade_runs(jobs, quiet=True, record=False, plot=False)
    assert not first.passed
    # The run's own process could write its folder: it turns its failure into a pass.
    path = jobs[0].out_dir / RESULT_NAME
    saved = json.loads(path.read_text())
    saved['report']['criteria'][0]['passed'] = True
    saved['report']['passed'] = True
    path.write_text(json.dumps(saved))
    stream = io.StringIO()
    [second] = grade_runs(jobs, quiet=True, record=False, plot=False,
                          progress=BatchProgress(1, stream=stream))
    assert not second.reused and not second.passed
    assert (f'running lap/seed_1 again: {path} was changed since the grader wrote it '
            '(its signature does not match)') in stream.getvalue()
    [note] = reuse_notes([second], tmp_path)
    assert note == ('1 saved result was run again: it was changed since the grader wrote it '
                    '(lap/seed_1)')


def scratch_parents(folder: Path) -> set[str]:
    """Return the graders' scratch parents in ``folder`` (without their lock files)."""
    return {name for name in os.listdir(folder) if name.startswith(sandbox_host.SCRATCH_PREFIX)
            and not name.endswith(sandbox_host.LOCK_SUFFIX)}


def test_the_scratch_cleanup_keeps_a_live_graders_folder_and_removes_a_dead_ones(tmp_path):
    # A grader holds a scratch parent, and so does each of its runs' processes: the live
    # grader's run lasts an hour of simulated time (~100 s of wall time here).
    temporary = tmp_path / 'tmp'
    with hanging_grader(tmp_path, tmp_path / 'live') as live:
        live_parents = scratch_parents(temporary)
        with hanging_grader(tmp_path, tmp_path / 'dead') as dead:
            dead_parents = scratch_parents(temporary) - live_parents
        assert dead.returncode == -signal.SIGKILL
        assert live_parents and dead_parents
        # A third grader on the same machine cleans up as it starts its runs.
        done = run_grader(str(scenario_file(tmp_path / 'scenarios')), '--out',
                          str(tmp_path / 'third'), *QUICK,
                          env={**os.environ, 'TMPDIR': str(temporary)})
        assert done.returncode == 0, done.stderr
        parents = scratch_parents(temporary)
        assert live.poll() is None, 'the live grader ended before the test was done'
        assert live_parents <= parents and not dead_parents & parents
        assert all(os.listdir(temporary / parent) for parent in live_parents)  # runs' folders


@pytest.mark.parametrize('whom', ['self', 'group'])
def test_a_stopped_run_fails_at_its_budget_alone_and_the_batch_goes_on(tmp_path, whom):
    node = tmp_path / 'stopper.py'
    node.write_text(STOPPER)
    scenarios = tmp_path / 'scenarios'
    scenario_file(scenarios, str(node), 5.0, 'stopped', f'params: {{stopper: {{whom: {whom}}}}}\n')
    scenario_file(scenarios, str(MOVER), 1.0, 'moving')
    out = tmp_path / 'out'
    try:
        done = subprocess.run(
            [sys.executable, '-m', 'sim_bridge.grade', str(scenarios), '--out', str(out),
             '--jobs', '2', '--timeout', '40', '--stall-timeout', '3', *QUICK],
            capture_output=True, text=True, timeout=WAIT_S)
    except subprocess.TimeoutExpired:
        pytest.fail('the grader waited for ever on a stopped run')
    assert done.returncode == 1, done.stderr
    runs = {run['run']: run for run in json.loads((out / 'report.json').read_text())['runs']}
    assert runs['moving/seed_1']['passed']
    stopped = runs['stopped/seed_1']
    assert not stopped['passed']
    # The node's own process (issue 24's agent) fails as its node error; a stopped run child
    # fails at its budget only, never as stalled.
    assert stopped['error'] is None or stopped['error'].startswith(
        'wall-clock budget of 40 s used up; the run was stopped (SIGSTOP)'), stopped


def test_gradescopes_output_holds_no_secret_and_no_instructor_path(tmp_path):
    instructor = tmp_path / 'instructor-only'
    scenario = scenario_file(instructor / 'scenarios', 'scan_ahead', 1.0, 'leak')
    submission = tmp_path / 'submission'
    submission.mkdir()
    (submission / 'scan_ahead.py').write_text(LEAKER)
    results = tmp_path / 'results.json'
    workdir = instructor / 'work'
    workdir.mkdir()
    secret = 'tok-5f2c9d1e8a7b'
    done = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.grade', str(scenario), '--submission',
         str(submission), '--gradescope', str(results), '--out', str(instructor / 'out'),
         *QUICK], cwd=workdir, capture_output=True, text=True, timeout=WAIT_S,
        env={**os.environ, 'GRADER_API_TOKEN': secret,
             'PYTHONPATH': os.pathsep.join(sys.path)})
    assert done.returncode == 1, done.stderr
    text = results.read_text()
    assert secret not in text
    for path in (instructor, repo_root() or Path(__file__).parents[2],
                 Path(tempfile.gettempdir()) / sandbox_host.SCRATCH_PREFIX):
        assert str(path) not in text, path
    assert 'RuntimeError' in text  # the student's own error is shown


def test_a_videos_world_and_length_come_from_the_graders_records_not_the_runs_folder(
        tmp_path):
    import imageio_ffmpeg
    scenario = scenario_file(tmp_path / 'scenarios', str(MOVER), 2.0, 'filmed')
    out = tmp_path / 'out'
    assert grade.main([str(scenario), '--out', str(out), '--no-plot', '--quiet',
                       '--video']) == 0
    # What a run could write in its folder: a far longer run, in a world of its choosing.
    folder = out / 'filmed' / 'seed_1'
    metrics = json.loads((folder / 'metrics.json').read_text())
    (folder / 'metrics.json').write_text(json.dumps({**metrics, 'sim_time_s': 30.0}))
    params = folder / 'params.yaml'
    params.write_text(params.read_text().replace('obstacles', str(tmp_path / 'bomb.world')))
    (folder / 'video.mp4').unlink()
    assert grade.main([str(scenario), '--out', str(out), '--no-plot', '--quiet',
                       '--video']) == 0
    frames = imageio_ffmpeg.count_frames_and_secs(str(folder / 'video.mp4'))[0]
    assert frames == 20  # 2 s of the scenario at 10 frames a second


def test_the_signing_key_is_the_graders_alone_and_binds_a_result_to_its_folder(tmp_path):
    state = grader_state.state_folder({'XDG_STATE_HOME': str(tmp_path / 'state')})
    key = grader_state.signing_key(state)
    assert (state.stat().st_mode & 0o777, (state / grader_state.KEY_NAME).stat().st_mode & 0o777
            ) == (0o700, 0o600)
    assert grader_state.signing_key(state) == key  # kept for the next invocation
    (state / grader_state.KEY_NAME).chmod(0o644)  # readable by others: no longer a secret
    assert grader_state.signing_key(state) != key
    signer = grader_state.ResultSigner(key)
    saved = {'fingerprint': 'f', 'report': {'passed': True}}
    signature = signer.signature(tmp_path / 'ana', saved)
    assert signer.signs(tmp_path / 'ana', saved, signature)
    assert not signer.signs(tmp_path / 'bob', saved, signature)  # copied to another's folder
    assert not grader_state.ResultSigner(bytes(32)).signs(tmp_path / 'ana', saved, signature)


def test_a_stopped_gradescope_grading_keeps_the_tests_of_its_finished_runs(tmp_path):
    submission = class_folder(tmp_path / 'class', ana=MOVER) / 'ana'
    shutil.copy(HELPER_STARTER, submission / HELPER_STARTER.name)
    scenarios = tmp_path / 'scenarios'
    scenario_file(scenarios, 'scan_ahead', 1.0, 'moves')
    scenario_file(scenarios, str(HELPER_STARTER), 0.5, 'hangs',
                  'params: {helper_starter: {how: hang}}\n')  # shorter: run second
    results, out = tmp_path / 'results.json', tmp_path / 'out'
    with open(tmp_path / 'stderr.txt', 'w') as stderr:
        grader = subprocess.Popen(
            [sys.executable, '-m', 'sim_bridge.grade', str(scenarios), '--submission',
             str(submission), '--gradescope', str(results), '--out', str(out),
             '--stall-timeout', '600', *QUICK], stdout=subprocess.DEVNULL, stderr=stderr)
    try:
        assert wait_until(lambda: started(out / 'hangs' / 'seed_1' / isolate.LOG_NAME)), (
            (tmp_path / 'stderr.txt').read_text())
        grader.send_signal(signal.SIGTERM)  # Gradescope's time limit
        assert grader.wait(timeout=WAIT_S) == 128 + signal.SIGTERM
    finally:
        grader.kill()
    tests = {test['name']: test for test in json.loads(results.read_text())['tests']}
    assert tests['moves: moves']['status'] == 'passed', tests
    assert tests['hangs: hangs']['status'] == 'failed'
    assert ('not graded: the grading was stopped after 1 of 2 runs'
            in tests['hangs: hangs']['output'])
