"""
Grade a whole class: every student's node files on every scenario, one table for the class.

``python -m sim_bridge.grade SCENARIO... --submissions DIR`` grades each folder of DIR as a
student's submission. A scenario's node (``wall_follow``) is replaced by the student's file of
the same name (``DIR/<student>/wall_follow.py``); a student without that file fails the
scenario's runs as "not submitted". Any folder name the file system allows is a student's
name (``col:on``, ``index.html``, bytes that are not UTF-8). Outputs below ``--out``:
``class.csv`` (a row per student, a column per scenario: passed runs of total and why the
others failed, then the runs in all and, when the scenarios carry marks
(:mod:`sim_bridge.grading.marks`), the marks per task and in all) and ``index.html``, the class's
page; ``students/<student>/`` with each run's outputs, ``report.json`` and ``report.html``.
Without namespaces, the class's folder and the outputs are closed to the runs.
"""

import csv
import os
from pathlib import Path
import re
from typing import NamedTuple, Sequence

from sim_bridge.common.console import text_table
from sim_bridge.common.text import count_cell, one_line, OUTCOME_LEGEND, PathNames, printable
from sim_bridge.grading import html_report
from sim_bridge.grading.isolate import format_bytes
from sim_bridge.grading.marks import format_marks, task_marks, TaskMarks, total
from sim_bridge.grading.runs import (
    GradeJob, PAGE_NAME, REPORT_NAME, reuse_notes, RunReport, write_outputs, write_report)
from sim_bridge.grading.scenario import Scenario
from sim_bridge.grading.submission_files import (
    find_node_files, MAX_FILE_BYTES, missing_text)
from sim_bridge.runner.boundary.outside import sandbox
from sim_bridge.runner.boundary.outside.sandbox_host import close_to_runs
from sim_bridge.runner.targets import target_name

CSV_NAME = 'class.csv'
#: What a spreadsheet reads as the start of a formula, and a number it reads as a number.
FORMULA_STARTS = ('=', '+', '-', '@', '\t', '\r')
PLAIN_NUMBER = re.compile(r'[-+]?[0-9]+(\.[0-9]+)?([eE][-+]?[0-9]+)?')
INDEX_NAME = 'index.html'
#: The folder of ``--out`` holding a folder per student: no student's name can collide with
#: the class's own outputs.
STUDENTS_DIR = 'students'
#: The folder of a submission's outputs its zips are unpacked in.
UNPACKED_DIR = '.unpacked'


class ClassBatch:
    """The runs of a class: a job per student, scenario and seed, or a run not submitted."""

    def __init__(self, scenarios: list[Scenario], submissions: Path, out: Path) -> None:
        if not submissions.is_dir():
            raise ValueError(f'--submissions {submissions}: not a folder')
        # --out inside the class folder (class/results), or the class folder itself (its
        # students/), holds the grader's outputs, no student.
        out_path, ours = out.resolve(), (out / STUDENTS_DIR).resolve()
        self.students = sorted(folder.name for folder in submissions.iterdir()
                               if folder.is_dir() and not folder.name.startswith('.')
                               and not out_path.is_relative_to(folder.resolve())
                               and folder.resolve() != ours)
        if not self.students:
            raise ValueError(f'--submissions {submissions}: no student folders in it')
        self.scenarios = scenarios
        self.out = out
        self.jobs: list[GradeJob] = []
        #: Each run's student, the reports of runs whose node files are missing, and what
        #: each student's report says of the files graded (graded wall_follower.py as ...).
        self.student_of: dict[str, str] = {}
        self.missing: list[tuple[str, RunReport]] = []
        self.file_notes: dict[str, list[str]] = {}
        for student in self.students:
            runs = submission_runs(scenarios, self.source_folder(submissions / student),
                                   self.folder(student), student)
            self.jobs += runs.jobs
            self.missing += [(student, report) for report in runs.missing]
            self.file_notes[student] = runs.notes
            self.student_of.update({str(job.out_dir): student for job in runs.jobs})
        close_to_students_runs([submissions, out])

    def source_folder(self, folder: Path) -> Path:
        """
        Return the folder to run a student's files from: ``folder``, or a link to it.

        rclpy's logging refuses a source file path that is not UTF-8 (a folder unzipped from
        a Windows export): such a folder is run through a link in ``students/.sources/``,
        named as the reports show it (hidden: no student's folder).
        """
        if printable(folder.name) == folder.name:
            return folder.resolve()
        link = self.out / STUDENTS_DIR / '.sources' / printable(folder.name)
        link.parent.mkdir(parents=True, exist_ok=True)
        if link.is_symlink():
            link.unlink()
        link.symlink_to(folder.resolve(), target_is_directory=True)
        return Path(os.path.abspath(link))

    def folder(self, student: str) -> Path:
        """Return the output folder of ``student``."""
        return self.out / STUDENTS_DIR / student

    def by_student(self, reports: list[RunReport]) -> dict[str, list[RunReport]]:
        """Return each student's reports (of :attr:`jobs`, plus the missing), scenario order."""
        order = {scenario.name: index for index, scenario in enumerate(self.scenarios)}
        students: dict[str, list[RunReport]] = {student: [] for student in self.students}
        for job, report in zip(self.jobs, reports):
            students[self.student_of[str(job.out_dir)]].append(report)
        for student, report in self.missing:
            students[student].append(report)
        for runs in students.values():
            runs.sort(key=lambda report: (order[report.run.scenario.name], report.run.seed))
        return students

    def marks(self, entries: dict[str, list[dict]]) -> dict[str, list[TaskMarks]]:
        """Return each student's marks per task from their run entries."""
        return {student: task_marks(self.scenarios, runs) for student, runs in entries.items()}

    def table(self, entries: dict[str, list[dict]], *,
              points: bool = False) -> list[list[str]]:
        """
        Return the class table: a header, then per student the marks, then the runs.

        ``entries`` are each student's run entries (``RunReport.as_dict``). When the scenarios
        carry marks, the total (``marks (of 10)``) and a column per task with marks (``task 1
        (of 2)``) come first; with ``points``, a column per point of each task marked by the
        handout's points (``task 2: no collision (of 0.5)``), its marks and, when lost, why
        (``0: 1 collision(s)``). Then a cell per scenario, 'passed/total' runs followed by the
        worst reason of a failed one (``0/3 not submitted``, see :data:`OUTCOME_LEGEND`), and
        the runs in all.
        """
        marks = self.marks(entries)
        marked = [task for task in task_marks(self.scenarios, []) if task.marks is not None]
        _, maximum = total(marked)
        header = [*([f'marks (of {format_marks(maximum)})'] if marked else []),
                  *(f'{task.title} (of {format_marks(task.marks)})' for task in marked)]
        students = {student: [task for task in marks[student] if task.marks is not None]
                    for student in entries}
        if points:
            header += [f'{task.title}: {point.point} (of {format_marks(point.marks)})'
                       for task in next(iter(students.values()), []) for point in task.points]
        rows = [['student', *header, *(scenario.name for scenario in self.scenarios), 'runs']]
        for student, runs in entries.items():
            tasks = students[student]
            cells = [*([format_marks(total(tasks)[0])] if tasks else []),
                     *(format_marks(task.earned) for task in tasks)]
            if points:
                cells += [format_marks(point.earned) + (f': {point.why()}' if point.lost else '')
                          for task in tasks for point in task.points]
            cells += [' '.join(filter(None, count_cell(
                [run for run in runs if run['scenario'] == scenario.name])))
                for scenario in self.scenarios]
            rows.append([one_line(student), *cells, ' '.join(filter(None, count_cell(runs)))])
        return rows

    def write_outputs(self, reports: list[RunReport], names: PathNames | None = None,
                      notes: Sequence[str] = ()) -> tuple[str, list[Path]]:
        """
        Write every student's report and page, class.csv and index.html.

        ``notes`` come first in every report (how the runs were isolated, when not fully).

        Each file is written on its own: one that cannot be written (named on stderr) stops
        no other. Return the table with where the outputs are, and the files not written.
        """
        students = self.by_student(reports)
        entries = {student: [report.as_dict(names) for report in runs]
                   for student, runs in students.items()}
        marks = self.marks(entries)
        index = self.out / INDEX_NAME
        pages = {student: self.folder(student) / PAGE_NAME for student in students}
        notes = [*notes, *reuse_notes(reports, self.out / STUDENTS_DIR)]
        writers = {}
        for student, runs in students.items():
            mine = [*notes, *self.file_notes[student]]
            writers[self.folder(student) / REPORT_NAME] = (
                lambda path, runs=runs, student=student, mine=mine: write_report(
                    runs, path, names=names, notes=mine, marks=marks[student]))
            writers[pages[student]] = (
                lambda path, student=student, mine=mine: html_report.write_runs_page(
                    path, f'Grading report: {student}', entries[student], up=index,
                    root=self.out, notes=mine, marks=marks[student]))
        rows = self.table(entries)
        with_points = self.table(entries, points=True)
        writers[self.out / CSV_NAME] = lambda path: write_csv(path, with_points)
        writers[index] = lambda path: html_report.write_class_index(
            path, 'Class grading report', entries,
            [scenario.name for scenario in self.scenarios],
            {student: page for student, page in pages.items() if page.is_file()}, marks)
        unwritten = write_outputs(writers)
        legend = [f'  {name}: {text}' for name, text in OUTCOME_LEGEND.items()]
        legend += [f'  {task.rule(own=False)}' for task in next(iter(marks.values()), [])
                   if task.marks is not None]
        lines = [format_rows(rows), *legend, *(f'note: {note}' for note in notes),
                 *(f'note: {printable(student)}: {note}'
                   for student, mine in self.file_notes.items() for note in mine),
                 f'class: {printable(os.fspath(self.out / CSV_NAME))} and '
                 f'{printable(os.fspath(index))}; each student: '
                 f'{printable(os.fspath(self.out / STUDENTS_DIR))}/<student>/{PAGE_NAME}']
        if unwritten:
            lines.append(f'{len(unwritten)} files not written (see above): '
                         + ', '.join(printable(os.fspath(path)) for path in unwritten))
        return '\n'.join(lines), unwritten


class SubmissionRuns(NamedTuple):
    """One submission's runs: the jobs to run, the failed runs of missing files, its notes."""

    jobs: list[GradeJob]
    missing: list[RunReport]
    #: What its reports say of the files graded ('graded wall_follower.py as wall_follow').
    notes: list[str]


def close_to_students_runs(folders: Sequence[Path]) -> None:
    """
    Close a class's ``folders`` (its submissions, the outputs) to the runs without namespaces.

    A run's uid alone (PARTLY sandboxed) reads what any user may: a classmate's node file, the
    outputs of earlier runs. A run reads its own files from its sandbox's copy, none of these.
    """
    if sandbox.isolation_mode().kind == 'uid':
        for folder in folders:
            folder.mkdir(parents=True, exist_ok=True)
        close_to_runs([str(folder) for folder in folders])


def submission_runs(scenarios: list[Scenario], source: Path, out: Path,
                    name: str) -> SubmissionRuns:
    """
    Return the runs of one submission: the jobs to run, the failed runs of missing files.

    Each scenario's node is replaced by the student's file of the same name
    (``wall_follow`` by ``wall_follow.py``), or the one file meant for it, found in the folder
    ``source`` as students hand it in (:func:`sim_bridge.submission_files.find_node_files`: at
    the top, in a folder, in ``scan_pkg/scan_pkg/``, in a zip, which is unpacked below ``out``;
    ``wall_follower.py``, a file whose node is so named, a ``setup.py`` entry point); a
    scenario with a file missing is not run and its runs fail as ``not submitted: no
    wall_follow.py in <name>/ (found: ...; expected ...)``, unless the scenario carries no
    marks (an extra task the instructor did not ask for): then the student simply has no runs
    of it (``-`` in the class table). Outputs go to ``out/<scenario>/seed_<n>``; the progress
    calls a run ``<name>/<run>``.
    """
    wanted = list(dict.fromkeys(f'{target_name(node)}.py' for scenario in scenarios
                                for node in scenario.nodes))
    found = find_node_files(source, wanted, out / UNPACKED_DIR)
    jobs, missing = [], []
    for scenario in scenarios:
        files = {target_name(node): found.files.get(f'{target_name(node)}.py')
                 for node in scenario.nodes}
        absent = [f'{node}.py' for node, path in files.items() if path is None]
        if absent and scenario.marks is None:
            continue
        why_not = ('not submitted: ' + missing_text(absent, found, wanted, name) if absent
                   else oversized([path for path in files.values() if path is not None]))
        graded = scenario
        for node, path in files.items():
            if path is not None:
                # An existing file is taken as a file whatever its path holds (targets).
                graded = graded.with_node_override(f'{node}={os.path.abspath(path)}')
        for run in graded.runs():
            job = GradeJob(run, out / run.name, f'{name}/{run.name}')
            if why_not:
                missing.append(RunReport(run, job.out_dir, [], None, why_not, 0.0))
            else:
                jobs.append(job)
    return SubmissionRuns(jobs, missing, found.notes)


def oversized(files: list[Path]) -> str | None:
    """
    Return why one of a submission's node ``files`` is too big to run, in one line, or None.

    Sizes are checked before anything is read: a file over MAX_FILE_BYTES (a sparse file of
    gigabytes) is never read by the grader.
    """
    for path in files:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            return (f'node file too big: {path.name} is {format_bytes(size)}, over the '
                    f'{format_bytes(MAX_FILE_BYTES)} a node file may be')
    return None


def spreadsheet_text(field: str) -> str:
    """
    Return ``field`` as a spreadsheet shows it as text, never as a formula.

    A cell that begins with ``= + - @``, a tab or a carriage return is read as a formula (a
    student's folder named ``=HYPERLINK(...)``): it gets a leading ``'``, as OWASP's CSV
    injection page advises. A plain number (``-0.5``) stays a number.
    """
    if field.startswith(FORMULA_STARTS) and not PLAIN_NUMBER.fullmatch(field):
        return "'" + field
    return field


def write_csv(path: Path, rows: list[list[str]]) -> None:
    """Write ``rows`` as a CSV file (UTF-8), every cell text or a number (spreadsheet_text)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, 'w', newline='', encoding='utf-8') as file:
        csv.writer(file).writerows([spreadsheet_text(str(field)) for field in row]
                                   for row in rows)


def format_rows(rows: list[list[str]]) -> str:
    """Return rows as an aligned text table: the first row the header, the first column left."""
    return text_table(rows[0], rows[1:], right=range(1, len(rows[0])))
