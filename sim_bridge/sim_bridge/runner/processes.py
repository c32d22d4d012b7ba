"""
Run ROS 2 processes side by side as ``ros2 launch`` does, printing their lines as it prints them.

A :class:`ProcessSpec` is a process's name and command line; :class:`LiveRun` starts them,
prints what they write and stops them; :func:`run_live` is the whole of a live run
(sim_bridge.commands.live, and a runner's node run as a process, use it).

Output is ros2 launch's with ``output='screen'``: each line a child writes (stdout and stderr,
in the order written) is printed as it arrives, prefixed with the process's name,
``[wall_follow-2] [INFO] [1795499925.029450212] [wall_follow]: following the wall on the
right``; the lines of this module are launch's, ``[INFO] [sim_bridge-1]: process started with
pid [1234]``, ``[INFO] [wall_follow-2]: process has finished cleanly [pid 1235]`` or ``[ERROR]
[wall_follow-2]: process has died [pid 1235, exit code 1, cmd '...'].``

Stopping, at Ctrl-C or after ``--duration`` wall seconds: SIGINT to the processes in reverse
order of start, each waited for before the next, so the node's last zero command reaches a
simulator that still runs (the driving nodes send one when interrupted; SIGTERM would end them
without it). A process still running ``sigterm_timeout`` (5 s) after SIGINT gets SIGTERM, and
``sigkill_timeout`` (5 s) later SIGKILL, as launch does. Exit status: 0 when every process
ended cleanly (status 0) after being asked to; 1 when one ended before the run did (the others
are stopped, and the last line names it) or did not end cleanly; 2 for a bad command line.

Unlike launch, the children run in a session of their own: Ctrl-C in the terminal reaches this
process only, which stops them in order (launch's children get the terminal's SIGINT all at
once). SIGINT and SIGTERM are at their default actions in the children even when this process
was started with them ignored (in the background); on Linux each child also gets SIGINT if this
process dies without stopping it.

The pure parts, the command lines of a task and the lines printed, are plain functions;
:class:`LiveRun` runs processes, and :func:`run_live` is the whole command.
"""

import math
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from typing import Callable, Iterable, Mapping, NamedTuple, Sequence


#: The name of this module's own log lines (launch's are ``[launch]``).
LOGGER = 'live'
#: Wall seconds after SIGINT before SIGTERM, and after SIGTERM before SIGKILL (launch's).
SIGTERM_TIMEOUT_S = 5.0
SIGKILL_TIMEOUT_S = 5.0
#: Wall seconds the next process keeps running after one stopped: the zero command it sent
#: on the way out reaches the simulator and acts.
SETTLE_S = 0.3
#: Wall seconds to wait for a dead process's last output before reporting its end anyway.
OUTPUT_GRACE_S = 1.0
#: Longest wait (s) for output before checking the processes again.
POLL_S = 0.05
#: Most lines printed before checking the processes again.
MAX_LINES_PER_POLL = 1000
DISCOVERY_VARIABLE = 'ROS_AUTOMATIC_DISCOVERY_RANGE'

Output = Callable[[str], None]


class ProcessSpec(NamedTuple):
    """One process to start: its executable's name (for the prefix) and its command line."""

    executable: str
    cmd: tuple[str, ...]


# ---------------------------------------------------------------------------------------------
# The pure parts: lines printed, environments and command lines.

def process_names(specs: Sequence[ProcessSpec]) -> list[str]:
    """Return launch's names of ``specs``' processes: ``<executable>-<n>``, n from 1."""
    return [f'{spec.executable}-{number}' for number, spec in enumerate(specs, start=1)]


def prefixed(name: str, line: str) -> str:
    """Return a child's output ``line`` as launch prints it: ``[name] line``."""
    return f'[{name}] {line}'


def log_line(level: str, logger: str, message: str) -> str:
    """Return a line of launch's own log: ``[LEVEL] [logger]: message``."""
    return f'[{level}] [{logger}]: {message}'


def started_line(name: str, pid: int) -> str:
    """Return launch's line for a process that started."""
    return log_line('INFO', name, f'process started with pid [{pid}]')


def ended_line(name: str, pid: int, returncode: int, cmd: Sequence[str]) -> str:
    """Return launch's line for a process that ended (status 0: cleanly; else died)."""
    if returncode == 0:
        return log_line('INFO', name, f'process has finished cleanly [pid {pid}]')
    command = ' '.join(cmd)
    return log_line('ERROR', name, f'process has died [pid {pid}, exit code {returncode}, '
                                   f"cmd '{command}'].")


def signal_line(name: str, signal_name: str) -> str:
    """Return launch's line for a signal sent to a process."""
    return log_line('INFO', name, f"sending signal '{signal_name}' to process[{name}]")


def escalation_line(name: str, timeout_s: float, sent: str, next_signal: str) -> str:
    """Return launch's line for a process still running ``timeout_s`` (s) after ``sent``."""
    return log_line('ERROR', name, f"process[{name}] failed to terminate '{timeout_s:g}' seconds "
                                   f"after receiving '{sent}', escalating to '{next_signal}'")


def child_environment(base: Mapping[str, str]) -> tuple[dict[str, str], str | None]:
    """
    Return the environment of a live child made from ``base``, and a warning or None.

    Output line-buffered (Python's and rcutils' logging); discovery on across processes:
    ``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` becomes ``LOCALHOST`` (the warning says so). The rest,
    ``ROS_DOMAIN_ID`` included, is ``base``'s.
    """
    env = dict(base)
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '1'
    warning = None
    if env.get(DISCOVERY_VARIABLE, '').upper() == 'OFF':
        env[DISCOVERY_VARIABLE] = 'LOCALHOST'
        warning = (f'{DISCOVERY_VARIABLE}=OFF hides each process from every other: the live '
                   'processes run with LOCALHOST (this machine only)')
    return env, warning


def print_line(line: str) -> None:
    """Print ``line`` on stdout at once (the default output of a live run)."""
    print(line, flush=True)


# ---------------------------------------------------------------------------------------------
# Running processes.

def _child_setup() -> Callable[[], None] | None:
    """
    Return a function to run in each child before its program starts, or None.

    It sets SIGINT and SIGTERM back to their default action: a child inherits an ignored
    signal, and a command started in the background has SIGINT ignored, which would leave the
    driving nodes (whose Ctrl-C handler is Python's, installed only where SIGINT is not
    ignored) deaf to the SIGINT that stops them. On Linux the child also gets SIGINT when this
    process dies (prctl PR_SET_PDEATHSIG).
    """
    import ctypes
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        set_action = libc.signal
    except (OSError, AttributeError):
        return None
    set_action.restype = ctypes.c_void_p
    set_action.argtypes = (ctypes.c_int, ctypes.c_void_p)
    prctl = getattr(libc, 'prctl', None) if sys.platform.startswith('linux') else None
    pr_set_pdeathsig = 1

    def setup() -> None:
        for signal_number in (signal.SIGINT, signal.SIGTERM):
            set_action(int(signal_number), None)  # NULL: SIG_DFL
        if prctl is not None:
            prctl(pr_set_pdeathsig, int(signal.SIGINT))

    return setup


class LiveRun:
    """
    Start processes, print their output interleaved, stop them in order.

    ``specs``' processes are started by :meth:`start` with :func:`child_environment` of
    ``env`` (default: this process's). Each line they write, and each of launch's lines about
    them, goes to ``out`` as it comes (default: stdout). With ``on_line``, each process's
    stdout and stderr are read apart, and ``on_line(index, stream, line)`` ('STDOUT' or
    'STDERR') is called in a reader thread as each line arrives, before ``out`` prints it. As a
    context manager it stops every process still running when the block ends, however it ends.
    """

    def __init__(self, specs: Iterable[ProcessSpec], *, env: Mapping[str, str] | None = None,
                 out: Output = print_line, sigterm_timeout_s: float = SIGTERM_TIMEOUT_S,
                 sigkill_timeout_s: float = SIGKILL_TIMEOUT_S, settle_s: float = SETTLE_S,
                 on_line: Callable[[int, str, str], None] | None = None):
        self.specs = list(specs)
        self.names = process_names(self.specs)
        self.env, self.env_warning = child_environment(os.environ if env is None else env)
        self.out = out
        self.on_line = on_line
        self.sigterm_timeout_s = sigterm_timeout_s
        self.sigkill_timeout_s = sigkill_timeout_s
        self.settle_s = settle_s
        self.processes: list[subprocess.Popen] = []
        #: Exit status of each process that ended, by name.
        self.returncodes: dict[str, int] = {}
        self._lines: queue.Queue = queue.Queue()
        self._eof: set[int] = set()
        self._open_streams: dict[int, int] = {}
        self._exit_seen: dict[int, float] = {}
        self._stopping: set[int] = set()
        self._readers: list[threading.Thread] = []

    def __enter__(self) -> 'LiveRun':
        return self

    def __exit__(self, *exc_info) -> None:
        self.stop_all()

    def start(self) -> None:
        """Start every process in order; print launch's 'process started' line for each."""
        if self.env_warning:
            self.out(log_line('WARNING', LOGGER, self.env_warning))
        preexec = _child_setup()
        for index, (spec, name) in enumerate(zip(self.specs, self.names)):
            apart = self.on_line is not None
            process = subprocess.Popen(
                spec.cmd, env=self.env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                stderr=subprocess.PIPE if apart else subprocess.STDOUT,
                start_new_session=True, preexec_fn=preexec)
            self.processes.append(process)
            self.out(started_line(name, process.pid))
            streams = [('STDOUT', process.stdout), ('STDERR', process.stderr)][:1 + apart]
            self._open_streams[index] = len(streams)
            for stream_name, stream in streams:
                reader = threading.Thread(target=self._read, args=(index, stream_name, stream),
                                          name=f'live-output-{name}', daemon=True)
                reader.start()
                self._readers.append(reader)

    def _read(self, index: int, stream_name: str, stream) -> None:
        for raw in iter(stream.readline, b''):
            line = raw.decode('utf-8', errors='replace').rstrip('\r\n')
            if self.on_line is not None:
                self.on_line(index, stream_name, line)
            self._lines.put((index, line))
        stream.close()
        self._lines.put((index, None))

    def running(self) -> list[str]:
        """Return the names of the started processes whose end is not reported yet."""
        return [self.names[index] for index in range(len(self.processes))
                if self.names[index] not in self.returncodes]

    def pump(self, timeout_s: float) -> list[str]:
        """
        Print output and report ends for up to ``timeout_s`` (s) or until a process ends.

        Return the names of the processes whose end was reported in this call.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            ended = self._report_ends()
            remaining = deadline - time.monotonic()
            if ended or remaining <= 0.0:
                return ended
            try:
                index, line = self._lines.get(timeout=min(remaining, POLL_S))
            except queue.Empty:
                continue
            for count in range(MAX_LINES_PER_POLL):
                if count:
                    try:
                        index, line = self._lines.get_nowait()
                    except queue.Empty:
                        break
                if line is None:
                    self._open_streams[index] -= 1
                    if not self._open_streams[index]:
                        self._eof.add(index)
                else:
                    self.out(prefixed(self.names[index], line))

    def _report_ends(self) -> list[str]:
        ended = []
        now = time.monotonic()
        for index, process in enumerate(self.processes):
            name = self.names[index]
            if name in self.returncodes or process.poll() is None:
                continue
            seen = self._exit_seen.setdefault(index, now)
            # Its last lines first: they are still in the pipe until its end of file.
            if index in self._eof or now - seen >= OUTPUT_GRACE_S:
                self.returncodes[name] = process.returncode
                self.out(ended_line(name, process.pid, process.returncode, process.args))
                ended.append(name)
        return ended

    def wait(self, duration_s: float | None = None) -> str | None:
        """
        Print output for ``duration_s`` wall seconds (None: no limit) or until a process ends.

        Return the name of a process that ended on its own (not stopped here), or None when
        the time was up.
        """
        deadline = math.inf if duration_s is None else time.monotonic() + duration_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return None
            for name in self.pump(min(remaining, 1.0)):
                if self.names.index(name) not in self._stopping:
                    return name

    def stop(self, name: str) -> int | None:
        """
        Stop the process ``name`` as launch does: SIGINT, then SIGTERM, then SIGKILL.

        Each signal is sent only if the process still runs after the previous one's timeout;
        output keeps being printed meanwhile. A Ctrl-C here skips to the next signal. Return
        its exit status (None if it was never started).
        """
        index = self.names.index(name)
        if index >= len(self.processes):
            return None
        self._stopping.add(index)
        steps = [(signal.SIGINT, self.sigterm_timeout_s, 'SIGTERM'),
                 (signal.SIGTERM, self.sigkill_timeout_s, 'SIGKILL'),
                 (signal.SIGKILL, self.sigkill_timeout_s, None)]
        for signal_number, timeout_s, next_signal in steps:
            if name in self.returncodes:
                break
            self._signal(index, signal_number)
            deadline = time.monotonic() + timeout_s
            try:
                while name not in self.returncodes and time.monotonic() < deadline:
                    self.pump(deadline - time.monotonic())
            except KeyboardInterrupt:
                continue
            if name not in self.returncodes and next_signal is not None:
                self.out(escalation_line(name, timeout_s, signal_number.name, next_signal))
        return self.returncodes.get(name)

    def _signal(self, index: int, signal_number: signal.Signals) -> None:
        process = self.processes[index]
        if process.poll() is not None:
            return
        self.out(signal_line(self.names[index], signal_number.name))
        try:
            process.send_signal(signal_number)
        except ProcessLookupError:
            pass

    def stop_all(self) -> None:
        """Stop every running process, the last started first, letting each settle."""
        stopped_one = False
        for name in reversed(self.names[:len(self.processes)]):
            if name in self.returncodes:
                continue
            if stopped_one and self.settle_s > 0.0:
                try:
                    self.pump(self.settle_s)
                except KeyboardInterrupt:
                    pass
                if name in self.returncodes:
                    continue
            self.stop(name)
            stopped_one = True
        for reader in self._readers:
            reader.join(timeout=OUTPUT_GRACE_S)
        self.pump(0.0)

    def clean(self) -> bool:
        """Tell whether every started process ended with status 0."""
        return (len(self.returncodes) == len(self.processes)
                and all(code == 0 for code in self.returncodes.values()))


class _Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP received: stop as at Ctrl-C."""


def _raise_interrupt(signal_number, frame) -> None:
    raise _Interrupted(signal.Signals(signal_number).name)


def run_live(specs: Sequence[ProcessSpec], duration_s: float | None = None, *,
             env: Mapping[str, str] | None = None, out: Output = print_line,
             sigterm_timeout_s: float = SIGTERM_TIMEOUT_S,
             sigkill_timeout_s: float = SIGKILL_TIMEOUT_S,
             on_line: Callable[[int, str, str], None] | None = None) -> int:
    """
    Run ``specs``' processes for ``duration_s`` wall seconds (None: until Ctrl-C); stop them.

    ``on_line`` is :class:`LiveRun`'s (each line of each process, as it arrives).

    Return 0 when every process ended cleanly when asked to, 1 when one ended early (the last
    line names it) or any did not end cleanly. SIGTERM and SIGHUP stop the run as Ctrl-C does
    (in the main thread); Ctrl-C stops it even when it was started with SIGINT ignored (in
    the background), as launch's own handler does.
    """
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        handlers[signal.SIGINT] = signal.signal(signal.SIGINT, signal.default_int_handler)
        for signal_number in (signal.SIGTERM, signal.SIGHUP):
            handlers[signal_number] = signal.signal(signal_number, _raise_interrupt)
    ended = None
    try:
        with LiveRun(specs, env=env, out=out, sigterm_timeout_s=sigterm_timeout_s,
                     sigkill_timeout_s=sigkill_timeout_s, on_line=on_line) as run:
            try:
                run.start()
                ended = run.wait(duration_s)
            except KeyboardInterrupt as interrupt:
                message = (f'{interrupt} received' if isinstance(interrupt, _Interrupted)
                           else 'user interrupted with ctrl-c (SIGINT)')
                out(log_line('WARNING', LOGGER, message))
    finally:
        for signal_number, handler in handlers.items():
            signal.signal(signal_number, handler)
    if ended is not None:
        out(log_line('ERROR', LOGGER, f'{ended} ended before the run did (exit code '
                                      f'{run.returncodes[ended]}): stopped the others'))
        return 1
    if not run.clean():
        unclean = [name for name in run.names if run.returncodes.get(name) != 0]
        out(log_line('ERROR', LOGGER, f"{', '.join(unclean)} did not end cleanly"))
        return 1
    return 0
