"""
Tasks 1 and 3 graded as a TA would, for nodes written to game their printed-value points.

Each fixture node (``fixtures/printed/``, written in a student's style) says in its docstring
the marks a TA gives it by the handout, decided before grading: a node that dies after its
first scan, one that prints the rightmost beam (``ranges[0]``, a TurtleBot3 habit) as the
range ahead, one that hangs after five scans, a scan_around that dies after two of its five
lines, one that prints right values once a second, one that also prints a line of 12,000
numbers, and honest nodes that keep full marks. They
are graded with the grader's command line on the shipped scenarios, shortened to the drive
towards the cube.
"""

import json
from pathlib import Path
import re
import shutil

import jinja2
import pytest

from sim_bridge.commands import grade

WORKSPACE = Path(__file__).resolve().parents[2]
FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'printed'
#: student: ({node file: fixture}, {task: a TA's marks by the handout}).
CLASS = {
    'dies': ({'scan_ahead.py': 'dies_after_first_scan.py'}, {'1': 0.0}),
    'tb3': ({'scan_ahead.py': 'turtlebot_front_beam.py'}, {'1': 0.0}),
    'hangs': ({'scan_ahead.py': 'hangs_after_five_scans.py'}, {'1': 0.0}),
    'timer': ({'scan_ahead.py': 'once_a_second.py'}, {'1': 1.0}),
    'two_lines': ({'scan_around.py': 'regions_dies_after_two_lines.py'}, {'3': 0.0}),
    'long_line': ({'scan_ahead.py': 'long_line.py'}, {'1': 2.0}),
    'honest': ({'scan_ahead.py': 'middle_beam.py', 'scan_around.py': 'regions_one_line.py'},
               {'1': 2.0, '3': 2.0}),
}
#: The scenarios' drive up to the cube: 10 s of the 26 (100 scans).
DURATION_S = 10.0


def escaped(text):
    """Return ``text`` as the pages' templates write it (jinja2's autoescape)."""
    return jinja2.Environment(autoescape=True).from_string('{{ text }}').render(text=text)


@pytest.fixture(scope='module')
def reports(tmp_path_factory):
    """Grade the class on scan_ahead and scan_around; return each student's report (and page)."""
    root = tmp_path_factory.mktemp('printed')
    scenarios = root / 'scenarios'
    scenarios.mkdir()
    for name in ('scan_ahead', 'scan_around'):
        text = (WORKSPACE / 'scenarios' / f'{name}.yaml').read_text()
        text = re.sub(r'^duration: .*$', f'duration: {DURATION_S:g}', text, flags=re.MULTILINE)
        (scenarios / f'{name}.yaml').write_text(text)
    for student, (files, _) in CLASS.items():
        folder = root / 'submissions' / student
        folder.mkdir(parents=True)
        for name, fixture in files.items():
            shutil.copyfile(FIXTURES / fixture, folder / name)
    out = root / 'out'
    grade.main([str(scenarios), '--submissions', str(root / 'submissions'), '--out', str(out),
                '--jobs', '2', '--stall-timeout', '10', '--no-record', '--no-plot', '--quiet'])
    return {student: {**json.loads((out / 'students' / student / 'report.json').read_text()),
                      'page': (out / 'students' / student / 'report.html').read_text()}
            for student in CLASS}


def task(report, number):
    return next(task for task in report['marks']['tasks'] if task['task'] == number)


def lost(report, number):
    return {point['point']: point['why'] for point in task(report, number)['points']
            if point['lost']}


@pytest.mark.parametrize('student', list(CLASS))
def test_each_node_gets_the_marks_a_ta_gives(reports, student):
    for number, marks in CLASS[student][1].items():
        assert task(reports[student], number)['marks'] == pytest.approx(marks), (
            student, lost(reports[student], number))


def test_a_node_that_dies_after_its_first_scan_missed_every_scan_after_it(reports):
    why = lost(reports['dies'], '1')['prints the range ahead for each scan']
    assert re.search(r'\b99 of 100 scans\b', why), why
    assert 'stopped at t=0.' in why, why


def test_the_rightmost_beam_is_named_as_what_the_values_match(reports):
    for why in lost(reports['tb3'], '1').values():
        assert 'match beam 0 (angle -1.57 rad, the rightmost), not the beam ahead' in why, why


def test_a_scan_around_that_dies_after_two_lines_loses_both_points(reports):
    reasons = lost(reports['two_lines'], '3')
    assert len(reasons) == 2, reasons
    assert 'front-right, front-left, left never printed' in ' '.join(reasons.values())


def test_a_node_printing_once_a_second_loses_for_each_scan_only(reports):
    assert list(lost(reports['timer'], '1')) == ['prints the range ahead for each scan']


def test_each_point_states_its_rule_beside_it(reports):
    for point in task(reports['honest'], '1')['points'] + task(reports['honest'], '3')['points']:
        assert '0.06 m' in point['rule'] and 'scan' in point['rule'], point
        assert escaped(point['rule']) in reports['honest']['page']


def test_a_line_of_12000_numbers_is_scored_in_the_graders_time_not_blamed_on_the_node(reports):
    run = reports['long_line']['runs'][0]
    assert run['error'] is None and not run['metrics']['node_errors'], run['error']
    assert run['metrics']['printed']['range_ahead']['right'] >= 99
