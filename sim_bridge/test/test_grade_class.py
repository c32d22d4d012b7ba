"""
A class graded with one command: the demo's four submissions, each run in its own process.

``ana`` hands in the project's own nodes, ``ben`` the lab's naive wall follower, ``cleo`` a
scan reader that puts an int in a float field and no wall follower, ``dev`` a wall follower
that does not compile and a scan reader that calls ``sys.exit`` (sim_bridge.demo.CLASS). The
class table, class.csv, every student's report and the HTML pages (every link resolving) are
checked.
"""

import contextlib
import csv
import io
import json
from pathlib import Path

import pytest

from sim_bridge import grade
from sim_bridge.demo import CLASS, CLASS_SCENARIOS, make_class
from sim_bridge.grade_class import ClassBatch, CSV_NAME, INDEX_NAME
from sim_bridge.html_report import linked_files
from sim_bridge.scenario import load_scenarios

WORKSPACE = Path(__file__).resolve().parents[2]
SCENARIOS = [WORKSPACE / 'test' / 'scenarios' / name for name in CLASS_SCENARIOS]
EXPECTED_TABLE = [
    ['student', 'scan_ahead', 'wall_follow_box_cw', 'total'],
    ['ana', '1/1', '3/3', '4/4'],
    ['ben', '1/1', '0/3', '1/4'],
    ['cleo', '0/1', '0/3', '0/4'],
    ['dev', '0/1', '0/3', '0/4'],
]


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
        assert list(csv.reader(file)) == EXPECTED_TABLE
    for row in EXPECTED_TABLE:
        assert ' '.join(row) == ' '.join(next(line for line in stdout.splitlines()
                                              if line.startswith(row[0])).split())


def test_each_student_has_a_report_with_the_reasons(graded):
    out, _, _ = graded
    reports = {student: json.loads((out / student / grade.REPORT_NAME).read_text())
               for student in CLASS}
    assert [run['run'] for run in reports['ana']['runs']] == [
        'scan_ahead/seed_1', *(f'wall_follow_box_cw/seed_{seed}' for seed in (1, 2, 3))]
    cleo = {run['run']: run for run in reports['cleo']['runs']}
    assert cleo['wall_follow_box_cw/seed_2']['error'] == \
        'not submitted: no wall_follow.py in cleo/'
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
    pages = [out / INDEX_NAME, *(out / student / grade.PAGE_NAME for student in CLASS)]
    links = [link for page in pages for link in linked_files(page)]
    assert [link for link in links if not link.exists()] == []
    assert sum(link.name == 'trajectory.png' for link in links) >= 6
    assert {out / student / grade.PAGE_NAME for student in CLASS} <= set(links)


def test_each_job_is_named_after_its_student_and_a_missing_file_is_not_run(tmp_path):
    batch = ClassBatch(load_scenarios(SCENARIOS), make_class(tmp_path / 'class', WORKSPACE),
                       tmp_path / 'out')
    assert [job.name for job in batch.jobs if job.name.startswith('cleo/')] == [
        'cleo/scan_ahead/seed_1']
    assert [report.run.name for student, report in batch.missing] == [
        f'wall_follow_box_cw/seed_{seed}' for seed in (1, 2, 3)]
    assert {student for student, _ in batch.missing} == {'cleo'}
    ana = [job for job in batch.jobs if job.name.startswith('ana/')]
    assert [job.out_dir for job in ana] == [tmp_path / 'out' / 'ana' / job.run.name for job in ana]
    assert all(node.endswith('/ana/wall_follow.py') or node.endswith('/ana/scan_ahead.py')
               for job in ana for node in job.run.scenario.nodes)
