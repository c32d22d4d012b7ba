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
"""

import json
from pathlib import Path
import re

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
