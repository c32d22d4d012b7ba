"""
What no run can do to the grader: edit a saved grade, lose a live grader its scratch folder,
stall the batch by stopping itself, or leak the grader's secrets into Gradescope's results.

Each test grades real runs of a small hostile node of its own (issue 24, §2, §4 and §5).
"""

import io
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile

import pytest

from sim_bridge.common.paths import repo_root
from sim_bridge.grading import isolate
from sim_bridge.grading.batch import BatchProgress, grade_runs
from sim_bridge.grading.runs import GradeJob, RESULT_NAME, reuse_notes
from sim_bridge.grading.scenario import scenario_from_dict
from test_grader_faults import hanging_grader, QUICK, scenario_file, WAIT_S

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
MOVER = FIXTURES / 'function_node.py'

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
import sim_bridge


def main():
    print(dict(os.environ))
    with open('/proc/self/environ', 'rb') as environ:
        initial = environ.read().decode(errors='replace')
    raise RuntimeError(f'{initial} {sys.path} {sim_bridge.__file__} {os.getcwd()}')
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


def scratch_folders(folder: Path) -> list[str]:
    return sorted(name for name in os.listdir(folder)
                  if name.startswith(isolate.SCRATCH_PREFIX))


def test_the_scratch_cleanup_keeps_a_live_graders_folder_and_removes_a_dead_ones(tmp_path):
    temporary = tmp_path / 'tmp'
    # A grader killed with SIGKILL leaves its run's scratch folder behind.
    with hanging_grader(tmp_path / 'dead', tmp_path / 'dead' / 'out') as dead:
        pass
    assert dead.returncode == -signal.SIGKILL
    [left] = scratch_folders(tmp_path / 'dead' / 'tmp')
    os.rename(tmp_path / 'dead' / 'tmp' / left, tmp_path / 'left')
    temporary.mkdir()
    with hanging_grader(tmp_path, tmp_path / 'out'):
        [live] = scratch_folders(temporary)
        # The live grader seen from another pid namespace: its pid is no process here.
        os.rename(temporary / live, temporary / f'{isolate.SCRATCH_PREFIX}999999999-live')
        # The dead grader's pid reused by a running process (this one).
        os.rename(tmp_path / 'left', temporary / f'{isolate.SCRATCH_PREFIX}{os.getpid()}-dead')
        isolate.remove_leftover_scratch(str(temporary))
        assert scratch_folders(temporary) == [f'{isolate.SCRATCH_PREFIX}999999999-live']


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
    assert runs['stopped/seed_1']['error'].startswith(
        'wall-clock budget of 40 s used up; the run was stopped (SIGSTOP)'), runs


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
    assert 'RuntimeError' in text  # the student's own error is shown
    assert secret not in text
    for path in (instructor, repo_root() or Path(__file__).parents[2],
                 Path(tempfile.gettempdir()) / isolate.SCRATCH_PREFIX):
        assert str(path) not in text, path
