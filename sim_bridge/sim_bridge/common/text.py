"""
Texts a grading report carries: bounded, printable, valid JSON, free of the grader's paths.

Student code is data: an exception message may be 50 MB long, hold a lone surrogate (a file
name decoded with ``surrogateescape``), and a run's parameters may be ``.inf``. Every report
entry goes through :func:`json_safe` before it is sent, saved or shown, so writing a report
never fails on one run's content and never grows with it. :class:`PathNames` turns the
grader's absolute paths into paths relative to the folders a reader knows. The rest formats
what the instructor reads: measured values with units, a run's outcome in a few words.
"""

import math
import os
import re
from typing import Any, Callable

#: The most bytes (UTF-8) of one text in a report: an error, a traceback, a log excerpt.
TEXT_LIMIT_BYTES = 16 * 1024
#: The most characters of a reason in a progress line or a table cell.
REASON_CHARS = 80
#: How the grader's errors about a submission's files begin: a reason shows them whole, so
#: every file they name is named in full.
FILE_ERRORS = ('not submitted', 'node file too big')
#: Run outcomes from the best to the worst (see :func:`outcome`), for a class table cell.
OUTCOMES = ('passed', 'criteria failed', 'node error', 'error', 'not submitted')
#: What each failed outcome means, for the legend under a class table.
OUTCOME_LEGEND = {
    'criteria failed': 'the run completed; a criterion did not hold',
    'node error': 'a node raised, exited or stopped replying during the run',
    'error': 'the run did not complete (the node file does not import, a crash, a limit)',
    'not submitted': "the student's folder has no file for the scenario's node",
}
#: The unit of a metric, by the end of its name.
_UNITS = (('_m', 'm'), ('_s', 's'), ('_deg', 'deg'))
#: Control characters (C0 but newline and tab, DEL, C1) a terminal would act on.
_CONTROL = re.compile('[\\x00-\\x08\\x0b-\\x1f\\x7f-\\x9f]')
_METRIC = re.compile(r'(?:(?P<function>\w+)\s*\(\s*)?(?P<path>[A-Za-z_][\w.]*)')


def printable(text: str) -> str:
    r"""
    Return ``text`` encodable as UTF-8 and inert on a terminal: ``\xNN`` escapes for the rest.

    A surrogate from ``os.fsdecode`` (a file name that is not UTF-8) shows as the byte it
    stands for: ``os.fsdecode(b'caf\xe9')`` gives ``'caf\\xe9'``. A control character but
    newline and tab shows as its code (``'\x1b[2J'`` as ``'\\x1b[2J'``), so a student's
    message cannot clear the instructor's terminal, rewrite a line with ``\r`` or put a NUL
    in a page.
    """
    try:
        text.encode('utf-8')
    except UnicodeEncodeError:
        try:
            raw = text.encode('utf-8', 'surrogateescape')
        except UnicodeEncodeError:  # a surrogate no file name decoding makes
            text = text.encode('utf-8', 'backslashreplace').decode('utf-8')
        else:
            text = raw.decode('utf-8', 'backslashreplace')
    return _CONTROL.sub(lambda match: f'\\x{ord(match.group()):02x}', text)


def one_line(name: str) -> str:
    r"""Return a name (a student's folder, a run) printable on one line: newline as ``\n``."""
    return printable(name).replace('\n', '\\n').replace('\t', '\\t')


def cap_text(text: str, limit: int = TEXT_LIMIT_BYTES) -> str:
    """
    Return ``text`` printable and at most about ``limit`` bytes (UTF-8) long.

    A longer text keeps its beginning and its end (where a traceback says what was raised)
    around a line ``... N bytes cut ...``.
    """
    text = printable(text)
    if len(text) * 4 <= limit:  # no character takes more than 4 bytes
        return text
    data = text.encode('utf-8')
    if len(data) <= limit:
        return text
    keep = limit // 2
    head = data[:keep].decode('utf-8', 'ignore')
    tail = data[-keep:].decode('utf-8', 'ignore')
    return f'{head}\n... {len(data) - 2 * keep} bytes cut ...\n{tail}'


def json_safe(value: Any, text: Callable[[str], str] = cap_text) -> Any:
    """
    Return ``value`` as strict JSON can hold it, with every text passed through ``text``.

    Mappings, lists and tuples are copied; a non-finite float becomes the text ``'inf'``,
    ``'-inf'`` or ``'nan'``; anything else that is not a JSON value becomes its text.
    """
    if isinstance(value, str):
        return text(value)
    if value is None or isinstance(value, (bool, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if isinstance(value, dict):
        return {text(str(key)): json_safe(item, text) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(item, text) for item in value]
    return text(str(value))


class PathNames:
    """
    Replace the grader's absolute folders in texts by names a report's reader knows.

    ``folders`` maps a folder to what stands for it (``''`` for a path relative to it,
    ``'~'``); the longest folder wins, and only where its name ends (not ``/out2`` for
    ``/out``). ``relative('/out/ana/x')`` with ``{'/out': ''}`` gives ``'ana/x'``; the folder
    itself gives ``'.'``.
    """

    def __init__(self, folders: dict[str | os.PathLike, str]) -> None:
        self.folders = {}
        for folder, name in folders.items():
            folder = os.path.abspath(folder)
            if folder != os.path.dirname(folder):  # never the root folder
                self.folders.setdefault(folder, name)
        ordered = sorted(self.folders, key=len, reverse=True)
        self.pattern = re.compile(
            f"(?:{'|'.join(map(re.escape, ordered))})(?P<slash>/+|(?![\\w.@%+~-]))"
        ) if ordered else None

    def __call__(self, text: str) -> str:
        """Return ``text`` with each of the folders replaced by its name."""
        if self.pattern is None:
            return text
        return self.pattern.sub(self._replace, text)

    def _replace(self, match: re.Match) -> str:
        folder = match.group(0)[:len(match.group(0)) - len(match['slash'])]
        name = self.folders[folder]
        if match['slash']:
            return f'{name}/' if name else ''
        return name or '.'

    def path(self, path: str | os.PathLike) -> str:
        """Return how the report names a file (absolute, or relative to the current folder)."""
        return self(os.path.abspath(path))


def format_number(value: float | int) -> str:
    """Return a number as people read it: 3 significant digits, or 3 decimals below 1."""
    if isinstance(value, bool) or isinstance(value, int) or not math.isfinite(value):
        return str(value)
    magnitude = abs(value)
    if magnitude < 0.0005:
        return '0.000'
    if magnitude < 1:
        return f'{value:.3f}'
    return f'{value:.{max(0, 2 - math.floor(math.log10(magnitude)))}f}'


def format_measured(criterion: str, value: Any) -> str:
    """
    Return a criterion's measured ``value`` with the unit of its metric: '0.000 m', '12.3 s'.

    A list (``all(turns_deg)``) reads 'N values, min .., max ..'; a missing value 'no value'.
    """
    match = _METRIC.match(criterion.strip())
    unit = ''
    if match is not None and match['function'] != 'len':
        for suffix, name in _UNITS:
            if any(part.endswith(suffix) for part in match['path'].split('.')):
                unit = f' {name}'
    if value is None:
        return 'no value'
    if isinstance(value, list):
        numbers = [item for item in value if isinstance(item, (int, float))]
        if not numbers:
            return f'{len(value)} values' if value else 'no values'
        return (f'{len(value)} values, min {format_number(min(numbers))}{unit}, '
                f'max {format_number(max(numbers))}{unit}')
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f'{format_number(value)}{unit}'
    return str(value)


def first_line(text: str, chars: int | None = REASON_CHARS) -> str:
    """Return the first non-empty line of ``text``, printable, cut to ``chars`` (None: not)."""
    line = next((line.strip() for line in text.split('\n') if line.strip()), '')
    line = printable(line)
    return line if chars is None or len(line) <= chars else line[:chars - 3].rstrip() + '...'


def outcome(entry: dict[str, Any]) -> str:
    """Return a run entry's outcome, one of :data:`OUTCOMES`."""
    if entry.get('passed'):
        return 'passed'
    error = entry.get('error')
    if error is not None:
        return 'not submitted' if str(error).startswith('not submitted') else 'error'
    if (entry.get('metrics') or {}).get('node_errors'):
        return 'node error'
    return 'criteria failed'


def reason(entry: dict[str, Any]) -> str:
    """Say in a few words why a run entry failed ('' for a passed run)."""
    if entry.get('passed'):
        return ''
    if entry.get('error') is not None:
        return error_reason(str(entry['error']))
    node_errors = (entry.get('metrics') or {}).get('node_errors') or []
    if node_errors:
        return first_line(str(node_errors[0].get('error')))
    # A criterion whose measured value is a text (what a node printed) says itself why.
    failed = [result['value'] if isinstance(result.get('value'), str) else result['criterion']
              for result in entry.get('criteria', []) if not result.get('passed')]
    return first_line(', '.join(failed) or 'failed')


def error_reason(error: str) -> str:
    """
    Return a run's error as a reason: its first line, cut to REASON_CHARS.

    The grader's errors about the submission's files (FILE_ERRORS: one bounded line) are kept
    whole, so every file they name is named in full.
    """
    return first_line(error, None if error.startswith(FILE_ERRORS) else REASON_CHARS)


def count_cell(entries: list[dict[str, Any]]) -> tuple[str, str]:
    """
    Return a class table cell of runs: ('passed/total', the worst outcome of a failed run).

    The outcome is '' when every run passed; the cell of no runs is ('-', '').
    """
    if not entries:
        return '-', ''
    outcomes = [outcome(entry) for entry in entries]
    worst = max(outcomes, key=OUTCOMES.index)
    passed = outcomes.count('passed')
    return f'{passed}/{len(entries)}', '' if worst == 'passed' else worst
