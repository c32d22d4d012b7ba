"""
A node file run by the runner cannot reach what the grader keeps: each attack of a hostile node.

fixtures/hostile/prying_node.py tries, as it is imported: an instructor's secret file, the
grader's environment through /proc (any of it), its own environment (a secret the grader's
holds), the kit's reference nodes, and the grader's pipes through /proc/<ppid>/fd. What it
printed is read from the run's log.jsonl.
"""

import json
import os
from pathlib import Path
import shutil
import subprocess
import tempfile

import pytest
from sim_bridge.grading.class_batch import ClassBatch
from sim_bridge.grading.scenario import scenario_from_dict
from sim_bridge.runner.boundary.outside import sandbox as sandbox_module
from sim_bridge.runner.boundary.outside.node_sandbox import NodeSandbox
from sim_bridge.runner.boundary.outside.sandbox import (
    isolation_mode, NO_NAMESPACES_VARIABLE, SandboxLimits)
from sim_bridge.runner.run import run_simulation

HOSTILE = Path(__file__).resolve().parent / 'fixtures' / 'hostile'
KIT_NODES = Path(__file__).resolve().parents[2] / 'scan_pkg' / 'scan_pkg'
SECRET = 'instructor-secret-5f1c'
#: What only a sandbox holds: an ordinary user without bubblewrap runs NOT sandboxed, where a
#: run reads what its grader reads (docs/grading.md); its own environment is clean even there.
held = pytest.mark.skipif(isolation_mode().kind == 'none',
                          reason='NOT sandboxed here: nothing is held from a run')


@pytest.fixture(scope='module')
def pried(tmp_path_factory):
    """Run the prying node once; return its attempts and the run's out dir."""
    root = tmp_path_factory.mktemp('pried')
    instructor, student, out_dir = root / 'instructor', root / 'student', root / 'out'
    instructor.mkdir()
    student.mkdir()
    (instructor / 'solutions.txt').write_text(SECRET)
    shutil.copy(HOSTILE / 'prying_node.py', student / 'prying_node.py')
    (student / 'prying_targets.py').write_text(
        f'SECRET_FILE = {str(instructor / "solutions.txt")!r}\nGRADER_PID = {os.getpid()}\n')
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv('LAB_SECRET', SECRET)
        run_simulation('obstacles', [str(student / 'prying_node.py')], duration_s=1.0,
                       out_dir=out_dir, quiet=True)
    lines = [json.loads(line) for line in (out_dir / 'log.jsonl').read_text().splitlines()]
    printed = [text for entry in lines for text in entry.values()
               if isinstance(text, str) and text.startswith('PRYING ')]
    assert printed, lines
    return json.loads(printed[0].removeprefix('PRYING ')), out_dir


@pytest.mark.parametrize('attack', [pytest.param('secret file', marks=held),
                                    pytest.param('grader environ', marks=held), 'own environ',
                                    pytest.param('parent pipes', marks=held)])
def test_a_node_file_cannot_reach_the_graders_secrets_or_pipes(pried, attack):
    found, _ = pried
    assert not found[attack].startswith('GOT'), found


@held
def test_a_node_file_cannot_import_the_reference_nodes(pried):
    found, _ = pried
    assert found['scan_pkg.wall_follow'] in ('ImportError', 'ModuleNotFoundError'), found
    # Nor the controllers they run, from source or from Python's bytecode cache.
    assert found['scan_pkg.behaviors'] in ('ImportError', 'ModuleNotFoundError'), found
    assert not found['cached controller'].startswith('GOT'), found
    assert found['scan_pkg.report'].startswith('GOT'), found  # the kit's library: students'


@held
def test_a_node_file_cannot_import_the_graders_own_scan_geometry(pried):
    # sim_bridge is readable in a run (its agent lives there): the regions it judges by are not.
    found, _ = pried
    refused = ('ImportError', 'ModuleNotFoundError', 'PermissionError')
    assert found['grader geometry'] in refused, found


@held
def test_the_secret_is_in_no_output_file(pried):
    _, out_dir = pried
    holding = [path for path in out_dir.rglob('*')
               if path.is_file() and SECRET.encode() in path.read_bytes()]
    assert not holding


def test_the_run_says_how_its_nodes_were_isolated(pried):
    _, out_dir = pried
    metrics = json.loads((out_dir / 'metrics.json').read_text())
    isolation = metrics['run_mode']['sandbox']
    assert isolation.startswith(('bubblewrap', 'PARTLY', 'NOT')), isolation
    if not isolation.startswith('bubblewrap'):
        assert any(warning.startswith('runs ') for warning in metrics['warnings'])


def test_not_sandboxed_a_run_still_runs_to_its_grade_and_says_so_loudly(shared_python):
    # An ordinary user with no namespaces (forced here by the grader's environment): the run
    # is graded as it would be sandboxed, and the grader and every report say it was not.
    setpriv = shutil.which('setpriv')
    if os.geteuid() != 0 or setpriv is None:
        pytest.skip('needs root and setpriv, to grade as user nobody')
    folder = Path(tempfile.mkdtemp())
    try:
        folder.chmod(0o777)  # nobody's: the submission, the scenario, the outputs
        node = folder / 'scan_ahead.py'
        shutil.copy(KIT_NODES / 'scan_ahead.py', node)
        scenario = folder / 'ahead.yaml'
        scenario.write_text(f'world: obstacles\nnodes: [{node}]\nduration: 2.0\nseed: 1\n'
                            'criteria: [len(node_errors) == 0, collisions == 0]\n')
        for path in (node, scenario):
            path.chmod(0o644)
        done = subprocess.run(
            [setpriv, '--reuid=65534', '--regid=65534', '--clear-groups', shared_python, '-m',
             'sim_bridge.grade', str(scenario), '--out', str(folder / 'out'), '--no-record',
             '--no-plot'], capture_output=True, text=True, timeout=300, cwd=folder,
            env={**os.environ, 'HOME': str(folder), NO_NAMESPACES_VARIABLE: '1'})
        report = json.loads((folder / 'out' / 'report.json').read_text())
        page = (folder / 'out' / 'report.html').read_text()
    finally:
        shutil.rmtree(folder)
    said = f'NOT sandboxed: namespaces turned off by {NO_NAMESPACES_VARIABLE}'
    assert done.returncode == 0, done.stderr
    assert f'node processes: {said}' in done.stderr.splitlines()
    assert f'note: runs {said}' in done.stdout.splitlines()
    assert report['notes'] == [f'runs {said}'] and said in page
    [run] = report['runs']
    assert run['passed'] and run['metrics']['run_mode']['sandbox'] == said


def test_partly_sandboxed_a_students_run_reads_no_classmates_file_nor_output(
        shared_python, monkeypatch):
    # Without namespaces a run's uid reads what any user may: a class folder as an
    # instructor's umask leaves it (0755, 0644) hands alice's run bob's honest node file.
    if os.geteuid() != 0:
        pytest.skip('a dedicated uid needs root')
    monkeypatch.setenv(NO_NAMESPACES_VARIABLE, '1')
    monkeypatch.setattr(sandbox_module, 'LAUNCHER_PYTHON', shared_python)
    isolation_mode.cache_clear()
    folder = Path(tempfile.mkdtemp())
    try:
        folder.chmod(0o755)
        submissions, out = folder / 'class', folder / 'out'
        for student in ('alice', 'bob'):
            (submissions / student).mkdir(parents=True)
        shutil.copy(HOSTILE / 'snoop.py', submissions / 'alice' / 'wall_follow.py')
        (submissions / 'bob' / 'wall_follow.py').write_text(
            (KIT_NODES / 'wall_follow.py').read_text())  # 0644, as bob's upload
        earlier = out / 'students' / 'bob' / 'wall_follow' / 'seed_1' / 'log.jsonl'
        earlier.parent.mkdir(parents=True)
        earlier.write_text('{"printed": "what bob printed"}\n')
        scenario = scenario_from_dict({'world': 'obstacles', 'nodes': ['wall_follow'],
                                       'duration': 1.0, 'criteria': ['collisions == 0']},
                                      'wall_follow')
        ClassBatch([scenario], submissions, out)
        targets = [submissions / 'bob' / 'wall_follow.py', earlier]
        where = NodeSandbox(str(submissions / 'alice' / 'wall_follow.py'), SandboxLimits())
        with where.sandbox as box, tempfile.TemporaryFile() as output:
            box.popen([shared_python, where.target, str(os.getpid()), *map(str, targets),
                       '--write'], where.environment(), stdout=output,
                      stderr=subprocess.STDOUT).wait(120)
            output.seek(0)
            text = output.read().decode()
    finally:
        shutil.rmtree(folder)
        isolation_mode.cache_clear()
    assert box.isolation.startswith('PARTLY sandboxed'), box.isolation
    found = json.loads(text.splitlines()[-1])
    assert [found[str(target)] for target in targets] == ['PermissionError'] * 2, found
