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
from html import escape
from html.parser import HTMLParser
import json
import os
from pathlib import Path
from typing import Any, Sequence
from urllib.parse import quote, unquote_to_bytes, urlsplit

from sim_bridge.common.text import count_cell, format_measured, outcome, OUTCOME_LEGEND, printable
from sim_bridge.grading.marks import format_marks, TaskMarks, total as marks_total

STYLE = """
body { font-family: sans-serif; margin: 2em; max-width: 70em; }
table { border-collapse: collapse; margin: 1em 0; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: left; }
th { background: #eee; }
.pass { background: #d7f5d7; color: #145214; }
.fail { background: #f9d6d5; color: #8a1212; }
.some, .warn { background: #fde9c4; color: #7a4a00; }
td, p, li { overflow-wrap: anywhere; }
pre { background: #f4f4f4; padding: 0.6em; white-space: pre-wrap; overflow-wrap: anywhere; }
.why { display: block; font-size: 85%; }
img, video { max-width: min(100%, 48em); border: 1px solid #ccc; }
"""


def _link(target: str | os.PathLike | None, folder: Path, text: str) -> str:
    """Return an ``<a>`` to ``target`` relative to ``folder``, or '' when it does not exist."""
    if target is None or not os.path.exists(target):
        return ''
    return f'<a href="{_href(target, folder)}">{escape(text)}</a>'


def _href(target: str | os.PathLike, folder: Path) -> str:
    """Return the URL of ``target`` relative to ``folder`` (a folder's ends in /), escaped."""
    # Bytes: a file name that is not UTF-8 is linked by its bytes, as the file system has it.
    url = quote(os.fsencode(Path(os.path.relpath(target, folder)).as_posix()))
    return escape(url + '/' if os.path.isdir(target) else url)


def _text(value: Any) -> str:
    """Return ``value`` as escaped text: strings as they are, None as a dash, others as JSON."""
    if value is None:
        return '&mdash;'
    return escape(value if isinstance(value, str) else json.dumps(value, default=str))


def _verdict(passed: bool) -> str:
    return '<span class="pass">passed</span>' if passed else '<span class="fail">FAIL</span>'


def _page(path: Path, title: str, body: list[str], up: Path | None = None) -> Path:
    """Write an HTML page at ``path`` (making its folder) and return ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    back = [f'<p><a href="{_href(up, path.parent)}">&larr; index</a></p>'] if up else []
    path.write_text(printable('\n'.join([
        '<!DOCTYPE html>', '<html lang="en">', '<head>', '<meta charset="utf-8">',
        f'<title>{escape(title)}</title>', f'<style>{STYLE}</style>', '</head>', '<body>',
        *back, f'<h1>{escape(title)}</h1>', *body, '</body>', '</html>', ''])),
        encoding='utf-8')
    return path


def _table(header: list[str], rows: list[str]) -> str:
    head = [f"<tr>{''.join(f'<th>{escape(cell)}</th>' for cell in header)}</tr>"] if header else []
    return '\n'.join(['<table>', *head, *rows, '</table>'])


def _run_rows(index: int, run: dict[str, Any]) -> list[str]:
    """
    Return the table rows of one run, as grade prints them.

    Its error, node errors and criteria with measured values; its warnings (which fail
    nothing) are listed once for the page (:func:`_warnings_list`).
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
    name = f'<a href="#run-{index}">{escape(run["run"])}</a>'
    rows = []
    for criterion, shown, verdict in cells:
        rows.append(f'<tr><td>{name}</td><td>{escape(criterion)}</td><td>{escape(shown)}</td>'
                    f'<td class="{verdict}">{"FAIL" if verdict == "fail" else verdict}</td></tr>')
        name = ''
    return rows


def _run_section(index: int, run: dict[str, Any], folder: Path, root: Path) -> str:
    """Return one run's section: verdict, setup, plot, output links, errors and tracebacks."""
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
    parts = [f'<section id="run-{index}">',
             f'<h2>{escape(run["run"])}: {_verdict(run["passed"])}</h2>',
             _table([], [f'<tr><th>{escape(key)}</th><td>{_text(value)}</td></tr>'
                         for key, value in facts])]
    if run['error'] is not None:
        parts.append(f'<p class="fail">error: {escape(run["error"])}</p>')
    video = out_dir / 'video.mp4'  # sim_bridge.media.video.VIDEO_NAME (grade --video)
    if video.is_file():
        # An instructor watches a failing run before reading its numbers: it comes first.
        parts.append(f'<p><video controls preload="metadata" src="{_href(video, folder)}">'
                     f'{_link(video, folder, "video.mp4")}</video></p>')
    plot = out_dir / 'trajectory.png'
    parts.append(f'<p><img src="{_href(plot, folder)}" alt="trajectory of {escape(run["run"])}">'
                 '</p>' if plot.is_file() else '<p>no plot</p>')
    links = [_link(out_dir / 'metrics.json', folder, 'metrics.json'),
             _link(out_dir / 'run', folder, 'recording run/'),
             _link(video, folder, 'video.mp4'),
             _link(root / run['log'] if run.get('log') else None, folder, 'log')]
    parts.append(f"<p>outputs: {' | '.join(link for link in links if link) or 'none'}</p>")
    if metrics.get('warnings'):
        parts.append('<h3>warnings</h3>\n' + _warnings_list([run]))
    for node_error in metrics.get('node_errors', []):
        parts.append(f'<h3>node error in {escape(node_error["node"])}</h3>'
                     f'<pre>{escape(node_error["error"])}</pre>')
        if node_error.get('traceback'):
            parts.append(f'<pre>{escape(node_error["traceback"])}</pre>')
    if run['traceback']:
        parts.append(f'<h3>traceback</h3>\n<pre>{escape(run["traceback"])}</pre>')
    return '\n'.join([*parts, '</section>'])


def _warnings_list(runs: list[dict]) -> str:
    """Return the runs' warnings as a list, each once with the number of runs it was in."""
    counts = Counter(warning for run in runs
                     for warning in dict.fromkeys((run['metrics'] or {}).get('warnings') or []))
    if not counts:
        return ''
    items = [f'<li>{escape(warning)}'
             + (f' <span class="why">({count} runs)</span>' if count > 1 else '') + '</li>'
             for warning, count in counts.items()]
    return '<ul class="warn">' + ''.join(items) + '</ul>'


def _marks_table(tasks: list[TaskMarks]) -> list[str]:
    """
    Return the marks line and table of a page: per task its marks and runs passed.

    A task marked by the handout's points has a row per point under it: its marks and, when
    lost, why.
    """
    marked = [task for task in tasks if task.marks is not None]
    if not marked:
        return []
    earned, maximum = marks_total(marked)
    rows = []
    for task in marked:
        rows.append(f'<tr><td><b>{escape(task.title)}</b></td>'
                    f'{_marks_cell(task.earned, task.marks, bold=True)}'
                    f'<td>{escape(task.rule())}</td><td>{task.passed}/{task.runs}</td>'
                    f'<td>{escape(", ".join(task.scenarios))}</td></tr>')
        rows += [f'<tr><td>&nbsp;&nbsp;{escape(point.point)}</td>'
                 f'{_marks_cell(point.earned, point.marks)}'
                 f'<td class="why">{escape(point.why())}</td><td></td><td></td></tr>'
                 for point in task.points]
    return [f'<p><b>marks {format_marks(earned)}/{format_marks(maximum)}</b></p>',
            _table(['task', 'marks', 'how, or why marks were lost', 'runs passed',
                    'scenarios'], rows)]


def _marks_cell(earned: float, maximum: float, bold: bool = False,
                lost: Sequence[str] = ()) -> str:
    """
    Return a cell 'earned/maximum' marks: green when all, amber when some, red when none.

    ``lost`` names the points lost, listed under the marks.
    """
    colour = 'pass' if earned >= maximum else 'some' if earned > 0 else 'fail'
    text = f'{format_marks(earned)}/{format_marks(maximum)}'
    why = f'<span class="why">lost: {escape(", ".join(lost))}</span>' if lost else ''
    return f'<td class="{colour}">{f"<b>{text}</b>" if bold else text}{why}</td>'


def write_runs_page(path: Path, title: str, runs: list[dict], *, up: Path | None = None,
                    root: Path | None = None, notes: list[str] = (),
                    marks: list[TaskMarks] | None = None) -> Path:
    """
    Write one page of runs (a student's report, or one grading batch) and return its path.

    The page opens with the marks (``marks``, per task and point, with why marks were lost),
    then a summary line, ``notes`` (e.g. runs reused from an earlier invocation), the runs'
    warnings (each once, with the number of runs it was in), the pass/fail table (a row per
    criterion of each run, the error of a run that did not complete) and a section per run
    with its plot and outputs. ``up`` is the index page to link back to;
    it is linked even if not written yet. Relative paths in ``runs`` are relative to ``root``.
    """
    folder = path.parent
    root = Path(root) if root is not None else Path()
    passed = sum(bool(run['passed']) for run in runs)
    rows = [row for index, run in enumerate(runs) for row in _run_rows(index, run)]
    warnings = _warnings_list(runs)
    body = [*_marks_table(marks or []),
            f'<p>{passed} of {len(runs)} runs passed</p>',
            *(f'<p class="warn">{escape(note)}</p>' for note in notes),
            *([f'<h3>warnings</h3>\n{warnings}'] if warnings else []),
            _table(['run', 'criterion', 'measured', 'result'], rows),
            *(_run_section(index, run, folder, root) for index, run in enumerate(runs))]
    return _page(path, title, body, up)


def _count_cell(runs: list[dict]) -> str:
    """Return a cell 'passed/total' and why the others failed; green, amber if some, red."""
    count, why = count_cell(runs)
    if not runs:
        return '<td>&mdash;</td>'
    passed = sum(outcome(run) == 'passed' for run in runs)
    colour = 'pass' if passed == len(runs) else 'some' if passed else 'fail'
    reason = f'<span class="why">{escape(why)}</span>' if why else ''
    return f'<td class="{colour}">{count}{reason}</td>'


def write_class_index(path: Path, title: str, students: dict[str, list[dict]],
                      scenarios: list[str], pages: dict[str, Path],
                      marks: dict[str, list[TaskMarks]] | None = None) -> Path:
    """
    Write the class index and return its path.

    One row per student (sorted by name): with ``marks`` (each student's, per task), first the
    marks in all and per task out of the maximum, with the points lost; then 'passed/total'
    runs per scenario and in all, and the worst reason a run failed (see
    :data:`OUTCOME_LEGEND`, under the table); a student's name links to ``pages[student]``
    when that page exists.
    """
    marks = marks or {}
    marked = [task for task in next(iter(marks.values()), []) if task.marks is not None]
    header = ['student', *(['marks'] if marked else []), *(task.title for task in marked),
              *scenarios, 'runs']
    rows = []
    for student in sorted(students, key=lambda name: (name.casefold(), name)):
        runs = students[student]
        name = _link(pages.get(student), path.parent, student) or escape(student)
        tasks = [task for task in marks.get(student, []) if task.marks is not None]
        cells = [_marks_cell(*marks_total(tasks), bold=True)] if tasks else []
        cells += [_marks_cell(task.earned, task.marks, lost=[
            point.point for point in task.points if point.lost]) for task in tasks]
        cells += [_count_cell([run for run in runs if run['scenario'] == scenario])
                  for scenario in scenarios]
        cells.append(_count_cell(runs))
        rows.append(f"<tr><td>{name}</td>{''.join(cells)}</tr>")
    total = sum(len(runs) for runs in students.values())
    passed = sum(bool(run['passed']) for runs in students.values() for run in runs)
    rate = f', {passed} passed ({100.0 * passed / total:.0f} %)' if total else ''
    body = [f'<p>{len(students)} students, {total} runs{rate}</p>',
            _table(header, rows),
            *(f'<p>{escape(task.rule())}</p>' for task in marked),
            '<p>' + '<br>\n'.join(f'<b>{escape(name)}</b>: {escape(text)}'
                                  for name, text in OUTCOME_LEGEND.items()) + '</p>']
    return _page(path, title, body)


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
