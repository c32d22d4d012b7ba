"""
A class as a TA reads it (issue 32): the file meant, reasons in full, a column per task.

A 1280 px screen shows the class page; each student has their own legend.

The class here is graded up to its runs (:class:`ClassBatch` finds the files and fails the
missing ones); the runs themselves are given their reports, as a grading would, so the pages
are what a grading writes without simulating 54 runs.
"""

from html.parser import HTMLParser
from pathlib import Path

from sim_bridge.grading.class_batch import ClassBatch, INDEX_NAME, STUDENTS_DIR
from sim_bridge.grading.html_report import write_class_index, write_runs_page
from sim_bridge.grading.marks import task_marks
from sim_bridge.grading.runs import PAGE_NAME, REPORT_NAME, RunReport
from sim_bridge.grading.scenario import load_scenarios
from sim_bridge.grading.task_points import unearned_points

WORKSPACE = Path(__file__).resolve().parents[2]
SCENARIOS = load_scenarios([str(WORKSPACE / 'scenarios')])
FOLLOWER = """from rclpy.node import Node


class WallFollower(Node):
    def __init__(self):
        super().__init__('wall_follower')
"""
#: Files a student hands in that are none of the lab's nodes by any name.
OTHER_FILES = [f'{name}.py' for name in (
    'helpers_for_the_lab', 'geometry_tools_i_wrote', 'plotting_my_results',
    'constants_and_parameters', 'an_attempt_that_did_not_work', 'another_old_attempt')]


class Cells(HTMLParser):
    """The text of each table cell (th or td) of a page, by row."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[str]] = []
        self.cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == 'tr':
            self.rows.append([])
        elif tag in ('td', 'th'):
            self.cell = []

    def handle_endtag(self, tag):
        if tag in ('td', 'th') and self.cell is not None:
            self.rows[-1].append(' '.join(self.cell))
            self.cell = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell.append(data)


def cells(page: Path) -> list[list[str]]:
    parser = Cells()
    parser.feed(page.read_text(encoding='utf-8'))
    return parser.rows


def graded_class(tmp_path: Path) -> tuple[ClassBatch, str]:
    """Grade a class of two: ana's follower is wall_follower.py, ben hands in other files."""
    submissions = tmp_path / 'class'
    (submissions / 'ana').mkdir(parents=True)
    (submissions / 'ana' / 'wall_follower.py').write_text(FOLLOWER)
    (submissions / 'ben').mkdir()
    for name in OTHER_FILES:
        (submissions / 'ben' / name).write_text('# mine\n')
    batch = ClassBatch(SCENARIOS, submissions, tmp_path / 'out')
    reports = [RunReport(job.run, job.out_dir, [], None, 'stopped before it ran (a test)', 0.0)
               for job in batch.jobs]
    text, unwritten = batch.write_outputs(reports)
    assert not unwritten
    return batch, text


def test_a_follower_named_wall_follower_is_graded_as_wall_follow_and_said(tmp_path):
    batch, text = graded_class(tmp_path)
    graded = {job.run.scenario.name: job.run.scenario.nodes for job in batch.jobs}
    assert sorted(graded) == sorted(scenario.name for scenario in SCENARIOS
                                    if scenario.task_name == '4')
    assert all(nodes == (str(tmp_path / 'class' / 'ana' / 'wall_follower.py'),)
               for nodes in graded.values())
    said = 'graded wall_follower.py as wall_follow (its name)'
    assert f'note: ana: {said}' in text.splitlines()
    page = (tmp_path / 'out' / STUDENTS_DIR / 'ana' / PAGE_NAME).read_text(encoding='utf-8')
    assert said in page
    assert said in (tmp_path / 'out' / STUDENTS_DIR / 'ana' / REPORT_NAME).read_text()


def test_the_reason_on_every_page_names_the_files_found_in_full(tmp_path):
    graded_class(tmp_path)
    index = (tmp_path / 'out' / INDEX_NAME).read_text(encoding='utf-8')
    page = (tmp_path / 'out' / STUDENTS_DIR / 'ben' / PAGE_NAME).read_text(encoding='utf-8')
    for text in (index, page):
        for name in OTHER_FILES:
            assert name in text, name
        assert '...' not in text


def test_the_class_page_has_one_column_per_task(tmp_path):
    graded_class(tmp_path)
    rows = cells(tmp_path / 'out' / INDEX_NAME)
    header = rows[0]
    assert header == ['student', 'marks', 'task 1', 'task 2', 'task 3', 'task 4', 'extra',
                      'runs']
    assert len(rows) == 3 and all(len(row) == len(header) for row in rows)
    ben = next(row for row in rows if row[0] == 'ben')
    # Each task's cell: its mark and the first point lost, why, and how many more.
    assert ben[header.index('task 2')].startswith('0/3 lost: drives straight: not submitted: ')
    assert ben[header.index('task 2')].endswith('and 5 more points lost')
    assert ben[header.index('task 2')].count('lost:') == 1


def entries(scenarios, earned_in: str, out: Path) -> list[dict]:
    """Run entries of task 4 that earn every point in the ``earned_in`` direction only."""
    result = []
    for scenario in scenarios:
        earned = scenario.direction == earned_in
        for run in scenario.runs():
            entry = RunReport(run, out / run.name, [], None, 'replaced below', 0.0).as_dict()
            entry.update(passed=earned, error=None, points=[
                dict(point.as_dict(), earned=earned)
                for point in unearned_points(scenario.points, 'went the other way')])
            result.append(entry)
    return result


def test_each_student_is_marked_and_told_on_their_own_direction(tmp_path):
    follow = [scenario for scenario in SCENARIOS if scenario.task_name == '4']
    students = {'ana': entries(follow, 'clockwise', tmp_path),
                'ben': entries(follow, 'counterclockwise', tmp_path)}
    marks = {name: task_marks(follow, runs) for name, runs in students.items()}
    assert [marks[name][0].earned for name in students] == [3.0, 3.0]
    pages = {name: write_runs_page(tmp_path / name / PAGE_NAME, name, runs, marks=marks[name])
             for name, runs in students.items()}
    index = write_class_index(tmp_path / INDEX_NAME, 'class', students,
                              [scenario.name for scenario in follow], pages, marks)
    [legend] = [line for line in index.read_text(encoding='utf-8').splitlines()
                if line.startswith('<p>task 4: ')]
    assert 'clockwise' not in legend  # the class's rule: each student's direction counts
    rows = {row[0]: row for row in cells(index)[1:]}
    assert rows['ana'][2] == '3/3 marked on the clockwise starts'
    assert rows['ben'][2] == '3/3 marked on the counterclockwise starts'
    assert 'the clockwise starts' in pages['ana'].read_text(encoding='utf-8')
    assert 'the counterclockwise starts' in pages['ben'].read_text(encoding='utf-8')
