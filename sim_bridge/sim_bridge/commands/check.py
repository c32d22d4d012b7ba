"""
A student's check before handing in: their own nodes on the shipped scenarios, as the TA grades.

``./lab check [FOLDER]`` grades the node files in FOLDER (default: the current folder) on every
scenario the kit ships (``scenarios/``), exactly as the instructor's grader does
(:mod:`sim_bridge.commands.grade` with ``--submission FOLDER``: each node sandboxed, stepped on
simulated time), then prints which files it graded, each task's marks and, for each point it
lost, the words of the TA's page (the grader's table of runs is on the pages). It writes no
recording or plot; the report pages are in ``--out``. Exit status: 0 when every point was
earned, 1 when one was lost, 2 when the check could not run.
"""

import argparse
import contextlib
import io
import json
import os
from pathlib import Path
import sys
from typing import Any, Sequence

from sim_bridge.commands import grade
from sim_bridge.common.paths import output_folder, scenarios_dir
from sim_bridge.grading.marks import format_marks
from sim_bridge.grading.runs import REPORT_NAME


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Read the command line of ``./lab check``."""
    parser = argparse.ArgumentParser(prog='./lab check',
                                     description=__doc__.strip().split('\n')[0])
    parser.add_argument('folder', nargs='?', default='.', type=Path,
                        help='the folder of your node files (default: this folder)')
    parser.add_argument('--scenario', action='append', dest='scenarios', metavar='SCENARIO',
                        help='check on this scenario file only (repeatable; default: every '
                             'shipped scenario)')
    parser.add_argument('--out', type=output_folder, default=Path('out') / 'check',
                        help='folder of the report pages (default out/check)')
    parser.add_argument('--jobs', type=int, default=os.cpu_count() or 1,
                        help='runs at once (default: one per CPU)')
    return parser.parse_args(argv)


def marks_lines(marks: dict[str, Any]) -> list[str]:
    """Return the lines that say each task's marks and why each lost point was lost."""
    lines = [f"marks {format_marks(marks['total'])}/{format_marks(marks['max'])}"]
    for task in marks['tasks']:
        if task['max'] is None:  # graded, carrying no marks (the guide's closest_obstacle)
            lines.append(f"  {task['task']}: no marks")
            continue
        lines.append(f"  task {task['task']}: {format_marks(task['marks'])}/"
                     f"{format_marks(task['max'])}")
        for point in task['points']:
            if point['marks'] < point['max']:
                why = f": {point['why']}" if point['why'] else ''
                lines.append(f"    lost {format_marks(point['max'] - point['marks'])} of "
                             f"{format_marks(point['max'])}, {point['point']}{why}")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Check a student's folder; return 0 when every point was earned (see the module)."""
    args = parse_args(argv)
    if not args.folder.is_dir():
        print(f'error: {args.folder} is not a folder of node files', file=sys.stderr)
        return 2
    scenarios = args.scenarios or [str(scenarios_dir())]
    # The grader's table of runs is the TA's; the student gets its notes (which file was
    # graded) and the marks, unless there are no marks to give.
    graded = io.StringIO()
    with contextlib.redirect_stdout(graded):
        status = grade.main([*scenarios, '--submission', str(args.folder), '--out',
                             str(args.out), '--jobs', str(max(1, args.jobs)), '--no-record',
                             '--no-plot', '--quiet'])
    try:
        report = json.loads((args.out / REPORT_NAME).read_text(encoding='utf-8'))
    except (OSError, ValueError):
        report = {}
    marks = report.get('marks')
    if not marks:
        print(graded.getvalue(), end='')
        return status or 2
    notes = [line for line in graded.getvalue().splitlines() if line.startswith('note: ')]
    print('\n'.join([*notes, *marks_lines(marks)]))
    print(f"pages: {args.out / 'report.html'}")
    return 0 if marks['total'] >= marks['max'] else 1


if __name__ == '__main__':
    sys.exit(main())
