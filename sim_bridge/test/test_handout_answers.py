"""
The handout's four sample answers, graded by the handout's own points as a TA would.

The answers are read from the handout (``../shared/lab_handout.md``, beside the workspace or
one of its parents) when the test runs: the code between each ``CODE STARTS HERE`` and ``CODE
ENDS HERE`` line, its Markdown escapes undone, is the node file the handout names. Never copied
into the project. As pasted, the code is indented with no-break spaces and does not compile: the
grader's hint says what to replace, and the answers are then graded as a student who followed
it hands them in. They lose marks for their real faults only: the wanderbot collides at 1 m/s
and stays pinned, scan_around drops the last beam from the left region, the wall follower
measures the wall once (and circles away from the object for good). A careful student's wall
follower (clockwise, 0.7 m, ``examples/careful_wall_follow.py``) and wanderbot (stops within
0.7 m, turns 110-170 degrees, ``examples/careful_wanderbot.py``) get full marks.

The handout's own workspace: its ``scan_pkg`` made as ``ros2 pkg create --build-type
ament_python scan_pkg`` makes it, holding the four answers and their console scripts, built by
colcon beside a copy of sim_bridge (the kit's scan_pkg absent from the workspace); the kit's
runner runs the student's installed console script on simulated time.
"""

import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

import pytest

from sim_bridge.commands import grade
from sim_bridge.common.paths import examples_dir
from sim_bridge.grading.scenario import load_scenario
from sim_bridge.runner.targets import describe

WORKSPACE = Path(__file__).resolve().parents[2]
HANDOUT = next((folder / 'shared' / 'lab_handout.md' for folder in WORKSPACE.parents
                if (folder / 'shared' / 'lab_handout.md').is_file()), None)
pytestmark = pytest.mark.skipif(HANDOUT is None, reason='the handout (../shared/lab_handout.md) '
                                'is not beside this workspace')
#: The node file each of the handout's answers is, by the name of its code block.
NODE_FILES = {'SCAN AHEAD': 'scan_ahead.py', 'WANDERBOT': 'wanderbot.py',
              'SCAN AROUND': 'scan_around.py', 'WALL FOLLOWER': 'wall_follow.py'}
ANSWER = re.compile(r'^\*### (?P<name>[A-Z ]+) CODE STARTS HERE ###\*$(?P<code>.*?)'
                    r'^\*### (?P=name) CODE ENDS HERE ###\*$', re.MULTILINE | re.DOTALL)
#: One seed of each task's scenarios, and of the wall follower's box and cylinder each way.
GRADED = ['scan_ahead', 'wanderbot', 'scan_around', 'wall_follow_box_cw', 'wall_follow_box_ccw',
          'wall_follow_cylinder_cw', 'wall_follow_cylinder_ccw']
CAREFUL = {'wall_follow.py': examples_dir() / 'careful_wall_follow.py',
           'wanderbot.py': examples_dir() / 'careful_wanderbot.py'}


def handout_answers() -> dict[str, str]:
    """Return each answer's node file name and its code as the handout shows it."""
    text = HANDOUT.read_text(encoding='utf-8')
    return {NODE_FILES[found['name']]: re.sub(r'\\([\\_*#`\[\]])', r'\1',
                                              found['code']).strip('\n') + '\n'
            for found in ANSWER.finditer(text)}


@pytest.fixture(scope='module')
def marks(tmp_path_factory):
    """Grade the answers (student 'handout') and the careful student's; return their marks."""
    root = tmp_path_factory.mktemp('handout')
    scenarios = root / 'scenarios'
    scenarios.mkdir()
    for name in GRADED:
        source = WORKSPACE / 'scenarios' / f'{name}.yaml'
        seed = load_scenario(source).seeds[0]
        text = re.sub(r'^seeds?: .*$', f'seed: {seed}', source.read_text(), flags=re.MULTILINE)
        (scenarios / f'{name}.yaml').write_text(text)
    handout = root / 'submissions' / 'handout'
    handout.mkdir(parents=True)
    for name, code in handout_answers().items():
        (handout / name).write_text(code.replace('\u00a0', ' '), encoding='utf-8')
    careful = root / 'submissions' / 'careful'
    careful.mkdir()
    for name, source in CAREFUL.items():
        (careful / name).write_text(source.read_text())
    out = root / 'out'
    grade.main([str(scenarios), '--submissions', str(root / 'submissions'), '--out', str(out),
                '--no-record', '--no-plot', '--quiet'])
    return {student: {task['task']: task for task in json.loads(
        (out / 'students' / student / 'report.json').read_text())['marks']['tasks']}
        for student in ('handout', 'careful')}


#: ``ros2 pkg create --build-type ament_python scan_pkg --dependencies rclpy geometry_msgs
#: sensor_msgs`` (Jazzy's template): package.xml, setup.cfg, setup.py (with the handout's console
#: scripts added), resource/scan_pkg and scan_pkg/__init__.py.
STUDENT_PACKAGE_XML = """<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" \
schematypens="http://www.w3.org/2001/XMLSchema"?>
<package format="3">
  <name>scan_pkg</name>
  <version>0.0.0</version>
  <description>TODO: Package description</description>
  <maintainer email="student@todo.todo">student</maintainer>
  <license>TODO: License declaration</license>

  <depend>rclpy</depend>
  <depend>geometry_msgs</depend>
  <depend>sensor_msgs</depend>

  <test_depend>ament_copyright</test_depend>
  <test_depend>ament_flake8</test_depend>
  <test_depend>ament_pep257</test_depend>
  <test_depend>python3-pytest</test_depend>

  <export>
    <build_type>ament_python</build_type>
  </export>
</package>
"""
STUDENT_SETUP_CFG = """[develop]
script_dir=$base/lib/scan_pkg
[install]
install_scripts=$base/lib/scan_pkg
"""
STUDENT_SETUP_PY = """from setuptools import find_packages, setup

package_name = 'scan_pkg'

setup(
    name=package_name,
    version='0.0.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages',
            ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='student',
    maintainer_email='student@todo.todo',
    description='TODO: Package description',
    license='TODO: License declaration',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'scan_ahead = scan_pkg.scan_ahead:main',
            'wanderbot = scan_pkg.wanderbot:main',
            'scan_around = scan_pkg.scan_around:main',
            'wall_follow = scan_pkg.wall_follow:main',
        ],
    },
)
"""
COLCON = Path(sys.executable).parent / 'colcon'
#: ``python -m sim_bridge.run`` in a Python without the kit's scan_pkg, as in the student's
#: workspace: an editable install of it (this venv's) would lend its modules to any scan_pkg.
RUN_WITHOUT_KITS_SCAN_PKG = (
    'import runpy, sys\n'
    "kits = '__editable___scan_pkg'\n"
    'sys.meta_path[:] = [finder for finder in sys.meta_path\n'
    "                    if not getattr(finder, '__module__', '').startswith(kits)]\n"
    "runpy.run_module('sim_bridge.run', run_name='__main__', alter_sys=True)\n")


def make_student_package(folder: Path) -> None:
    """Write the handout's scan_pkg in ``folder`` as ros2 pkg create and the handout make it."""
    (folder / 'resource').mkdir(parents=True)
    (folder / 'resource' / 'scan_pkg').write_text('')
    (folder / 'scan_pkg').mkdir()
    (folder / 'scan_pkg' / '__init__.py').write_text('')
    for name, text in (('package.xml', STUDENT_PACKAGE_XML), ('setup.cfg', STUDENT_SETUP_CFG),
                       ('setup.py', STUDENT_SETUP_PY)):
        (folder / name).write_text(text)
    for name, code in handout_answers().items():
        (folder / 'scan_pkg' / name).write_text(code.replace('\u00a0', ' '), encoding='utf-8')


def lost(task):
    return {point['point']: point['why'] for point in task['points'] if point['lost']}


def test_the_handout_holds_four_answers_that_as_pasted_get_the_hint_to_replace_its_spaces():
    answers = handout_answers()
    assert sorted(answers) == sorted(NODE_FILES.values())
    for name, code in answers.items():
        with pytest.raises(SyntaxError) as raised:
            compile(code, name, 'exec')
        assert 'holds a no-break space (U+00A0)' in describe(raised.value)
        assert 'replace every one in the file with a space' in describe(raised.value)


def test_the_handout_scan_ahead_earns_both_points_of_task_1(marks):
    assert marks['handout']['1']['marks'] == 2.0, lost(marks['handout']['1'])


def test_the_handout_wanderbot_that_crashes_at_1_m_s_and_stays_pinned_gets_a_tas_0_to_1(marks):
    # At 1 m/s, turning only while its one beam sees the obstacle, it hits something within
    # its first few turns and stays pinned there for most of the run: not wandering.
    task = marks['handout']['2']
    assert task['marks'] <= 1.0, lost(task)
    assert 'stuck for most of the run' in lost(task)['drives straight']
    assert 'collision' in lost(task)['no collision']


def test_the_handout_scan_around_prints_five_labelled_lines_and_loses_its_dropped_beam(marks):
    task = marks['handout']['3']
    assert task['marks'] == 1.0
    assert list(lost(task)) == ['the five region minima printed right (capped as the node caps)']
    assert 'left printed 10' in lost(task)[
        'the five region minima printed right (capped as the node caps)']


def test_the_handout_wall_follower_that_measures_the_wall_once_loops_nothing(marks):
    # It keeps its first reading of the wall and drives circles beside the box: a TA's 0.
    task = marks['handout']['4']
    assert task['marks'] == 0.0
    assert 'no full loop' in lost(task)['loops the object in one direction']
    assert 'not following it' in lost(task)['no collision']


def test_a_careful_one_direction_follower_at_0_7_m_gets_full_marks(marks):
    task = marks['careful']['4']
    assert task['direction'] == 'clockwise'
    assert task['marks'] == 3.0, lost(task)


def test_a_careful_wanderbot_that_stops_turns_and_never_collides_gets_full_marks(marks):
    task = marks['careful']['2']
    assert task['marks'] == 3.0, lost(task)


@pytest.fixture(scope='module')
def student_workspace(tmp_path_factory) -> Path:
    """Build the student's workspace: src/sim_bridge (the kit's) and src/scan_pkg (their own)."""
    if not COLCON.is_file():
        pytest.skip('colcon is not installed beside this Python')
    root = tmp_path_factory.mktemp('student_workspace')
    shutil.copytree(WORKSPACE / 'sim_bridge', root / 'src' / 'sim_bridge',
                    ignore=shutil.ignore_patterns('__pycache__', '*.egg-info'))
    make_student_package(root / 'src' / 'scan_pkg')
    build = subprocess.run(
        [str(COLCON), '--log-base', 'log', 'build', '--build-base', 'build', '--install-base',
         'install'], cwd=root, capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stdout + build.stderr
    return root


def test_the_handouts_scan_pkg_builds_beside_sim_bridge_and_its_own_node_runs(
        student_workspace):
    install = student_workspace / 'install'
    # What sourcing install/setup.bash puts first: the workspace's packages, the student's
    # scan_pkg (taking the kit's name) with them.
    [student] = install.glob('scan_pkg/lib/python*/site-packages')
    [kit] = install.glob('sim_bridge/lib/python*/site-packages')
    python_path = [str(student), str(kit), *filter(None, [os.environ.get('PYTHONPATH')])]
    prefixes = [str(install / 'scan_pkg'), str(install / 'sim_bridge')]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(python_path),
               AMENT_PREFIX_PATH=os.pathsep.join(prefixes))
    out = student_workspace / 'run_out'
    run = subprocess.run(
        [sys.executable, '-c', RUN_WITHOUT_KITS_SCAN_PKG, '--world', 'obstacles', '--node',
         'scan_ahead',
         '--duration', '2', '--out', str(out), '--no-record', '--no-plot', '--quiet'],
        cwd=student_workspace, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert json.loads((out / 'metrics.json').read_text())['node_errors'] == []
    texts = [json.loads(line).get('text', '') for line in
             (out / 'log.jsonl').read_text().splitlines()]
    ranges = [text for text in texts if text.startswith('Range ahead: ')]
    # The handout's own words (str() of the reading), not the kit's answer ('1.23 m').
    assert ranges and all(re.fullmatch(r'Range ahead: \d+\.\d{3,}', text) for text in ranges), \
        texts[:5]


def test_lab_check_in_the_students_built_workspace_grades_their_sources_as_the_ta_page_says(
        student_workspace):
    # ``./lab check ~/ros2_ws`` after ``colcon build``: the copies colcon put in build/ and
    # install/ are not the student's files; src/scan_pkg/scan_pkg's are, and are graded.
    out = student_workspace / 'check_out'
    check = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.commands.check', str(student_workspace),
         '--scenario', str(WORKSPACE / 'scenarios' / 'scan_ahead.yaml'),
         '--scenario', str(WORKSPACE / 'scenarios' / 'scan_around.yaml'), '--out', str(out)],
        capture_output=True, text=True, timeout=600)
    assert check.returncode == 1, check.stdout + check.stderr  # a point lost
    lines = check.stdout.splitlines()
    for node in ('scan_ahead', 'scan_around'):
        assert f'note: {node}.py: graded src/scan_pkg/scan_pkg/{node}.py' in lines, lines
    assert '  task 1: 2/2' in lines and '  task 3: 1/2' in lines, lines
    # The lost point in the words of the TA's page (the student's report.json).
    [task_3] = [task for task in json.loads((out / 'report.json').read_text())['marks']['tasks']
                if task['task'] == '3']
    [(point, why)] = lost(task_3).items()
    assert f'    lost 1 of 1, {point}: {why}' in lines, lines
