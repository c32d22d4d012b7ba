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
``log.jsonl`` (one JSON object a line) and to its recording as ``/rosout``
(rcl_interfaces/msg/Log stamped with that simulated time).

Logger lines are read from the console text, not from /rosout, so that nothing a node writes
is missed (a logger of no node, ``RCUTILS_LOGGING_USE_STDOUT``, a C library's printf) and the
text is what the terminal showed; the format is rcutils' own, ``RCUTILS_CONSOLE_OUTPUT_FORMAT``
or its default, read back by :func:`console_pattern`.

A stepped run's nodes share the runner's process: :class:`OutputCapture` puts pipes on file
descriptors 1 and 2 for the run, copies what arrives to the terminal (unless quiet), and cuts it
into lines at the runner's :meth:`OutputCapture.sync` points (after each callback), each line
stamped with the time and node of the code that wrote its first byte. A process run reads its
node's pipes (sim_bridge.live) and stamps each line with the live simulated time.
"""

import collections
import contextlib
import ctypes
import faulthandler
import fcntl
import io
import json
import os
from pathlib import Path
import re
import selectors
import sys
import termios
import threading
from typing import Callable, ContextManager, Iterable

from sim_bridge.report_text import printable
from sim_bridge.run_environment import environment_set

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
#: Longest wait (wall s) at a sync for output already written to reach the reader thread (it
#: takes microseconds; a reader starved of the CPU must not hold the run).
SYNC_TIMEOUT_S = 1.0
#: Bytes read from a pipe at once, and the pipe size asked for (a node's burst fits in it).
CHUNK_BYTES = 2 ** 16
PIPE_BYTES = 2 ** 20
F_SETPIPE_SZ = 1031  # fcntl.F_SETPIPE_SZ, Linux only, named in Python 3.10+ on Linux only

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
    groups ``severity``, ``message`` and (when the format has it) ``name`` are the line's;
    None when the format lacks ``{severity}`` or ``{message}`` (no line can be read back).
    """
    if console_format is None:
        console_format = os.environ.get(FORMAT_VARIABLE) or DEFAULT_CONSOLE_FORMAT
    parts, seen, position = ['^'], set(), 0
    for token in _TOKEN.finditer(console_format):
        parts.append(re.escape(console_format[position:token.start()]))
        name = token.group(1)
        if name == 'severity' and name not in seen:
            parts.append(f"(?P<severity>{'|'.join(SEVERITIES)})")
        elif name in ('name', 'message') and name not in seen:
            parts.append(f'(?P<{name}>.*)' if name == 'message' else f'(?P<{name}>.*?)')
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

    ``pending`` holds the entries (with their time in ns) not yet written to the recording,
    when ``record``. At most MAX_LINES entries are kept; ``dropped`` counts the rest.
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
            self.pending.append((t_ns, entry))

    def take_pending(self) -> Iterable[tuple[int, dict]]:
        """Yield (and forget) the entries not yet recorded, oldest first, with their time (ns)."""
        while True:
            try:
                yield self.pending.popleft()
            except IndexError:
                return

    def warning(self) -> str | None:
        """Say how many lines (or bytes of output) were not kept, or None."""
        if not self.dropped:
            return self.output_warning
        return (f'{LOG_FILE} keeps the first {MAX_LINES} lines the nodes wrote; '
                f'{self.dropped} more were not kept')


def rosout_message(entry: dict, t_ns: int) -> bytes:
    """Return the CDR bytes of ``entry`` as a rcl_interfaces/msg/Log stamped ``t_ns`` (ns)."""
    from rcl_interfaces.msg import Log
    from rclpy.serialization import serialize_message
    msg = Log()
    msg.stamp.sec, msg.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    msg.level = SEVERITIES.get(entry['level']) or STREAM_LEVELS[entry['level']]
    msg.name = entry['node']
    msg.msg = entry['text']
    return serialize_message(msg)


def write_log(path: Path, entries: Iterable[dict]) -> None:
    """Write ``entries`` to ``path``, one JSON object a line (UTF-8)."""
    with open(path, 'w', encoding='utf-8') as file:
        for entry in entries:
            file.write(json.dumps(entry, ensure_ascii=False) + '\n')


class _Stream:
    """One captured file descriptor: its pipe, the terminal it copies to, its partial line."""

    def __init__(self, fd: int, name: str):
        self.fd = fd
        self.name = name
        self.saved = os.dup(fd)
        self.read_fd, write_fd = os.pipe()
        try:
            fcntl.fcntl(write_fd, F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:  # over the system's limit for unprivileged pipes: the default size
            pass
        os.dup2(write_fd, fd)
        os.close(write_fd)
        os.set_blocking(self.read_fd, False)
        #: Bytes the reader has taken from the pipe.
        self.taken = 0
        self.partial = b''
        self.partial_stamp: tuple[int, str] | None = None
        # A quiet run's line not shown yet (it may be a logger's), and whether the line
        # being written is shown whatever it is (too long to hold).
        self.unshown = b''
        self.showing = False

    def unread(self) -> int:
        """Return the bytes in the pipe not read yet."""
        count = ctypes.c_int()
        fcntl.ioctl(self.read_fd, termios.FIONREAD, count)
        return count.value


class OutputCapture:
    """
    Capture file descriptors 1 and 2 of this process as the nodes' output, while in the block.

    Python's ``sys.stdout`` and ``sys.stderr`` are line-buffered text streams on them for the
    block (pytest's or a notebook's streams may write elsewhere). A thread copies what arrives
    to the terminal as it was before the block (when ``quiet``, all but the loggers' lines, as
    ``--disable-stdout-logs`` would) and hands it to
    :meth:`sync`, which cuts it into lines for ``log``, stamped ``clock_ns()`` and the ``node``
    given; a line's stamp is that of the sync that saw its first byte. The runner writes its own
    lines with :meth:`console` (the terminal, not the nodes' output).
    """

    #: The capture in force, if any: the runner's own lines go round it (:func:`to_terminal`).
    active: 'OutputCapture | None' = None

    def __init__(self, log: NodeLog, clock_ns: Callable[[], int], *, quiet: bool = False):
        self.log = log
        self.clock_ns = clock_ns
        self.quiet = quiet
        self.streams: list[_Stream] = []
        self._chunks: list[tuple[_Stream, bytes]] = []
        self._ready = threading.Condition()
        self._thread: threading.Thread | None = None
        self._stop_read = self._stop_write = -1
        self._python_streams = None
        self._console = None
        self._libc = ctypes.CDLL(None)

    def __enter__(self) -> 'OutputCapture':
        self._flush_writers()
        OutputCapture.active = self
        self._python_streams = (sys.stdout, sys.stderr)
        self.streams = [_Stream(1, 'STDOUT'), _Stream(2, 'STDERR')]
        sys.stdout, sys.stderr = (
            io.TextIOWrapper(io.FileIO(fd, 'w', closefd=False), encoding='utf-8',
                             errors='backslashreplace', line_buffering=True) for fd in (1, 2))
        self._console = io.TextIOWrapper(io.FileIO(self.streams[1].saved, 'w', closefd=False),
                                         encoding='utf-8', errors='backslashreplace',
                                         line_buffering=True)
        if faulthandler.is_enabled():
            # A crash's stacks go straight to the terminal: the reader dies with the process.
            faulthandler.enable(self._console)
        self._stop_read, self._stop_write = os.pipe()
        self._thread = threading.Thread(target=self._read, name='node-output', daemon=True)
        self._thread.start()
        return self

    def console(self, text: str) -> None:
        """Write the runner's own ``text`` on the terminal's stderr."""
        try:
            self._console.write(text)
            self._console.flush()
        except (OSError, ValueError):
            pass

    def _read(self) -> None:
        selector = selectors.DefaultSelector()
        for stream in self.streams:
            selector.register(stream.read_fd, selectors.EVENT_READ, stream)
        selector.register(self._stop_read, selectors.EVENT_READ, None)
        while len(selector.get_map()) > 1:
            for key, _ in selector.select():
                stream = key.data
                if stream is None:  # the block ended (a process a node started may hold a pipe)
                    selector.close()
                    return
                # Read and count under the lock: a sync sees each byte unread or handed over.
                with self._ready:
                    try:
                        data = os.read(stream.read_fd, CHUNK_BYTES)
                    except BlockingIOError:
                        continue
                    if data:
                        self._chunks.append((stream, data))
                        stream.taken += len(data)
                        self._ready.notify_all()
                if data:
                    self._show(stream, data)
                else:
                    selector.unregister(stream.read_fd)
        selector.close()

    def _show(self, stream: _Stream, data: bytes) -> None:
        """Copy ``data`` to the terminal; in a quiet run, all but the loggers' whole lines."""
        if not self.quiet:
            self._copy(stream.saved, data)
            return
        buffer, start, shown = stream.unshown + data, 0, bytearray()
        while (end := buffer.find(b'\n', start)) >= 0:
            line = buffer[start:end + 1]
            if stream.showing or not self._logger_line(line):
                shown += line
            stream.showing, start = False, end + 1
        rest = buffer[start:]
        if rest and (stream.showing or len(rest) > CHUNK_BYTES):
            shown += rest
            rest, stream.showing = b'', True
        stream.unshown = rest
        self._copy(stream.saved, bytes(shown))

    def _logger_line(self, line: bytes) -> bool:
        text = _ANSI.sub('', line.decode('utf-8', errors='replace')).rstrip('\r\n')
        return self.log.pattern is not None and self.log.pattern.match(text) is not None

    @staticmethod
    def _copy(fd: int, data: bytes) -> None:
        try:
            while data:
                data = data[os.write(fd, data):]
        except OSError:  # the terminal is gone: the lines are still kept
            pass

    def _flush_writers(self) -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, AttributeError):  # closed or replaced by a node
                pass
        self._libc.fflush(None)  # C's stdio: rcutils' stdout, a library's printf

    def sync(self, node: str = '', keep: bool = True) -> None:
        """
        Cut what was written since the last sync into lines, stamped now and ``node``.

        Lines that start with ``keep`` false (a runner's node wrote them) are not kept.
        """
        self._flush_writers()
        with self._ready:
            # What was written so far: taken by the reader, or still in the pipe. Bytes
            # written after this (a node's thread) may come along, and need not be waited for.
            wanted = [(stream, stream.taken + stream.unread()) for stream in self.streams]
            self._ready.wait_for(lambda: all(stream.taken >= count for stream, count in wanted),
                                 timeout=SYNC_TIMEOUT_S)
            chunks, self._chunks = self._chunks, []
        if chunks:
            stamp = (self.clock_ns(), node if keep else None)
            for stream, data in chunks:
                self._cut(stream, data, stamp)

    def _cut(self, stream: _Stream, data: bytes, stamp: tuple[int, str | None]) -> None:
        *lines, rest = (stream.partial + data).split(b'\n')
        for line in lines:
            t_ns, node = stream.partial_stamp or stamp
            stream.partial_stamp = None
            if node is not None:
                self.log.add(t_ns, node, stream.name, line.decode('utf-8', errors='replace'))
        stream.partial = rest
        if rest and stream.partial_stamp is None:
            stream.partial_stamp = stamp

    def __exit__(self, *exc_info) -> None:
        self.sync()
        sys.stdout, sys.stderr = self._python_streams
        for stream in self.streams:
            os.dup2(stream.saved, stream.fd)
        if faulthandler.is_enabled():
            try:
                faulthandler.enable()  # on sys.stderr, as it was
            except (AttributeError, ValueError, io.UnsupportedOperation):
                # A stream without a file descriptor (pytest's capsys, a notebook's).
                faulthandler.enable(sys.__stderr__)
        os.write(self._stop_write, b'.')
        self._thread.join()
        for fd in (self._stop_read, self._stop_write):
            os.close(fd)
        for stream in self.streams:
            if stream.unshown and not self._logger_line(stream.unshown):
                self._copy(stream.saved, stream.unshown)
            t_ns, node = stream.partial_stamp or (0, None)
            if stream.partial and node is not None:
                self.log.add(t_ns, node, stream.name,
                             stream.partial.decode('utf-8', errors='replace'))
            os.close(stream.read_fd)
            os.close(stream.saved)
        self._console = None
        OutputCapture.active = None


class StreamLines:
    """
    What a node process wrote on its stdout and stderr, cut into lines on the trusted side.

    The bytes arrive from the process's pipes (:meth:`take`); :meth:`cut` (at the sync frames
    of sim_bridge.agent) turns what arrived so far into lines stamped with the sim time and
    node given: a line's stamp is that of the cut that saw its first byte. Whole lines are
    shown on this process's terminal as they are cut (when ``quiet``, all but the loggers'
    lines, as ``--disable-stdout-logs`` would). At most ``cap_bytes`` are kept; the rest are
    shown, counted, not kept. ``tail`` keeps the last lines (their first 1000 characters), to
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
            if not self.dropped:  # the kept lines are shown first, in order
                self.cut(*self.last_stamp)
            self.dropped += len(data) - room
            OutputCapture._copy(1 if stream == 'STDOUT' else 2, data[room:])

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
            OutputCapture._copy(1 if stream == 'STDOUT' else 2, line + b'\n')

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
    Write the runner's own ``text`` on stderr, around a capture in force.

    A node that closed stderr (``os.close(2)``, ``sys.stderr.close()``) costs the run nothing.
    """
    if OutputCapture.active is not None:
        OutputCapture.active.console(text)
        return
    try:
        sys.stderr.write(text)
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
