"""
Gradescope: ``grade --gradescope results.json`` and the autograder.zip's ``run_autograder``.

The results follow Gradescope's autograder specification: a score, and tests with name,
score, max_score, status ('passed' or 'failed'), output and visibility. ``run_autograder`` is
run as Gradescope runs it, on a root laid out as Gradescope lays it out (``source/`` from the
zip, ``submission/``, ``results/``), with real runs of the project's nodes.
"""

import json
import os
from pathlib import Path
import shutil
import stat
import subprocess
import sys
import tempfile
from types import SimpleNamespace
import zipfile

import pytest

from sim_bridge.commands import autograder as autograder_command, grade
from sim_bridge.grading.runs import run_scenario
from sim_bridge.runner.boundary.outside.sandbox import isolation_mode, NO_NAMESPACES_VARIABLE

WORKSPACE = Path(__file__).resolve().parents[2]
FIXTURES = Path(__file__).resolve().parent / 'fixtures'
SCENARIO = """\
world: wall_follow_box
nodes: [wall_follow]
task: {task}
marks: {marks}
marking: proportional
duration: 30
seeds: [1, 2, 3]
criteria: [laps >= 1, collisions == 0]
"""


def fake_simulate(world, targets, **options):
    """Stand in for run_simulation: seed 2 collides, seed 3 never completes a lap."""
    seed = options['seed']
    return SimpleNamespace(metrics={'laps': 0 if seed == 3 else 1, 'sim_time_s': 30.0,
                                    'collisions': 1 if seed == 2 else 0, 'node_errors': []})


def grade_in_process(jobs, *, progress=None, **options):
    """Stand in for grade_runs: each job's run in this process with fake_simulate."""
    return [run_scenario(job.run, job.out_dir, simulate=fake_simulate) for job in jobs]


@pytest.fixture
def scenarios(tmp_path):
    folder = tmp_path / 'scenarios'
    folder.mkdir()
    # Written in the opposite order of their tasks: the tests come ordered by task.
    (folder / 'a_box.yaml').write_text(SCENARIO.format(task=4, marks=3))
    (folder / 'b_box.yaml').write_text(SCENARIO.format(task=1, marks=2))
    return folder


def graded(tmp_path, monkeypatch, *arguments):
    monkeypatch.setattr(grade, 'grade_runs', grade_in_process)
    results = tmp_path / 'results' / 'results.json'
    status = grade.main([*map(str, arguments), '--gradescope', str(results),
                         '--out', str(tmp_path / 'out'), '--quiet'])
    return status, json.loads(results.read_text(encoding='utf-8'))


def test_results_score_the_marks_with_a_test_per_scenario_ordered_by_task(
        tmp_path, monkeypatch, scenarios, capsys):
    submission = tmp_path / 'submission'
    submission.mkdir()
    (submission / 'wall_follow.py').write_text('# graded by the stand-in simulator\n')
    status, results = graded(tmp_path, monkeypatch, scenarios, '--submission', submission)
    assert status == 1
    # 1 of 3 runs passes in each: 2/3 of task 1's marks 2, 1/3 of task 4's 3.
    assert results['score'] == pytest.approx(2 / 3 + 1, abs=1e-4)
    assert [(test['name'], test['score'], test['max_score'], test['status'])
            for test in results['tests']] == [
        ('task 1: b_box', pytest.approx(2 / 3, abs=1e-4), 2.0, 'failed'),
        ('task 4: a_box', 1.0, 3.0, 'failed')]
    output = results['tests'][0]['output']
    assert output.splitlines()[:4] == [
        '1 of 3 runs passed, 0.67 of 2 marks', 'b_box/seed_2: collisions == 0',
        'b_box/seed_3: laps >= 1', 'task 1: 2 marks x runs passed / 3 runs']
    assert 'laps >= 1' in output and str(tmp_path) not in json.dumps(results)
    assert results['output'].splitlines()[:2] == [
        'marks 1.67/5 (task 1: 0.67/2, task 4: 1/3)',
        'for information: 2 of 6 runs met every criterion of their scenario (the marks are the '
        'tests below)']
    assert {test['visibility'] for test in results['tests']} == {'visible'}
    # The summary line and the report show the marks too.
    assert '2 of 6 runs passed, marks 1.67/5 (task 1: 0.67/2, task 4: 1/3)' in \
        capsys.readouterr().out
    report = json.loads((tmp_path / 'out' / grade.REPORT_NAME).read_text())
    assert (report['marks']['total'], report['marks']['max']) == (pytest.approx(5 / 3), 5.0)
    assert 'marks 1.67/5' in (tmp_path / 'out' / grade.PAGE_NAME).read_text()


def fake_wall_follow(world, targets, **options):
    """Stand in for run_simulation: a clockwise follower at 0.7 m; seed 2 touches the box."""
    seed = options['seed']
    evidence = {'laps': -1, 'direction': 'clockwise', 'winding': -1.2, 'distance_m': 12.0,
                'along_turns': 1.1, 'chosen_m': 0.7, 'declared_m': None, 'mae_m': 0.05}
    return SimpleNamespace(metrics={'laps': -1, 'sim_time_s': 30.0, 'node_errors': [],
                                    'collisions': 1 if seed == 2 else 0,
                                    'wall_follow': evidence})


def graded_by_points(tmp_path, monkeypatch, simulate) -> dict:
    """Grade a wall follower on box_cw, marked by its points, with ``simulate``: results."""
    folder = tmp_path / 'scenarios'
    folder.mkdir()
    (folder / 'box_cw.yaml').write_text(SCENARIO.format(task=4, marks=3)
                                        + 'points: wall_follow\ndirection: clockwise\n')
    submission = tmp_path / 'submission'
    submission.mkdir()
    (submission / 'wall_follow.py').write_text('# graded by the stand-in simulator\n')
    monkeypatch.setattr(grade, 'grade_runs', lambda jobs, **options: [
        run_scenario(job.run, job.out_dir, simulate=simulate) for job in jobs])
    results = tmp_path / 'results.json'
    grade.main([str(folder), '--submission', str(submission), '--gradescope', str(results),
                '--out', str(tmp_path / 'out'), '--quiet'])
    return json.loads(results.read_text(encoding='utf-8'))


def test_a_task_marked_by_points_has_a_test_per_point_saying_why_it_was_lost(
        tmp_path, monkeypatch):
    results = graded_by_points(tmp_path, monkeypatch, fake_wall_follow)
    assert results['score'] == pytest.approx(3 - 1 / 3, abs=1e-4)
    assert [(test['name'], test['score'], test['max_score'], test.get('status'))
            for test in results['tests']] == [
        ('task 4: loops the object in one direction', 1.0, 1.0, 'passed'),
        ('task 4: keeps the wall at the distance it chose', 1.0, 1.0, 'passed'),
        ('task 4: no collision', pytest.approx(2 / 3, abs=1e-4), 1.0, 'failed'),
        ('task 4: runs (for information)', 0.0, 0.0, None)]
    assert results['tests'][2]['output'].splitlines() == [
        '1 collision(s) (box_cw/seed_2; lost in 1 of 3 runs)',
        'rule: "Move along walls without hitting them": no contact, only for a robot that moved '
        'along the object for 0.75 of a loop or more (a parked or crashed robot shows none).']
    assert results['tests'][0]['output'].startswith('shown in every run (3)')


def test_no_test_contradicts_the_score_when_the_points_are_earned_and_the_runs_fail(
        tmp_path, monkeypatch):
    def careful(world, targets, **options):  # no collision, in every seed
        return fake_wall_follow(world, targets, **dict(options, seed=1))

    # Every run fails its criteria (laps >= 1: the evidence says -1) and shows every point.
    results = graded_by_points(tmp_path, monkeypatch, careful)
    assert results['score'] == 3.0
    assert sum(test['score'] for test in results['tests']) == results['score']
    for test in results['tests']:  # full marks: a test passes, or is there for information
        assert test.get('status', 'passed') == 'passed', test
        assert test['score'] == test['max_score'], test
    assert '0 of 3 runs passed' not in json.dumps(results)
    assert '0 of 3 runs met every criterion' in results['tests'][-1]['output']


def test_a_submission_without_the_node_file_scores_0_saying_which_file(
        tmp_path, monkeypatch, scenarios):
    submission = tmp_path / 'submission'
    submission.mkdir()
    (submission / 'lab_notes.py').write_text('# no node\n')
    status, results = graded(tmp_path, monkeypatch, scenarios, '--submission', submission)
    assert status == 1
    assert results['score'] == 0
    assert [(test['score'], test['max_score'], test['status']) for test in results['tests']] \
        == [(0, 2.0, 'failed'), (0, 3.0, 'failed')]
    assert results['tests'][1]['output'].splitlines()[1].startswith(
        'a_box/seed_1: not submitted: no wall_follow.py in submission/ (found: lab_notes.py; ')


@pytest.mark.parametrize('arguments, says', [
    (['no_such_scenarios/'], 'no_such_scenarios: cannot read'),
    (['TMP/missing.yaml'], 'The submission could not be graded: missing.yaml: cannot read'),
    (['SCENARIOS', '--submission', 'nowhere'], '--submission nowhere: not a folder'),
])
def test_results_are_written_with_0_and_why_when_the_grading_cannot_start(
        tmp_path, monkeypatch, scenarios, arguments, says):
    monkeypatch.chdir(tmp_path)
    arguments = [str(scenarios) if argument == 'SCENARIOS'
                 else argument.replace('TMP', str(tmp_path)) for argument in arguments]
    status, results = graded(tmp_path, monkeypatch, *arguments)
    assert status == 2
    assert results['score'] == 0 and results['tests'] == []
    assert results['output'].startswith('The submission could not be graded: ')
    assert says in results['output']


def test_results_say_so_when_the_grading_is_stopped(tmp_path, monkeypatch, scenarios):
    def interrupted(jobs, **options):
        raise KeyboardInterrupt

    monkeypatch.setattr(grade, 'grade_runs', interrupted)
    results = tmp_path / 'results.json'
    assert grade.main([str(scenarios), '--gradescope', str(results), '--out',
                       str(tmp_path / 'out'), '--quiet']) == 130
    written = json.loads(results.read_text())
    assert written['score'] == 0
    assert 'the grading was stopped after 0 of 6 runs' in written['output']


def test_gradescope_results_are_for_one_submission_not_a_class(tmp_path, scenarios, capsys):
    results = tmp_path / 'results.json'
    assert grade.main([str(scenarios), '--submissions', str(tmp_path), '--gradescope',
                       str(results)]) == 2
    assert 'grade it with --submission DIR' in capsys.readouterr().err
    assert 'grade it with --submission DIR, not --submissions' in \
        json.loads(results.read_text())['output']


# run_autograder on a Gradescope-like root, with real runs.
AHEAD = """\
world: obstacles
nodes: [scan_ahead]
task: 1
marks: 2
duration: 2.0
seed: 1
criteria: [len(node_errors) == 0, collisions == 0]
"""
WANDER = """\
world: room
nodes: [wanderbot]
task: 2
marks: 3
marking: proportional
params:
  wanderbot: {seed: $seed}
duration: 3.0
seeds: [1, 2]
criteria: [len(node_errors) == 0, collisions == 0]
"""


@pytest.fixture(scope='module')
def autograder(tmp_path_factory):
    """Build autograder.zip from two short scenarios; return the zip's path and its names."""
    folder = tmp_path_factory.mktemp('build')
    (folder / 'ahead.yaml').write_text(AHEAD)
    (folder / 'wander.yaml').write_text(WANDER)
    zip_path = folder / 'autograder.zip'
    assert autograder_command.main(['build', str(folder / 'ahead.yaml'),
                                    str(folder / 'wander.yaml'), '-o', str(zip_path)]) == 0
    return zip_path


def gradescope_root(folder: Path, zip_path: Path, files: dict[str, Path]) -> Path:
    """Lay out a root as Gradescope does: source/ (the zip), submission/, results/."""
    root = folder / 'autograder'
    with zipfile.ZipFile(zip_path) as archive:
        archive.extractall(root / 'source')
        for info in archive.infolist():  # extractall drops the modes; Gradescope keeps them
            os.chmod(root / 'source' / info.filename, info.external_attr >> 16 & 0o777)
    shutil.copy(root / 'source' / 'run_autograder', root / 'run_autograder')
    (root / 'submission').mkdir()
    (root / 'results').mkdir()
    for name, source in files.items():
        shutil.copy(source, root / 'submission' / name)
    return root


def run_autograder(root: Path, python: str | None = sys.executable, **variables: str) -> dict:
    environment = {**os.environ, **variables, 'AUTOGRADER_ROOT': str(root)}
    environment.pop('AUTOGRADER_PYTHON', None)
    if python is not None:
        environment['AUTOGRADER_PYTHON'] = python
    # The kit's packages come from the zip (run_autograder sets PYTHONPATH), not from here.
    environment.pop('PYTHONPATH', None)
    subprocess.run([str(root / 'run_autograder')], env=environment, cwd=root, check=True,
                   timeout=600, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return json.loads((root / 'results' / 'results.json').read_text(encoding='utf-8'))


def test_the_zip_holds_setup_run_autograder_the_kit_and_the_scenarios(autograder):
    with zipfile.ZipFile(autograder) as archive:
        names = archive.namelist()
        modes = {info.filename: info.external_attr >> 16 for info in archive.infolist()}
        setup = archive.read('setup.sh').decode()
    assert names[:4] == ['setup.sh', 'run_autograder', 'scenarios/ahead.yaml',
                         'scenarios/wander.yaml']
    assert modes['run_autograder'] & stat.S_IXUSR and modes['setup.sh'] & stat.S_IXUSR
    for name in ('kit/lab', 'kit/requirements-ros.txt', 'kit/worlds/room.yaml',
                 'kit/scan_pkg/scan_pkg/wanderbot.py',
                 'kit/sim_bridge/sim_bridge/grade/__main__.py',
                 'kit/sim_bridge/setup.py'):
        assert name in names
    assert modes['kit/lab'] & stat.S_IXUSR
    assert not [name for name in names if '/test/' in name or '__pycache__' in name]
    # What grading needs, nothing for development: no colcon, pytest or linters.
    assert 'python3-venv' in setup and '-r "$kit/requirements.txt"' in setup
    assert 'requirements-dev' not in setup and 'ament-(flake8|pep257)' in setup


def test_run_autograder_grades_a_node_on_the_kits_library_but_not_on_its_answers(
        autograder, tmp_path):
    # scan_ahead uses scan_pkg's library (report): full marks. The kit's wanderbot runs the
    # kit's own controller (scan_pkg.behaviors), which a submission's sandbox holds empty.
    if isolation_mode().kind == 'none':
        pytest.skip('NOT sandboxed (an ordinary user without bubblewrap): a run reads what its '
                    "grader reads, the kit's answers too (docs/grading.md); Gradescope is root")
    nodes = WORKSPACE / 'scan_pkg' / 'scan_pkg'
    root = gradescope_root(tmp_path, autograder, {'scan_ahead.py': nodes / 'scan_ahead.py',
                                                  'wanderbot.py': nodes / 'wanderbot.py'})
    results = run_autograder(root)
    assert results['score'] == 2
    ahead, wander = results['tests']
    assert (ahead['name'], ahead['score'], ahead['max_score'], ahead['status']) == (
        'task 1: ahead', 2, 2, 'passed')
    assert (wander['score'], wander['status']) == (0, 'failed')
    assert 'Error' in wander['output'] and 'behaviors' in wander['output'], wander['output']
    assert (root / 'results' / 'graded' / 'ahead' / 'seed_1' / 'metrics.json').is_file()


def test_run_autograder_partly_sandboxed_grades_as_the_dedicated_uid_and_says_so(
        autograder, shared_python):
    # As root in a container that refuses namespaces (forced here by the grader's
    # environment): each run drops to a dedicated uid, which cannot read the kit's answers.
    if os.geteuid() != 0:
        pytest.skip('the dedicated uid needs root')
    folder = Path(tempfile.mkdtemp(prefix='gradescope-'))  # the runs' uids read the kit there
    try:
        folder.chmod(0o755)
        nodes = WORKSPACE / 'scan_pkg' / 'scan_pkg'
        root = gradescope_root(folder, autograder, {'scan_ahead.py': nodes / 'scan_ahead.py',
                                                    'wanderbot.py': nodes / 'wanderbot.py'})
        results = run_autograder(root, python=shared_python,
                                 **{NO_NAMESPACES_VARIABLE: '1'})
        report = json.loads((root / 'results' / 'graded' / 'report.json').read_text())
        page = (root / 'results' / 'graded' / 'report.html').read_text()
        modes = [path.stat().st_mode & 0o777 for path in (
            root, root / 'source', root / 'source' / 'scenarios',
            root / 'source' / 'scenarios' / 'ahead.yaml')]
    finally:
        shutil.rmtree(folder)
    assert results['score'] == 2, json.dumps(results, indent=1)
    # The runs' uids pass through the root to the kit; the scenarios are root's alone.
    assert [mode & 0o001 for mode in modes[:2]] == [1, 1] and modes[2:] == [0o700, 0o600]
    ahead, wander = results['tests']
    assert (ahead['score'], ahead['status'], wander['score'], wander['status']) == (
        2, 'passed', 0, 'failed')
    assert 'PermissionError' in wander['output'] and 'wanderbot.py' in wander['output']
    said = ('runs PARTLY sandboxed: uid 6', ' only, no namespaces (namespaces turned off by '
            f'{NO_NAMESPACES_VARIABLE})')
    [note] = [line for line in results['output'].splitlines() if line.startswith(said[0])]
    assert said[1] in note and note in report['notes'] and 'PARTLY sandboxed' in page
    [ahead_run] = [run for run in report['runs'] if run['run'] == 'ahead/seed_1']
    assert ahead_run['metrics']['run_mode']['sandbox'].startswith('PARTLY sandboxed: uid 6')


#: ``python3`` on the machine setup.sh is tried on, offline: ``-m venv`` makes a venv of the
#: system's Python, with its pip, that reads this Python's packages (fixtures/shared_venv.py).
PYTHON3_STUB = ('#!/bin/sh\n[ "$1 $2" = "-m venv" ] || exec /usr/bin/python3 "$@"\n'
                'exec {python} {shared_venv} --with-pip "$3"\n')
#: The grader's side of a hunt, run as run_autograder runs the grader: the node file given
#: runs as a submission's, with the answers to look for; prints what it printed.
HUNT_AS_GRADER = """
import subprocess, sys, tempfile
from sim_bridge.runner.boundary.outside.node_sandbox import NodeSandbox
from sim_bridge.runner.boundary.outside.sandbox import SandboxLimits
where = NodeSandbox(sys.argv[1], SandboxLimits())
with where.sandbox as box, tempfile.TemporaryFile() as output:
    box.popen([sys.executable, where.target, sys.argv[2]], where.environment(), stdout=output,
              stderr=subprocess.STDOUT).wait(300)
    output.seek(0)
    print(output.read().decode())
"""


def set_up(root: Path) -> None:
    """Run the zip's setup.sh as Gradescope does (as root), offline: apt-get does nothing."""
    stubs = root.parent / 'stubs'
    stubs.mkdir()
    (stubs / 'apt-get').write_text('#!/bin/sh\nexit 0\n')
    (stubs / 'python3').write_text(PYTHON3_STUB.format(
        python=sys.executable, shared_venv=FIXTURES / 'shared_venv.py'))
    for stub in stubs.iterdir():
        stub.chmod(0o755)
    # pip finds every requirement installed (this Python's site folder), and builds the kit's
    # packages with the setuptools there.
    done = subprocess.run(['bash', str(root / 'source' / 'setup.sh')], timeout=600, text=True,
                          capture_output=True, env={**os.environ, 'PIP_NO_INDEX': '1',
                                                    'PATH': f'{stubs}:{os.environ["PATH"]}',
                                                    'PIP_NO_BUILD_ISOLATION': '0'})
    assert done.returncode == 0, done.stderr[-2000:]


def test_setup_leaves_no_answer_a_partly_sandboxed_run_can_read(
        autograder, tmp_path, shared_python, answer_hunt):
    # pip builds the kit's packages in their folders, which leaves a readable copy of the
    # reference nodes in kit/scan_pkg/build/lib (3/3 for a wall_follow.py that runs it from
    # there, PARTLY sandboxed). A hostile student's node walks the machine,
    # as the autograder's grader runs it without namespaces, and names every answer it reads.
    if os.geteuid() != 0 or not Path('/usr/bin/python3').is_file():
        pytest.skip("setup.sh runs as root, with the system's Python")
    folder = Path(tempfile.mkdtemp(prefix='gradescope-'))  # the runs' uids read the kit there
    try:
        folder.chmod(0o755)
        root = gradescope_root(folder, autograder, {})
        set_up(root)
        kit = root / 'source' / 'kit'
        built = [str(path.relative_to(kit)) for pattern in ('*/build', '*/*.egg-info')
                 for path in kit.glob(pattern)]
        # What the setup.sh of earlier kits left there: the grader closes it to runs.
        shutil.copytree(kit / 'scan_pkg' / 'scan_pkg', kit / 'scan_pkg' / 'build' / 'lib'
                        / 'scan_pkg', dirs_exist_ok=True)
        (tmp_path / 'student').mkdir()
        node = tmp_path / 'student' / 'wall_follow.py'
        shutil.copy(FIXTURES / 'hostile' / 'answer_hunt.py', node)
        sources = [path for path in (kit / 'scan_pkg' / 'scan_pkg').rglob('*.py')
                   if path.stem in ('closest_obstacle', 'scan_ahead', 'scan_around',
                                    'wall_follow', 'wanderbot') or 'behaviors' in path.parts]
        library = kit / 'scan_pkg' / 'scan_pkg' / 'report.py'
        hunted = subprocess.run(
            [str(kit / '.venv' / 'bin' / 'python'), '-c', HUNT_AS_GRADER, str(node),
             json.dumps(answer_hunt.wanted(sources, [library]))],
            capture_output=True, text=True, timeout=600,
            env={**os.environ, 'PYTHONPATH': f'{kit}/scan_pkg:{kit}/sim_bridge',
                 NO_NAMESPACES_VARIABLE: '1'})
        found = json.loads(hunted.stdout.strip().splitlines()[-1])
    finally:
        shutil.rmtree(folder)
    assert len(sources) == 8 and found['expected'] == [str(library)], (sources, found)
    assert built == []
    # The run sees the whole machine: other checkouts of the kit are other people's files.
    assert [path for path in found['answers'] if path.startswith(str(folder))] == []


def test_run_autograder_gives_0_to_a_crashing_node_and_a_missing_file(autograder, tmp_path):
    root = gradescope_root(tmp_path, autograder,
                           {'scan_ahead.py': FIXTURES / 'raising_node.py'})
    results = run_autograder(root)
    assert results['score'] == 0
    ahead, wander = results['tests']
    assert (ahead['score'], ahead['max_score'], ahead['status']) == (0, 2, 'failed')
    assert 'ZeroDivisionError: no valid beam to average' in ahead['output']
    assert 'scan_ahead.py' in ahead['output'] and str(root) not in ahead['output']
    assert (wander['score'], wander['max_score'], wander['status']) == (0, 3, 'failed')
    assert 'not submitted: no wanderbot.py in submission/' in wander['output']


def test_run_autograder_without_its_setup_still_writes_a_grade(autograder, tmp_path):
    root = gradescope_root(tmp_path, autograder, {})
    results = run_autograder(root, python=None)
    assert results['score'] == 0 and results['tests'] == []
    assert 'The autograder is not set up' in results['output']
