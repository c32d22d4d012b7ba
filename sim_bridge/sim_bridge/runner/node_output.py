"""
What the nodes of a run write, line by line, with the simulated time of the code that wrote it.

Every line a node writes during a run, through its rclpy logger (rcutils' console output, on
stderr) or ``print`` (anything on stdout or stderr), becomes one entry::

    {"t": 12.3, "node": "scan_ahead", "level": "INFO", "text": "Range ahead: 1.23",
     "line": "[INFO] [1795499925.029450212] [scan_ahead]: Range ahead: 1.23"}

``t`` is the simulated time (s) when the line was written; ``level`` is the logger's severity
(``DEBUG`` ``INFO`` ``WARN`` ``ERROR`` ``FATAL``) for a line in rcutils' console format, else
``STDOUT`` or ``STDERR``; ``text`` the logger's message alone (the whole line otherwise);
``line`` the line as the console showed it (colour codes removed). ``node`` is the logger's
name for a logger line; for any other line, the node whose code was running when it was
written where the runner knows it (a stepped run), else ''. The run writes them to
``log.jsonl`` (one JSON object a line) and to its recording as ``/rosout``, received at that
simulated time, each an rcl_interfaces/msg/Log as rcl fills it: stamped with the wall clock
(rcutils' own time of the line when the console format shows it, else when the line was read),
with the file, function and line of the logging call when the format shows them.

Logger lines are read from the console text, not from /rosout, so that nothing a node writes
is missed (a logger of no node, ``RCUTILS_LOGGING_USE_STDOUT``, a C library's printf) and the
text is what the terminal showed; the format is rcutils' own, ``RCUTILS_CONSOLE_OUTPUT_FORMAT``
or its default, read back by :func:`console_pattern`.

A run's nodes write in processes of their own (sim_bridge.runner.boundary.inside.agent), whose
stdout and stderr (file descriptors 1 and 2: rcutils' console output and a C library's printf too)
are pipes the runner reads: :class:`StreamLines` copies what arrives to the terminal (unless quiet)
and cuts it into lines at the node process's sync points (around each callback), each line
stamped with the sim time and node of the code that wrote its first byte.
"""

import collections
import contextlib
import json
import os
from pathlib import Path
import re
import sys
import threading
import time
from typing import ContextManager, Iterable

from sim_bridge.common.run_environment import environment_set
from sim_bridge.common.text import printable

#: The file of the run's output folder that holds the lines, one JSON object each.
LOG_FILE = 'log.jsonl'
#: The recording's topic and type of the lines, as ROS 2 nodes publish their log.
ROSOUT_TOPIC = '/rosout'
ROSOUT_TYPE = 'rcl_interfaces/msg/Log'
#: rcutils' console format when RCUTILS_CONSOLE_OUTPUT_FORMAT does not set one.
DEFAULT_CONSOLE_FORMAT = '[{severity}] [{time}] [{name}]: {message}'
FORMAT_VARIABLE = 'RCUTILS_CONSOLE_OUTPUT_FORMAT'
COLOUR_VARIABLE = 'RCUTILS_COLORIZED_OUTPUT'
#: Logger severities as rcutils prints them, and their rcl_interfaces/msg/Log levels.
SEVERITIES = {'DEBUG': 10, 'INFO': 20, 'WARN': 30, 'ERROR': 40, 'FATAL': 50}
#: The Log level a raw line gets in the recording.
STREAM_LEVELS = {'STDOUT': 20, 'STDERR': 40}
#: Most lines a run keeps: a node printing without end must not take the grader's memory.
MAX_LINES = 200_000

#: What rcutils prints for the console format's tokens the recording reads back.
_TOKEN_PATTERNS = {'name': '.*?', 'message': '.*', 'time': r'-?\d+\.\d+',
                   'time_as_nanoseconds': r'-?\d+', 'file_name': '.*?',
                   'function_name': '.*?', 'line_number': r'\d+'}
_ANSI = re.compile(r'\x1b\[[0-9;]*[A-Za-z]')
_TOKEN = re.compile(r'\{(\w+)\}')


def terminal_colours() -> ContextManager[None]:
    """
    Keep rcutils' colours on a terminal while the output is captured, for the block.

    rcutils colours its lines when stderr is a terminal (RCUTILS_COLORIZED_OUTPUT unset); in a
    capture it is a pipe. The variable is read when rcutils' logging starts (``rclpy.init``).
    """
    if os.environ.get(COLOUR_VARIABLE) is None and sys.stderr.isatty():
        return environment_set({COLOUR_VARIABLE: '1'})
    return contextlib.nullcontext()


def console_pattern(console_format: str | None = None) -> re.Pattern | None:
    """
    Return a regex matching a logger line of rcutils' console format, or None.

    ``console_format`` defaults to RCUTILS_CONSOLE_OUTPUT_FORMAT or rcutils' default. The
    groups ``severity``, ``message`` and (when the format has them) ``name``, ``time``,
    ``time_as_nanoseconds``, ``file_name``, ``function_name`` and ``line_number`` are the
    line's; None when the format lacks ``{severity}`` or ``{message}`` (no line can be read
    back).
    """
    if console_format is None:
        console_format = os.environ.get(FORMAT_VARIABLE) or DEFAULT_CONSOLE_FORMAT
    parts, seen, position = ['^'], set(), 0
    for token in _TOKEN.finditer(console_format):
        parts.append(re.escape(console_format[position:token.start()]))
        name = token.group(1)
        if name in seen:
            parts.append('.*?')
        elif name == 'severity':
            parts.append(f"(?P<severity>{'|'.join(SEVERITIES)})")
        elif name in _TOKEN_PATTERNS:
            parts.append(f'(?P<{name}>{_TOKEN_PATTERNS[name]})')
        else:
            parts.append('.*?')
        seen.add(name)
        position = token.end()
    parts.append(re.escape(console_format[position:]) + '$')
    if not {'severity', 'message'} <= seen:
        return None
    return re.compile(''.join(parts))


def log_entry(t_s: float, node: str, stream: str, line: str,
              pattern: re.Pattern | None) -> dict:
    """
    Return the entry of one console ``line`` (no newline) written at ``t_s`` (s) on ``stream``.

    ``stream`` is 'STDOUT' or 'STDERR'; ``node`` is the node whose code wrote it, or ''. The
    line is kept printable (report_text.printable: a student's text that is not UTF-8, a
    control character, shown as escapes), its colour codes removed.
    """
    line = printable(_ANSI.sub('', line).rstrip('\r'))
    match = pattern.match(line) if pattern is not None else None
    if match is None:
        return {'t': t_s, 'node': node, 'level': stream, 'text': line, 'line': line}
    name = match.groupdict().get('name')
    return {'t': t_s, 'node': node if name is None else name, 'level': match['severity'],
            'text': match['message'], 'line': line}


class NodeLog:
    """
    The entries of a run, in the order written; thread-safe.

    ``pending`` holds the entries not yet written to the recording, when ``record``, with their
    sim time and the wall clock time they were read at (ns). At most MAX_LINES entries are
    kept; ``dropped`` counts the rest.
    """

    def __init__(self, record: bool = True, pattern: re.Pattern | None = None):
        self.entries: list[dict] = []
        self.pending: collections.deque = collections.deque()
        self.record = record
        self.dropped = 0
        #: What the run's output capture says it could not keep, if anything.
        self.output_warning: str | None = None
        self.pattern = console_pattern() if pattern is None else pattern
        self._lock = threading.Lock()

    def add(self, t_ns: int, node: str, stream: str, line: str) -> None:
        """Keep ``line``, written on ``stream`` (STDOUT, STDERR) at ``t_ns`` (ns) by ``node``."""
        entry = log_entry(t_ns / 1e9, node, stream, line, self.pattern)
        with self._lock:
            if len(self.entries) >= MAX_LINES:
                self.dropped += 1
                return
            self.entries.append(entry)
        if self.record:
            self.pending.append((t_ns, entry, time.time_ns()))

    def take_rosout(self) -> Iterable[tuple[int, bytes]]:
        """
        Yield (and forget) the entries not yet recorded, oldest first, as /rosout messages.

        Each is its sim time (ns) and the CDR bytes of its rcl_interfaces/msg/Log.
        """
        while True:
            try:
                t_ns, entry, read_ns = self.pending.popleft()
            except IndexError:
                return
            match = None
            if entry['level'] in SEVERITIES and self.pattern is not None:
                match = self.pattern.match(entry['line'])
            yield t_ns, rosout_message(entry, read_ns, match.groupdict() if match else {})

    def warning(self) -> str | None:
        """Say how many lines (or bytes of output) were not kept, or None."""
        if not self.dropped:
            return self.output_warning
        return (f'{LOG_FILE} keeps the first {MAX_LINES} lines the nodes wrote; '
                f'{self.dropped} more were not kept')


def rosout_message(entry: dict, read_ns: int, fields: dict[str, str | None]) -> bytes:
    """
    Return the CDR bytes of ``entry`` as the rcl_interfaces/msg/Log rcl publishes on /rosout.

    ``fields`` are the console line's tokens (console_pattern's groups): the stamp is rcutils'
    wall clock time of the line (``time`` or ``time_as_nanoseconds``) when given, else
    ``read_ns`` (the wall clock, ns, when the line was read); ``file_name``,
    ``function_name`` and ``line_number`` when given.
    """
    from rcl_interfaces.msg import Log
    from rclpy.serialization import serialize_message
    msg = Log()
    msg.stamp.sec, msg.stamp.nanosec = divmod(_wall_ns(fields) or read_ns, 1_000_000_000)
    msg.level = SEVERITIES.get(entry['level']) or STREAM_LEVELS[entry['level']]
    msg.name = entry['node']
    msg.msg = entry['text']
    msg.file = fields.get('file_name') or ''
    msg.function = fields.get('function_name') or ''
    msg.line = int(fields.get('line_number') or 0)
    return serialize_message(msg)


def _wall_ns(fields: dict[str, str | None]) -> int | None:
    """Return the wall clock time (ns) a console line shows, None if it shows none."""
    if fields.get('time_as_nanoseconds'):
        return max(0, int(fields['time_as_nanoseconds']))
    if fields.get('time'):
        seconds, _, fraction = fields['time'].lstrip('-').partition('.')
        return int(seconds) * 1_000_000_000 + int(fraction[:9].ljust(9, '0'))
    return None


def write_log(path: Path, entries: Iterable[dict], max_bytes: int | None = None) -> int:
    """
    Write ``entries`` to ``path``, one JSON object a line (UTF-8), ``max_bytes`` at most.

    Return how many entries were left out: those after the first that would pass the cap.
    """
    written, left = 0, 0
    with open(path, 'w', encoding='utf-8') as file:
        for entry in entries:
            line = json.dumps(entry, ensure_ascii=False) + '\n'
            written += len(line.encode('utf-8')) if not left else 0
            if left or (max_bytes is not None and written > max_bytes):
                left += 1
                continue
            file.write(line)
    return left


def write_all(fd: int, data: bytes) -> None:
    """Write ``data`` to file descriptor ``fd``; a terminal that is gone costs nothing."""
    try:
        while data:
            data = data[os.write(fd, data):]
    except OSError:
        pass


class StreamLines:
    """
    What a node process wrote on its stdout and stderr, cut into lines on the trusted side.

    The bytes arrive from the process's pipes (:meth:`take`); :meth:`cut` (at the sync frames
    of sim_bridge.runner.boundary.inside.agent) turns what arrived so far into lines stamped with
    the sim time and node given: a line's stamp is that of the cut that saw its first byte. Whole
    lines are shown on this process's terminal as they are cut (when ``quiet``, all but the
    loggers' lines, as ``--disable-stdout-logs`` would). At most ``cap_bytes`` are kept; the rest
    are shown, counted, not kept. ``tail`` keeps the last lines (their first 1000 characters), to
    read a traceback or a crash's stack from.
    """

    def __init__(self, log: NodeLog, *, quiet: bool = False, cap_bytes: int = 8 * 2 ** 20):
        self.log = log
        self.quiet = quiet
        self.cap_bytes = cap_bytes
        self.kept = self.dropped = 0
        self.tail: collections.deque[str] = collections.deque(maxlen=400)
        self.arrived = {'STDOUT': [], 'STDERR': []}
        self.partial = {'STDOUT': b'', 'STDERR': b''}
        self.partial_stamp: dict[str, tuple[int, str] | None] = {'STDOUT': None, 'STDERR': None}
        self.last_stamp = (0, '')

    def take(self, stream: str, data: bytes) -> None:
        """
        Keep ``data`` that arrived on ``stream`` ('STDOUT' or 'STDERR'), within the cap.

        Past the cap, bytes are still shown (a grader's log keeps their head and tail) but
        neither kept nor cut into lines.
        """
        room = max(0, self.cap_bytes - self.kept)
        if room:
            self.arrived[stream].append(data[:room])
            self.kept += min(room, len(data))
        if len(data) > room:
            if not self.dropped:  # the kept lines are shown first, in order, the last cut short
                self.cut(*self.last_stamp)
                self._cut_short()
            self.dropped += len(data) - room
            write_all(1 if stream == 'STDOUT' else 2, data[room:])

    def cut(self, t_ns: int, node: str) -> None:
        """Cut what arrived since the last cut into lines stamped ``t_ns`` (ns) and ``node``."""
        self.last_stamp = (t_ns, node)
        for stream, chunks in self.arrived.items():
            if not chunks:
                continue
            *lines, rest = (self.partial[stream] + b''.join(chunks)).split(b'\n')
            chunks.clear()
            for line in lines:
                self._line(stream, line, self.partial_stamp[stream] or (t_ns, node))
                self.partial_stamp[stream] = None
            self.partial[stream] = rest
            if rest and self.partial_stamp[stream] is None:
                self.partial_stamp[stream] = (t_ns, node)

    def _line(self, stream: str, line: bytes, stamp: tuple[int, str]) -> None:
        text = line.decode('utf-8', errors='replace')
        self.tail.append(text[:1000])
        self.log.add(stamp[0], stamp[1], stream, text)
        if not (self.quiet and self.log.pattern is not None
                and self.log.pattern.match(_ANSI.sub('', text).rstrip('\r'))):
            write_all(1 if stream == 'STDOUT' else 2, line + b'\n')

    def _cut_short(self) -> None:
        """Keep the lines begun, as they are; show them without a newline (more follows)."""
        for stream, rest in self.partial.items():
            if rest:
                t_ns, node = self.partial_stamp[stream] or self.last_stamp
                text = rest.decode('utf-8', errors='replace')
                self.tail.append(text[:1000])
                self.log.add(t_ns, node, stream, text)
                write_all(1 if stream == 'STDOUT' else 2, rest)
                self.partial[stream], self.partial_stamp[stream] = b'', None

    def close(self, t_ns: int) -> None:
        """Cut what is left, the last line without its newline, at ``t_ns`` (ns)."""
        self.cut(t_ns, '')
        for stream, rest in self.partial.items():
            if rest:
                self._line(stream, rest, self.partial_stamp[stream] or (t_ns, ''))
                self.partial[stream] = b''

    def warning(self) -> str | None:
        """Say how many bytes of output were not kept, or None."""
        if not self.dropped:
            return None
        return (f'the nodes wrote {self.kept + self.dropped} bytes of output; the first '
                f'{self.kept} were kept, {self.dropped} were not')


def to_terminal(text: str) -> None:
    """
    Write the runner's own ``text`` on stderr.

    A closed or replaced stderr costs the run nothing.
    """
    try:
        sys.stderr.write(text)
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
