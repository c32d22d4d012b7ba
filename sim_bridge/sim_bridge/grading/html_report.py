r"""
Static HTML pages of grading results: a page of runs, and a class index of students.

The pages are opened from the disk in a browser: no network, no JavaScript. Every link and
image is relative to the page's folder and names a file that exists when the page is written
(except ``up``, the index a caller writes after its pages), so the whole output folder can be
moved or zipped. Run entries are the dicts of ``RunReport.as_dict()``
(:mod:`sim_bridge.grading.batch`) with an optional ``'log'`` key (path of the run's captured
output); paths in a run that are not absolute are relative to the ``root`` a page is given
(default: the current directory). Names, errors and tracebacks are untrusted text: always escaped,
and a text that is not valid UTF-8 (a lone surrogate) shows its bytes as ``\xNN``.
"""

from collections import Counter
from html.parser import HTMLParser
import json
import os
from pathlib import Path
from typing import Any, NamedTuple
from urllib.parse import quote, unquote_to_bytes, urlsplit

from jinja2 import Environment, FileSystemLoader, StrictUndefined
from sim_bridge.common.text import count_cell, format_measured, outcome, OUTCOME_LEGEND, printable
from sim_bridge.grading.marks import format_marks, TaskMarks, total as marks_total

#: The folder of the pages' templates (package data of sim_bridge).
TEMPLATE_DIR = Path(__file__).resolve().parent / 'templates'
#: The pages' templates, every value autoescaped.
TEMPLATES = Environment(loader=FileSystemLoader(TEMPLATE_DIR), autoescape=True,
                        undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                        keep_trailing_newline=True)
TEMPLATES.globals.update(marks_total=marks_total,
                         fraction=lambda earned, maximum:
                         f'{format_marks(earned)}/{format_marks(maximum)}')


class Link(NamedTuple):
    """A link's text and its URL relative to the page ('' when its file does not exist)."""

    href: str
    text: str


def _link(target: str | os.PathLike | None, folder: Path, text: str) -> Link:
    """Return the link to ``target`` from a page in ``folder``; no href when it is missing."""
    if target is None or not os.path.exists(target):
        return Link('', text)
    return Link(_href(target, folder), text)


def _href(target: str | os.PathLike, folder: Path) -> str:
    """Return the URL of ``target`` relative to ``folder`` (a folder's ends in /)."""
    # Bytes: a file name that is not UTF-8 is linked by its bytes, as the file system has it.
    url = quote(os.fsencode(Path(os.path.relpath(target, folder)).as_posix()))
    return url + '/' if os.path.isdir(target) else url


def _text(value: Any) -> str:
    """Return ``value`` as text: strings as they are, None as a dash, others as JSON."""
    if value is None:
        return '\u2014'
    return value if isinstance(value, str) else json.dumps(value, default=str)


def _page(path: Path, template: str, up: Path | None = None, **values: Any) -> Path:
    """Write the page of ``template`` with ``values`` at ``path`` (making its folder)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    html = TEMPLATES.get_template(template).render(
        up=_href(up, path.parent) if up else '', **values)
    path.write_text(printable(html), encoding='utf-8')
    return path


def _run_rows(run: dict[str, Any]) -> list[dict[str, str]]:
    """
    Return the table rows of one run, as grade prints them.

    Its error, node errors and criteria with measured values; its warnings (which fail
    nothing) are listed once for the page (:func:`_warnings`).
    """
    metrics = run['metrics'] or {}
    cells = []
    if run['error'] is not None:
        cells.append((f"error: {run['error']}", '', 'fail'))
    for node_error in metrics.get('node_errors', []):
        cells.append((f"node error: {node_error['node']}: {node_error['error']}", '', 'fail'))
    cells += [(result['criterion'], format_measured(result['criterion'], result['value']),
               'pass' if result['passed'] else 'fail') for result in run['criteria']]
    if not cells:
        cells.append(('(no criteria)', '', 'pass' if run['passed'] else 'fail'))
    return [{'criterion': criterion, 'shown': shown, 'verdict': verdict}
            for criterion, shown, verdict in cells]


def _run_view(index: int, run: dict[str, Any], folder: Path, root: Path) -> dict[str, Any]:
    """Return what one run's section shows: verdict, setup, plot, outputs, errors."""
    out_dir = root / run['out_dir']
    metrics = run['metrics'] or {}
    sim_time = metrics.get('sim_time_s')
    facts = [('scenario', run['scenario']), ('file', run['file']), ('world', run['world']),
             ('nodes', ', '.join(run['nodes'])), ('seed', run['seed']),
             ('duration', f"{run['duration_s']:g} s"
              + (f' ({sim_time:.3g} s simulated)' if isinstance(sim_time, (int, float)) else '')),
             ('params', run['params']), ('start', run['start']),
             ('wall time', f"{run['wall_time_s']:.1f} s"
              + (' (reused from an earlier invocation)' if run.get('reused') else ''))]
    video = out_dir / 'video.mp4'  # sim_bridge.media.video.VIDEO_NAME (grade --video)
    plot = out_dir / 'trajectory.png'
    outputs = [_link(out_dir / 'metrics.json', folder, 'metrics.json'),
               _link(out_dir / 'run', folder, 'recording run/'),
               _link(video, folder, 'video.mp4'),
               _link(root / run['log'] if run.get('log') else None, folder, 'log')]
    return {'index': index, 'name': run['run'], 'passed': run['passed'],
            'rows': _run_rows(run), 'error': run['error'], 'traceback': run['traceback'],
            'facts': [(key, _text(value)) for key, value in facts],
            'video': _link(video, folder, 'video.mp4'),
            'plot': _href(plot, folder) if plot.is_file() else '',
            'outputs': [output for output in outputs if output.href],
            'warnings': _warnings([run]),
            'node_errors': metrics.get('node_errors', [])}


def _warnings(runs: list[dict]) -> list[tuple[str, int]]:
    """Return the runs' warnings, each once with the number of runs it was in."""
    counts = Counter(warning for run in runs
                     for warning in dict.fromkeys((run['metrics'] or {}).get('warnings') or []))
    return list(counts.items())


def write_runs_page(path: Path, title: str, runs: list[dict], *, up: Path | None = None,
                    root: Path | None = None, notes: list[str] = (),
                    marks: list[TaskMarks] | None = None) -> Path:
    """
    Write one page of runs (a student's report, or one grading batch) and return its path.

    The page opens with the marks (``marks``, per task and point, with why marks were lost),
    and each task's scenarios (runs passed, the worst reason one failed), then a summary line,
    ``notes`` (e.g. runs reused from an earlier invocation), the runs' warnings (each once,
    with the number of runs it was in), the pass/fail table (a row per criterion of each run,
    the error of a run that did not complete) and a section per run with its plot and
    outputs. ``up`` is the index page to link back to;
    it is linked even if not written yet. Relative paths in ``runs`` are relative to ``root``.
    """
    root = Path(root) if root is not None else Path()
    return _page(path, 'runs.html', up, title=title, notes=list(notes),
                 scenarios={scenario: _count_cell([run for run in runs
                                                   if run['scenario'] == scenario])
                            for scenario in dict.fromkeys(run['scenario'] for run in runs)},
                 passed=sum(bool(run['passed']) for run in runs),
                 marked=[task for task in marks or [] if task.marks is not None],
                 warnings=_warnings(runs),
                 runs=[_run_view(index, run, path.parent, root)
                       for index, run in enumerate(runs)])


def _count_cell(runs: list[dict]) -> dict[str, str] | None:
    """Return a cell 'passed/total', why the others failed, green/amber/red; None if no runs."""
    if not runs:
        return None
    count, why = count_cell(runs)
    passed = sum(outcome(run) == 'passed' for run in runs)
    return {'count': count, 'why': why,
            'colour': 'pass' if passed == len(runs) else 'some' if passed else 'fail'}


def _task_cell(task: TaskMarks | None, runs: list[dict]) -> dict[str, Any] | None:
    """
    Return a class page's cell of one task of a student, None when it has no runs of it.

    Its marks and the first point lost (with why, and how many more were lost), and the
    direction marked; for a task without marks, its runs (:func:`_count_cell`).
    """
    if task is None or task.marks is None:
        return _count_cell(runs)
    lost = ([f'{point.point}: {point.why()}' for point in task.points if point.lost]
            or ([] if task.earned >= task.marks
                else [f'{task.passed} of {task.runs} runs passed']))
    return {'marks': (task.earned, task.marks),
            'lost': lost[0] if lost else '',
            'more': f'and {len(lost) - 1} more points lost' if len(lost) > 1 else '',
            'direction': (f'marked on the {task.direction} starts'
                          if task.direction and task.earned else '')}


def write_class_index(path: Path, title: str, students: dict[str, list[dict]],
                      scenarios: list[str], pages: dict[str, Path],
                      marks: dict[str, list[TaskMarks]] | None = None) -> Path:
    """
    Write the class index and return its path: a page a TA reads on a 1280 px screen.

    One row per student (sorted by name): the marks in all, then one column per task (with
    ``marks``, each student's; without, each scenario is a task): its marks, the first point
    lost and why, and the direction the student was marked on; a task without marks, and a
    student's runs in all, as 'passed/total' runs and the worst reason a run failed (see
    :data:`OUTCOME_LEGEND`, under the table, with each task's rule). Each scenario's runs are
    on the student's page, which the student's name links to (``pages[student]``) when it
    exists.
    """
    marks = marks or {}
    tasks = next(iter(marks.values()), [])
    columns = ([(task.title, task.scenarios) for task in tasks] if tasks
               else [(scenario, (scenario,)) for scenario in scenarios])
    rows = []
    for student in sorted(students, key=lambda name: (name.casefold(), name)):
        runs = students[student]
        mine = marks.get(student, [None] * len(columns))
        cells = [_task_cell(task, [run for run in runs if run['scenario'] in members])
                 for task, (_, members) in zip(mine, columns)]
        rows.append({'name': student, 'page': _link(pages.get(student), path.parent, student),
                     'cells': cells, 'runs': _count_cell(runs),
                     'total': marks_total(mine) if any(task and task.marks is not None
                                                       for task in mine) else None})
    marked = [task for task in tasks if task.marks is not None]
    return _page(path, 'class_index.html', title=title, students=rows,
                 columns=[name for name, _ in columns], marked=marked,
                 total=sum(len(runs) for runs in students.values()),
                 passed=sum(bool(run['passed']) for runs in students.values() for run in runs),
                 legend=OUTCOME_LEGEND)


class _Links(HTMLParser):
    """Collect the values of every ``href`` and ``src`` attribute of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.urls += [value for name, value in attrs if name in ('href', 'src') and value]


def linked_files(page: Path) -> list[Path]:
    """
    Return the files a page's links and images point at, resolved against the page's folder.

    In-page links (``#run-0``) are skipped. A link that is not relative to the page's folder
    (a URL with a scheme or host, or an absolute path) raises ValueError, since it would
    break when the folder is moved. Whether the files exist is for the caller to check.
    """
    parser = _Links()
    parser.feed(page.read_text(encoding='utf-8'))
    files = []
    for url in parser.urls:
        parts = urlsplit(url)
        if parts.scheme or parts.netloc or parts.path.startswith('/'):
            raise ValueError(f'{page}: link {url!r} is not relative to the page')
        if parts.path:
            files.append(page.parent / os.fsdecode(unquote_to_bytes(parts.path)))
    return files
