"""
A class graded with one command: the demo's four submissions, each run in its own process.

``ana`` hands in the project's own nodes, ``ben`` the lab's naive wall follower, ``cleo`` a
scan reader that puts an int in a float field and no wall follower, ``dev`` a wall follower
that does not compile and a scan reader that calls ``sys.exit`` (sim_bridge.commands.demo.CLASS).
The class table, class.csv, every student's report and the HTML pages (every link resolving) are
checked.
"""

import contextlib
import csv
import io
import json
import os
from pathlib import Path
import re
import shutil

import pytest

from sim_bridge.commands import grade
from sim_bridge.commands.demo import CLASS, CLASS_SCENARIOS, make_class
from sim_bridge.common.text import TEXT_LIMIT_BYTES
from sim_bridge.grading import batch
from sim_bridge.grading.class_batch import (
    ClassBatch, CSV_NAME, INDEX_NAME, STUDENTS_DIR, write_csv)
from sim_bridge.grading.html_report import linked_files
from sim_bridge.grading.scenario import load_scenarios

WORKSPACE = Path(__file__).resolve().parents[2]
SCENARIOS = [WORKSPACE / 'scenarios' / name for name in CLASS_SCENARIOS]
EXPECTED_TABLE = [
    ['student', 'marks (of 5)', 'task 1 (of 2)', 'task 4 (of 3)', 'scan_ahead',
     'wall_follow_box_cw', 'runs'],
    ['ana', '5', '2', '3', '1/1', '3/3', '4/4'],
    ['ben', '2', '2', '0', '1/1', '0/3 criteria failed', '1/4 criteria failed'],
    ['cleo', '0', '0', '0', '0/1 node error', '0/3 not submitted', '0/4 not submitted'],
    ['dev', '0', '0', '0', '0/1 node error', '0/3 error', '0/4 error'],
]
#: class.csv adds the marks of each point, and why it was lost, after the tasks' marks.
POINT_COLUMNS = ['task 1: prints the range ahead for each scan (of 1)',
                 'task 1: the range ahead printed right (capped as the node caps) (of 1)',
                 'task 4: loops the object in one direction (of 1)',
                 'task 4: keeps the wall at the distance it chose (of 1)',
                 'task 4: no collision (of 1)']


@pytest.fixture(scope='module')
def graded(tmp_path_factory):
    """Grade the class once through the command line; return (out folder, status, stdout)."""
    root = tmp_path_factory.mktemp('class')
    make_class(root / 'submissions', WORKSPACE)
    out = root / 'out'
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        status = grade.main([*map(str, SCENARIOS), '--submissions', str(root / 'submissions'),
                             '--out', str(out), '--jobs', '2', '--no-record', '--quiet'])
    return out, status, stdout.getvalue()


def test_the_class_table_is_printed_and_written_as_csv(graded):
    out, status, stdout = graded
    assert status == 1
    with open(out / CSV_NAME, newline='', encoding='utf-8') as file:
        rows = list(csv.reader(file))
    points = slice(4, 4 + len(POINT_COLUMNS))
    assert [row[:points.start] + row[points.stop:] for row in rows] == EXPECTED_TABLE
    assert rows[0][points] == POINT_COLUMNS
    ana, ben, cleo, _ = (dict(zip(POINT_COLUMNS, row[points])) for row in rows[1:])
    assert set(ana.values()) == {'1'}
    assert ben['task 4: no collision (of 1)'].startswith('0: ')
    assert 'collision(s) (wall_follow_box_cw/seed_1; lost in 3 of 3 runs)' in ben[
        'task 4: no collision (of 1)']
    assert cleo['task 1: prints the range ahead for each scan (of 1)'].startswith(
        "0: node error: node 'straight_ahead' raised AssertionError: The 'z' field")
    assert cleo['task 4: no collision (of 1)'].startswith(
        '0: not submitted: no wall_follow.py in cleo/ (found: scan_ahead.py; expected')
    for row in EXPECTED_TABLE:
        assert ' '.join(row) == ' '.join(next(line for line in stdout.splitlines()
                                              if line.startswith(row[0])).split())


def test_the_class_page_and_each_students_report_show_the_marks(graded):
    out, _, stdout = graded
    assert '  task 1: 2 marks, 1 for each of its 2 points, x the runs showing it' in \
        stdout.splitlines()
    assert ('  task 4: 3 marks, 1 for each of its 3 points, x the runs showing it, the '
            "starts of each student's direction (the one earning more)") in stdout.splitlines()
    index = (out / INDEX_NAME).read_text(encoding='utf-8')
    # The marks, a column per task, the runs in all; each scenario on the student's page.
    assert '<th>student</th><th>marks</th><th>task 1</th><th>task 4</th><th>runs</th>' in index
    assert '<td class="pass"><b>5/5</b></td>' in index  # ana
    assert '<td class="some"><b>2/5</b></td>' in index  # ben
    assert ('<td class="fail">0/3<span class="why">lost: loops the object in one direction: '
            in index)
    assert 'and 2 more points lost</span>' in index
    ben = json.loads((out / STUDENTS_DIR / 'ben' / grade.REPORT_NAME).read_text())['marks']
    assert (ben['total'], ben['max']) == (2.0, 5.0)
    assert [(task['task'], task['marks'], task['max'], task['runs'], task['passed'])
            for task in ben['tasks']] == [('1', 2.0, 2.0, 1, 1), ('4', 0.0, 3.0, 3, 0)]
    assert [point['point'] for point in ben['tasks'][1]['points'] if point['lost'] == 3] == [
        'loops the object in one direction', 'keeps the wall at the distance it chose',
        'no collision']
    page = (out / STUDENTS_DIR / 'ben' / grade.PAGE_NAME).read_text(encoding='utf-8')
    # The page opens with the marks, a row per point with why it was lost.
    assert page.index('<b>marks 2/5</b>') < page.index('runs passed</p>')
    assert '<td class="fail"><b>0/3</b></td>' in page
    # Beside each point, the rule it is judged by.
    assert re.search(r'<td>&nbsp;&nbsp;no collision<span class="why">[^<]*Move along walls '
                     r'without hitting them[^<]*</span></td><td class="fail">0/1</td>', page)


def test_each_student_has_a_report_with_the_reasons(graded):
    out, _, _ = graded
    reports = {student: json.loads((out / STUDENTS_DIR / student / grade.REPORT_NAME).read_text())
               for student in CLASS}
    assert [run['run'] for run in reports['ana']['runs']] == [
        'scan_ahead/seed_1', *(f'wall_follow_box_cw/seed_{seed}' for seed in (1, 2, 3))]
    cleo = {run['run']: run for run in reports['cleo']['runs']}
    assert cleo['wall_follow_box_cw/seed_2']['error'] == (
        'not submitted: no wall_follow.py in cleo/ (found: scan_ahead.py; expected '
        'scan_ahead.py, wall_follow.py or files named after them, at the top, in a folder, in '
        'scan_pkg/scan_pkg/ or in a zip)')
    [node_error] = cleo['scan_ahead/seed_1']['metrics']['node_errors']
    assert "The 'z' field must be of type 'float'" in node_error['error']
    dev = {run['run']: run for run in reports['dev']['runs']}
    assert 'SyntaxError' in dev['wall_follow_box_cw/seed_1']['error']
    [node_error] = dev['scan_ahead/seed_1']['metrics']['node_errors']
    assert 'SystemExit (sys.exit(3))' in node_error['error']
    ben = {run['run']: run for run in reports['ben']['runs']}
    assert ben['wall_follow_box_cw/seed_1']['metrics']['collisions'] > 0


def test_the_pages_link_only_files_that_exist(graded):
    out, _, _ = graded
    pages = [out / INDEX_NAME, *(out / STUDENTS_DIR / student / grade.PAGE_NAME
                                 for student in CLASS)]
    links = [link for page in pages for link in linked_files(page)]
    assert [link for link in links if not link.exists()] == []
    assert sum(link.name == 'trajectory.png' for link in links) >= 6
    assert {out / STUDENTS_DIR / student / grade.PAGE_NAME for student in CLASS} <= set(links)


def test_each_job_is_named_after_its_student_and_a_missing_file_is_not_run(tmp_path):
    batch = ClassBatch(load_scenarios(SCENARIOS), make_class(tmp_path / 'class', WORKSPACE),
                       tmp_path / 'out')
    assert [job.name for job in batch.jobs if job.name.startswith('cleo/')] == [
        'cleo/scan_ahead/seed_1']
    assert [report.run.name for student, report in batch.missing] == [
        f'wall_follow_box_cw/seed_{seed}' for seed in (1, 2, 3)]
    assert {student for student, _ in batch.missing} == {'cleo'}
    ana = [job for job in batch.jobs if job.name.startswith('ana/')]
    assert [job.out_dir for job in ana] == [
        tmp_path / 'out' / STUDENTS_DIR / 'ana' / job.run.name for job in ana]
    assert all(node.endswith('/ana/wall_follow.py') or node.endswith('/ana/scan_ahead.py')
               for job in ana for node in job.run.scenario.nodes)


def test_an_extra_task_without_marks_is_never_not_submitted(tmp_path):
    """The guide's closest-obstacle node is graded for those who hand it in, no one else."""
    scenarios = load_scenarios([*SCENARIOS, WORKSPACE / 'scenarios' / 'closest_obstacle.yaml'])
    submissions = make_class(tmp_path / 'class', WORKSPACE)
    shutil.copy(WORKSPACE / 'scan_pkg' / 'scan_pkg' / 'closest_obstacle.py',
                submissions / 'ana' / 'closest_obstacle.py')
    batch = ClassBatch(scenarios, submissions, tmp_path / 'out')
    extra = [job.name for job in batch.jobs if 'closest_obstacle' in job.name]
    assert extra == ['ana/closest_obstacle/seed_1']
    assert not [report for _, report in batch.missing
                if report.run.scenario.name == 'closest_obstacle']


def test_only_folders_are_students_and_an_out_folder_inside_the_class_is_none(tmp_path):
    submissions = make_class(tmp_path / 'class', WORKSPACE)
    (submissions / 'notes.txt').write_text('a file, no student')
    (submissions / '.git').mkdir()
    (submissions / 'results' / STUDENTS_DIR / 'ana').mkdir(parents=True)  # a graded --out
    batch = ClassBatch(load_scenarios(SCENARIOS), submissions, submissions / 'results')
    assert batch.students == sorted(CLASS)
    (submissions / 'grades' / '2026').mkdir(parents=True)
    batch = ClassBatch(load_scenarios(SCENARIOS), submissions, submissions / 'grades' / '2026')
    assert batch.students == sorted([*CLASS, 'results'])  # now an ordinary folder
    (submissions / STUDENTS_DIR).mkdir()  # --out is the class folder itself
    assert ClassBatch(load_scenarios(SCENARIOS), submissions, submissions).students == \
        sorted([*CLASS, 'grades', 'results'])


FIXTURES = Path(__file__).resolve().parent / 'fixtures'
SCAN_AHEAD = WORKSPACE / 'scan_pkg' / 'scan_pkg' / 'scan_ahead.py'
#: Folder names the file system allows: not UTF-8 (a Windows zip), the class's own outputs'
#: names, the TARGET syntax's ':'.
AWKWARD_NAMES = [os.fsdecode(b'Jos\xe9'), 'index.html', 'class.csv', 'col:on', 'new\nline']


@pytest.fixture(scope='module')
def awkward(tmp_path_factory):
    """
    Grade a class of awkward folders and errors twice (the second resumes).

    Return (class root, out folder, [(status, stdout, stderr) of each invocation]).
    """
    root = tmp_path_factory.mktemp('awkward')
    submissions = root / 'submissions'
    for name in AWKWARD_NAMES:
        (submissions / name).mkdir(parents=True)
        shutil.copyfile(SCAN_AHEAD, submissions / name / 'scan_ahead.py')
    for name, node in (('zoe', 'surrogate_error_node.py'), ('max', 'huge_error_node.py')):
        (submissions / name).mkdir()
        shutil.copyfile(FIXTURES / node, submissions / name / 'scan_ahead.py')
    scenario = root / 'scan_ahead.yaml'
    scenario.write_text('world: obstacles\nnodes: [scan_ahead]\nduration: 1.0\nseed: 1\n'
                        'criteria: [len(node_errors) == 0]\n')
    out = root / 'out'
    outputs = []
    for _ in range(2):
        stdout, stderr = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            status = grade.main([str(scenario), '--submissions', str(submissions),
                                 '--out', str(out), '--jobs', '2', '--no-record', '--no-plot'])
        outputs.append((status, stdout.getvalue(), stderr.getvalue()))
    return root, out, outputs


def test_awkward_folder_names_are_graded_under_their_names(awkward):
    root, out, outputs = awkward
    with open(out / CSV_NAME, newline='', encoding='utf-8') as file:
        rows = {row[0]: row[1:] for row in csv.reader(file)}
    for name in ('Jos\\xe9', 'index.html', 'class.csv', 'col:on', 'new\\nline'):
        assert rows[name] == ['1/1', '1/1'], name
    assert rows['zoe'] == rows['max'] == ['0/1 node error'] * 2
    links = linked_files(out / INDEX_NAME)
    assert len(links) == 7 and all(link.is_file() for link in links)
    assert out / STUDENTS_DIR / AWKWARD_NAMES[0] / grade.PAGE_NAME in links
    for status, stdout, stderr in outputs:
        assert status == 1
        assert 'Jos\\xe9' in stdout and 'Traceback' not in stderr
        assert 'new\\nline ' in stdout  # one row of the table


def test_error_texts_that_are_not_utf8_reach_every_report(awkward):
    _, out, _ = awkward
    zoe = out / STUDENTS_DIR / 'zoe'
    [run] = json.loads((zoe / grade.REPORT_NAME).read_text(encoding='utf-8'))['runs']
    assert 'cannot open map caf\\xe9.yaml' in run['metrics']['node_errors'][0]['error']
    assert 'cannot open map caf\\xe9.yaml' in (zoe / grade.PAGE_NAME).read_text(encoding='utf-8')
    result = json.loads((zoe / 'scan_ahead' / 'seed_1' / batch.RESULT_NAME).read_text())
    assert 'caf\\xe9' in result['report']['metrics']['node_errors'][0]['error']


def test_a_huge_error_is_cut_in_every_output(awkward):
    _, out, _ = awkward
    folder = out / STUDENTS_DIR / 'max'
    files = [folder / grade.REPORT_NAME, folder / grade.PAGE_NAME,
             folder / 'scan_ahead' / 'seed_1' / batch.RESULT_NAME,
             folder / 'scan_ahead' / 'seed_1' / 'metrics.json']
    for path in files:
        text = path.read_text(encoding='utf-8')
        assert path.stat().st_size < 8 * TEXT_LIMIT_BYTES, path
        assert re.search(r'\.\.\. \d+ bytes cut \.\.\.', text), path


def test_reports_carry_no_absolute_path_of_the_grader(awkward):
    root, out, _ = awkward
    files = [out / INDEX_NAME, out / CSV_NAME, *out.rglob(grade.REPORT_NAME),
             *out.rglob(grade.PAGE_NAME), *out.rglob(batch.RESULT_NAME)]
    for path in files:
        text = path.read_text(encoding='utf-8')
        for folder in (str(root), os.getcwd(), os.path.expanduser('~')):
            assert folder not in text, (path, folder)
    [run] = json.loads((out / STUDENTS_DIR / 'zoe' / grade.REPORT_NAME).read_text())['runs']
    assert run['nodes'] == ['zoe/scan_ahead.py']
    assert run['out_dir'] == f'{STUDENTS_DIR}/zoe/scan_ahead/seed_1'
    assert 'File "zoe/scan_ahead.py", line ' in run['metrics']['node_errors'][0]['traceback']


def test_a_second_invocation_says_it_reused_the_runs(awkward):
    _, out, outputs = awkward
    assert 'reused' not in outputs[0][1]
    assert 'note: 7 of 7 runs reused from an earlier invocation' in outputs[1][1]
    page = (out / STUDENTS_DIR / 'zoe' / grade.PAGE_NAME).read_text(encoding='utf-8')
    assert '7 of 7 runs reused from an earlier invocation' in page


def test_class_csv_cells_a_spreadsheet_would_run_as_formulas_are_text(tmp_path):
    """A student's folder named as a formula (CSV injection, OWASP) opens as its name."""
    hostile = ['=HYPERLINK("evil","click")', '+1+1', '-2+3+cmd', '@SUM(A1)', '\t=1+1']
    write_csv(tmp_path / CSV_NAME, [['student', 'marks'], *([name, '-0.5'] for name in hostile),
                                    ['ana', '1e-3']])
    with open(tmp_path / CSV_NAME, newline='', encoding='utf-8') as file:
        rows = list(csv.reader(file))
    assert [row[0] for row in rows[1:-1]] == ["'" + name for name in hostile]
    assert {row[1] for row in rows[1:]} == {'-0.5', '1e-3'}  # numbers stay numbers
    assert rows[-1][0] == 'ana'
