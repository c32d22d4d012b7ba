"""
Grade a whole class: every student's node files on every scenario, one table for the class.

``python -m sim_bridge.grade SCENARIO... --submissions DIR`` grades each folder of DIR as a
student's submission. A scenario's node (``wall_follow``) is replaced by the student's file of
the same name (``DIR/<student>/wall_follow.py``); a student without that file fails the
scenario's runs as "not submitted". Outputs below ``--out``: ``<student>/`` with each run's
outputs, ``report.json`` and ``report.html``; ``class.csv`` (a row per student, a column per
scenario: passed runs of total, then the total) and ``index.html``, the class's page.
"""

import csv
from pathlib import Path

from sim_bridge import html_report
from sim_bridge.grade import GradeJob, PAGE_NAME, REPORT_NAME, RunReport, write_report
from sim_bridge.scenario import Scenario, target_name

CSV_NAME = 'class.csv'
INDEX_NAME = 'index.html'


class ClassBatch:
    """The runs of a class: a job per student, scenario and seed, or a run not submitted."""

    def __init__(self, scenarios: list[Scenario], submissions: Path, out: Path) -> None:
        if not submissions.is_dir():
            raise ValueError(f'--submissions {submissions}: not a folder')
        self.students = sorted(folder.name for folder in submissions.iterdir()
                               if folder.is_dir() and not folder.name.startswith('.'))
        if not self.students:
            raise ValueError(f'--submissions {submissions}: no student folders in it')
        self.scenarios = scenarios
        self.out = out
        self.jobs: list[GradeJob] = []
        #: Each run's student, and the reports of runs whose node files are missing.
        self.student_of: dict[str, str] = {}
        self.missing: list[tuple[str, RunReport]] = []
        for student in self.students:
            for scenario in scenarios:
                files = {target_name(node): (submissions / student / f'{target_name(node)}.py')
                         for node in scenario.nodes}
                absent = [path.name for path in files.values() if not path.is_file()]
                graded = scenario
                for name, path in files.items():
                    graded = graded.with_node_override(f'{name}={path.resolve()}')
                for run in graded.runs():
                    job = GradeJob(run, out / student / run.name, f'{student}/{run.name}')
                    if absent:
                        self.missing.append((student, RunReport(
                            run, job.out_dir, [], None,
                            f"not submitted: no {', '.join(absent)} in {student}/", 0.0)))
                    else:
                        self.jobs.append(job)
                        self.student_of[str(job.out_dir)] = student

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

    def table(self, reports: list[RunReport]) -> list[list[str]]:
        """Return the class table: a header, then per student 'passed/total' per scenario."""
        rows = [['student', *(scenario.name for scenario in self.scenarios), 'total']]
        for student, runs in self.by_student(reports).items():
            cells = []
            for scenario in self.scenarios:
                mine = [report for report in runs if report.run.scenario.name == scenario.name]
                cells.append(f'{sum(report.passed for report in mine)}/{len(mine)}')
            rows.append([student, *cells, f'{sum(r.passed for r in runs)}/{len(runs)}'])
        return rows

    def write_outputs(self, reports: list[RunReport]) -> str:
        """Write every student's report and page, class.csv and index.html; return the table."""
        students = self.by_student(reports)
        index = self.out / INDEX_NAME
        pages = {}
        for student, runs in students.items():
            folder = self.out / student
            write_report(runs, folder / REPORT_NAME)
            pages[student] = html_report.write_runs_page(
                folder / PAGE_NAME, f'Grading report: {student}',
                [report.as_dict() for report in runs], up=index)
        rows = self.table(reports)
        with open(self.out / CSV_NAME, 'w', newline='', encoding='utf-8') as file:
            csv.writer(file).writerows(rows)
        html_report.write_class_index(
            index, 'Class grading report',
            {student: [report.as_dict() for report in runs] for student, runs in students.items()},
            [scenario.name for scenario in self.scenarios], pages)
        return format_rows(rows) + (f'\nclass: {self.out / CSV_NAME} and {index}; '
                                    f'each student: {self.out}/<student>/{PAGE_NAME}')


def format_rows(rows: list[list[str]]) -> str:
    """Return rows as an aligned text table: the first column left, the others right."""
    widths = [max(len(row[column]) for row in rows) for column in range(len(rows[0]))]
    lines = ['  '.join([row[0].ljust(widths[0])] + [cell.rjust(width) for cell, width
                                                    in zip(row[1:], widths[1:])])
             for row in rows]
    lines.insert(1, '-' * len(lines[0]))
    return '\n'.join(lines)
