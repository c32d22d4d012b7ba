"""
Students gaming the motion points, graded end to end as a TA would mark them.

Node files in students' styles (``fixtures/motion``): wall followers that drive a metre and
park, raise or steer into the box; wanderbots that shuttle on a timer without reading the
lidar, stop for good at their second obstacle, or turn exactly 90 degrees on the clock. Each
is graded by the shipped scenarios (one seed of the wanderbot's room and of the box each way)
and must get the marks a TA gives it by the handout (the band beside each), with every point's
rule shown beside it on the student's page.
"""

import json
from pathlib import Path
import re

import pytest

from sim_bridge.commands import grade
from sim_bridge.grading.scenario import load_scenario

WORKSPACE = Path(__file__).resolve().parents[2]
FIXTURES = Path(__file__).parent / 'fixtures' / 'motion'
SCENARIOS = ['wanderbot', 'wall_follow_box_cw', 'wall_follow_box_ccw']
#: Each student's files, by the name the lab gives them.
CLASS = {
    'parks': {'wall_follow.py': 'parks_after_1m.py', 'wanderbot.py': 'timed_shuttle.py'},
    'raises': {'wall_follow.py': 'raises_after_1m.py', 'wanderbot.py': 'stops_for_good.py'},
    'crashes': {'wall_follow.py': 'crashes_after_1m.py', 'wanderbot.py': 'timed_90_turn.py'},
}
#: A TA's marks (low, high) by the handout, decided before grading: task 2, task 4.
TA_BANDS = {
    # Drives straight, collides; its turns come from a timer, not from what is ahead.
    ('parks', '2'): (0.0, 0.5),
    # Drove 1.2 m beside the box and parked: no loop, no wall followed.
    ('parks', '4'): (0.0, 0.0),
    # Stopped within 0.7 m once and turned; stopped for good at the next obstacle.
    ('raises', '2'): (0.0, 0.5),
    # Drove 1.2 m and raised: nothing followed.
    ('raises', '4'): (0.0, 0.0),
    # Everything the handout asks, but its turns are exactly 90 degrees, not more.
    ('crashes', '2'): (2.5, 2.5),
    # Drove 0.9 m and steered into the box.
    ('crashes', '4'): (0.0, 0.0),
}


@pytest.fixture(scope='module')
def graded(tmp_path_factory):
    """Grade the class on one seed of each scenario; return each student's report."""
    root = tmp_path_factory.mktemp('gaming')
    scenarios = root / 'scenarios'
    scenarios.mkdir()
    for name in SCENARIOS:
        source = WORKSPACE / 'scenarios' / f'{name}.yaml'
        seed = load_scenario(source).seeds[0]
        text = re.sub(r'^seeds?: .*$', f'seed: {seed}', source.read_text(), flags=re.MULTILINE)
        (scenarios / f'{name}.yaml').write_text(text)
    for student, files in CLASS.items():
        folder = root / 'submissions' / student
        folder.mkdir(parents=True)
        for name, fixture in files.items():
            (folder / name).write_text((FIXTURES / fixture).read_text())
    out = root / 'out'
    grade.main([str(scenarios), '--submissions', str(root / 'submissions'), '--out', str(out),
                '--no-record', '--no-plot', '--quiet', '--jobs', '2'])
    return {student: (json.loads((out / 'students' / student / 'report.json').read_text()),
                      (out / 'students' / student / 'report.html').read_text())
            for student in CLASS}


@pytest.mark.parametrize('student, task', sorted(TA_BANDS))
def test_a_gaming_node_gets_the_marks_a_ta_gives(graded, student, task):
    tasks = {entry['task']: entry for entry in graded[student][0]['marks']['tasks']}
    low, high = TA_BANDS[student, task]
    lost = {point['point']: point['why'] for point in tasks[task]['points'] if point['lost']}
    assert low <= tasks[task]['marks'] <= high, lost


def test_the_student_page_shows_each_points_rule_beside_it(graded):
    report, page = graded['crashes']
    for task in report['marks']['tasks']:
        for point in task['points']:
            assert point['rule'] and point['rule'].split('"')[1] in page, point
    assert 'measured at 92° or more' in page
