"""
One graded run in a child process of its own, bounded in wall-clock time, memory and output.

The grader never runs a student's code in its own process. For each scenario run it forks a
child from a server process that has imported rclpy, pybullet and the runner once
(:func:`fork_server`). The child (:func:`run_child`) is a small supervisor: it makes itself a
session of its own (the terminal's Ctrl-C goes to the grader only), sends its stdout and
stderr into a pipe the grader drains into the run's ``log.txt`` (at most ``LOG_HEAD_BYTES``
of its beginning and ``LOG_TAIL_BYTES`` of its end, see :class:`CappedLog`), becomes the
subreaper of everything below it and forks the run itself. The run (:func:`run_job`) works in
a scratch directory with a trimmed environment (:func:`trimmed_environment`) and a bounded
address space; it runs the scenario with :func:`sim_bridge.grading.runs.run_scenario` (each node
file in a sandboxed process of its own, sim_bridge.runner.boundary.outside.node_sandbox), sending
its progress in simulated seconds and, when it ends, the run's report over a pipe. It then ends at
once, whatever threads a node left running (they are named in the report's
``metrics['warnings']``). However the run ends, the supervisor then kills
every process it started (a process in a session of its own or a double fork included: as a
subreaper, the supervisor inherits them) and exits with the run's status.

The parent (:class:`Child`) watches the pipes. When no simulated second has passed for
``Limits.stall_s`` of wall time while the nodes run, it sends SIGUSR1 (once they are stopped and
the run is scored, the time is the grader's own, never a node's stall); when the run's wall-clock
budget is used up, SIGUSR2. The run turns either into :class:`sim_bridge.runner.run.RunStopped`,
raised wherever Python is: inside a node's callback that ends the run as failed, naming the node,
the callback and the line, with every output written. A run that does not end within ``GRACE_S``
gets SIGABRT (faulthandler writes every thread's Python stack to the log), then is killed. A run
that dies without a result (``os._exit``, a segfault, the kernel's OOM killer) fails with its exit
status or signal and the end of its log.

A run stopped by a signal (SIGSTOP, SIGTSTP: its own, or anyone's) is not stalled: only its
wall-clock budget ends it, and then its supervisor is continued and told to end it. A run that
still has not ended a while after that is killed (SIGKILL): the batch never waits on it.

Nothing outlives the grader: the supervisor gets SIGTERM when the fork server dies, which it
does when the grader dies, however (SIGKILL included); the run is killed with its supervisor.
The runs' scratch folders are in the grader's scratch parent
(:func:`sim_bridge.runner.boundary.outside.sandbox_host.grader_folder`), whose lock the grader
holds as long as it lives: a grader removes only the parents whose lock it can take, those of
graders that have ended, whatever their process ids now name (a reused pid, another pid namespace
on a shared machine).
"""

import fcntl
import multiprocessing
import multiprocessing.connection
import multiprocessing.context
import multiprocessing.forkserver
import os
from pathlib import Path
import select
import shutil
import signal
import tempfile
import time
from typing import Any

from sim_bridge.grading.isolated_child import fork_server, process_stats, run_child
from sim_bridge.grading.limits import Job
from sim_bridge.grading.runs import LOG_NAME
from sim_bridge.runner.boundary.outside.sandbox import NO_NAMESPACES_VARIABLE
from sim_bridge.runner.boundary.outside.sandbox_host import grader_folder, remove_leftover_scratch

#: Wall seconds a stopped run gets to write its outputs, a SIGABRT for its stack dump, and its
#: supervisor to end it before it is killed.
GRACE_S = 10.0
ABORT_GRACE_S = 2.0
END_GRACE_S = 5.0
#: A run's log.txt keeps at most this many bytes of the beginning of its output (rclpy's and
#: the nodes' start-up lines, the first of a flood of warnings) and of its end (the traceback,
#: the stacks of a stopped run, the last lines before a crash); a line between them says how
#: much was cut. A node printing gigabytes writes 1 MiB.
LOG_HEAD_BYTES = 512 * 2 ** 10
LOG_TAIL_BYTES = 512 * 2 ** 10
#: Bytes the grader reads from a child's output pipe at once, and the pipe's size it asks for.
OUTPUT_CHUNK_BYTES = 2 ** 20
#: Chunks the grader reads from one child before looking at the others.
OUTPUT_CHUNKS_PER_POLL = 16
#: Lines of a dead child's log kept in its report, from at most its last LOG_TAIL_READ bytes.
LOG_TAIL_LINES = 40
LOG_TAIL_READ = 16 * 2 ** 10
#: Variables a child keeps: what Python, ROS 2 and the numeric libraries need to run, and
#: where Gazebo's models and worlds are (sim_bridge.common.paths looks a world's models up
#: there), and whether the grader turned the sandbox's namespaces off. Anything else
#: (credentials, tokens, the user's settings) stays with the grader.
KEPT_VARIABLES = ('PATH', 'LANG', 'LANGUAGE', 'TZ', 'PYTHONPATH', 'PYTHONHASHSEED',
                  'LD_LIBRARY_PATH', 'AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH',
                  'CMAKE_PREFIX_PATH', 'VIRTUAL_ENV', 'OMP_NUM_THREADS',
                  'GZ_SIM_RESOURCE_PATH', 'IGN_GAZEBO_RESOURCE_PATH', 'GAZEBO_MODEL_PATH',
                  'GAZEBO_RESOURCE_PATH', NO_NAMESPACES_VARIABLE)
KEPT_PREFIXES = ('LC_', 'ROS_', 'RMW_', 'RCUTILS_', 'FASTRTPS_', 'FASTDDS_', 'OPENBLAS_')
#: Process states (/proc/<pid>/stat) of a process stopped by a signal or a tracer.
STOPPED_STATES = (b'T', b't')


def trimmed_environment(scratch: Path, environ: dict[str, str] | None = None) -> dict[str, str]:
    """
    Return a child's environment, made from ``environ`` (default: this process's).

    It keeps KEPT_VARIABLES and KEPT_PREFIXES, puts HOME and TMPDIR in ``scratch``, makes
    output unbuffered and shares matplotlib's font cache with the grader.
    """
    environ = os.environ if environ is None else environ
    kept = {name: value for name, value in environ.items()
            if name in KEPT_VARIABLES or name.startswith(KEPT_PREFIXES)}
    cache = environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return {**kept, 'HOME': str(scratch), 'TMPDIR': str(scratch), 'PYTHONUNBUFFERED': '1',
            'MPLCONFIGDIR': environ.get('MPLCONFIGDIR') or os.path.join(cache, 'matplotlib')}


def exit_reason(returncode: int) -> str:
    """Say how a child ended: 'exit status 3', 'killed by SIGSEGV'."""
    if returncode < 0:
        try:
            return f'killed by {signal.Signals(-returncode).name}'
        except ValueError:
            return f'killed by signal {-returncode}'
    return f'exit status {returncode}'


def log_tail(path: Path, lines: int = LOG_TAIL_LINES) -> str | None:
    """
    Return the last ``lines`` lines of a log file, or None when it is empty or missing.

    Only the file's last LOG_TAIL_READ bytes are read (a line longer than that is cut).
    """
    try:
        with open(path, 'rb') as log:
            size = log.seek(0, os.SEEK_END)
            log.seek(max(0, size - LOG_TAIL_READ))
            data = log.read()
    except OSError:
        return None
    if size > LOG_TAIL_READ and b'\n' in data.rstrip():
        data = data[data.index(b'\n') + 1:]  # the first line read is the end of a longer one
    text = data.decode('utf-8', errors='replace')
    return '\n'.join(text.rstrip().splitlines()[-lines:]) or None


def format_bytes(count: int) -> str:
    """Return a number of bytes as a person reads it: '812 bytes', '3.5 MiB'."""
    for unit, size in (('GiB', 2 ** 30), ('MiB', 2 ** 20), ('KiB', 2 ** 10)):
        if count >= size:
            return f'{count / size:.1f} {unit}'
    return f'{count} bytes'


class CappedLog:
    """
    A run's log file, written from its output: at most its first ``head`` and last ``tail`` bytes.

    The beginning goes to the file as it comes (the log of a run that prints less than ``head``
    bytes is whole, and can be read while it runs); after that, the last ``tail`` bytes are
    kept in memory and :meth:`close` writes them after a line saying how much was cut.
    """

    def __init__(self, path: Path, head: int = LOG_HEAD_BYTES, tail: int = LOG_TAIL_BYTES):
        self.file = open(path, 'wb')
        self.head_room = head
        self.tail_bytes = tail
        self.tail = bytearray()
        self.cut = 0

    def write(self, data: bytes) -> None:
        """Add ``data`` (bytes the run printed) to the log."""
        if self.head_room > 0:
            head = data[:self.head_room]
            self.file.write(head)
            self.file.flush()
            self.head_room -= len(head)
            data = data[len(head):]
        self.tail += data
        excess = len(self.tail) - self.tail_bytes
        if excess > 0:
            del self.tail[:excess]
            self.cut += excess

    def close(self) -> None:
        """Write the end of the output kept in memory, and close the file."""
        if self.cut:
            self.file.write(f"\n[... {format_bytes(self.cut)} of output cut here: a run's log "
                            f'keeps the first {format_bytes(self.file.tell())} and the last '
                            f'{format_bytes(len(self.tail))} of it ...]\n'.encode())
        self.file.write(self.tail)
        self.file.close()


class Child:
    """
    One run in a child process: started, watched, stopped when over its limits, and reported.

    :meth:`poll` reads the child's output and progress and enforces the limits; it returns the
    run's report dict (as ``RunReport.as_dict``) once the child has ended, else None.
    """

    def __init__(self, job: Job) -> None:
        self.job = job
        self.budget_s = job.budget_s
        self.sim_s: float | None = None
        self.result: dict[str, Any] | None = None
        self.stop_reason: str | None = None
        self.stop_sent_at: float | None = None
        self.aborted = False
        job.out_dir.mkdir(parents=True, exist_ok=True)
        self.log_path = job.out_dir / LOG_NAME
        self.log = CappedLog(self.log_path)
        #: Why the log could not be written (a full disk), or None.
        self.log_failure: str | None = None
        #: True when the run was found stopped by a signal at its budget.
        self.halted = False
        #: True once the run's nodes are stopped and the grader scores it: no stall limit.
        self.scoring = False
        self.scratch = Path(tempfile.mkdtemp(prefix='run-', dir=grader_folder()))
        context = fork_server()
        self.pipe, writer = context.Pipe(duplex=False)
        # A pipe, not a file, takes the child's output: the grader writes what fits the cap
        # however much the child prints, and however it dies. (A Connection carries the pipe's
        # end to the child through the fork server; the bytes on it are the child's output.)
        self.output, output_writer = context.Pipe(duplex=False)
        os.set_blocking(self.output.fileno(), False)
        try:
            fcntl.fcntl(self.output.fileno(), fcntl.F_SETPIPE_SZ, OUTPUT_CHUNK_BYTES)
        except OSError:  # above the system's pipe-max-size: the default size works, slower
            pass
        # One fd for the grader's select: readable when the progress or the output pipe is.
        self.events = select.epoll()
        for connection in (self.pipe, self.output):
            self.events.register(connection.fileno(), select.EPOLLIN)
        self.process = context.Process(
            target=run_child, name=f'grade {job.run.name}',
            args=(job, writer, output_writer, self.scratch, trimmed_environment(self.scratch),
                  os.getpid()))
        self.process.start()
        writer.close()
        output_writer.close()
        self.started = self.progressed = time.monotonic()

    def fileno(self) -> int:
        """Return an fd that is readable when the child sent something (for select)."""
        return self.events.fileno()

    def read(self) -> bool:
        """Read what the child sent; return False once the pipe is closed."""
        try:
            while self.pipe.poll():
                kind, value = self.pipe.recv()
                if kind == 'progress':
                    self.sim_s = value
                    self.progressed = time.monotonic()
                elif kind == 'scoring':
                    self.scoring = True
                elif kind == 'result':
                    self.result = value
        except (EOFError, OSError):  # closed, or cut mid-message by a kill
            self.unregister(self.pipe)
            return False
        return True

    def read_output(self, chunks: int = OUTPUT_CHUNKS_PER_POLL) -> None:
        """Write up to ``chunks`` chunks of what the child printed to its log."""
        for _ in range(chunks):
            try:
                data = os.read(self.output.fileno(), OUTPUT_CHUNK_BYTES)
            except BlockingIOError:
                return
            if not data:
                self.unregister(self.output)
                return
            if self.log_failure is None:
                try:
                    self.log.write(data)
                except OSError as error:  # a full disk: the run goes on, its log is cut
                    self.log_failure = error.strerror or str(error)

    def unregister(self, connection: multiprocessing.connection.Connection) -> None:
        """Stop watching a closed pipe (select would find it readable for ever)."""
        try:
            self.events.unregister(connection.fileno())
        except (KeyError, OSError, ValueError):
            pass

    def poll(self) -> dict[str, Any] | None:
        """Read output and progress, enforce the limits; return the report once it ended."""
        self.read_output()
        open_pipe = self.read()
        if self.process.exitcode is None or open_pipe:
            self.enforce_limits(time.monotonic())
            if self.process.exitcode is None:
                return None
        self.read()
        report = self.result if self.result is not None else self.failure()
        self.close()
        return report

    def enforce_limits(self, now: float) -> None:
        """Ask a child over a limit to stop; abort, end, then kill a run that does not."""
        stall_s = self.job.limits.stall_limit_s(self.sim_s is not None)
        if self.stop_reason is None:
            if now - self.started > self.budget_s:
                reason = f'wall-clock budget of {self.budget_s:g} s used up'
                if stopped_group(self.process.pid):
                    # Stopped, it can write nothing: its supervisor ends it now.
                    self.stop_reason = (f'{reason}; the run was stopped (SIGSTOP) and never '
                                        'went on')
                    self.stop_sent_at = now - GRACE_S - ABORT_GRACE_S
                    self.aborted = self.halted = True
                else:
                    self.stop(signal.SIGUSR2, reason)
            elif now - self.progressed > stall_s and not self.scoring:
                if stopped_group(self.process.pid):  # not stalled: its budget decides
                    self.progressed = now
                else:
                    self.stop(signal.SIGUSR1, f'no reply for {stall_s:g} s')
        elif not self.aborted and now - self.stop_sent_at > GRACE_S:
            self.aborted = True
            self.signal(signal.SIGABRT)
        elif now - self.stop_sent_at > GRACE_S + ABORT_GRACE_S + END_GRACE_S:
            self.signal(signal.SIGKILL)  # the supervisor does not end it: nothing waits on it
            self.kill_supervisor()
        elif now - self.stop_sent_at > GRACE_S + ABORT_GRACE_S:
            self.end()

    def stop(self, signum: int, reason: str) -> None:
        """Ask the child to end its run for ``reason`` (SIGUSR1: stalled, SIGUSR2: over budget)."""
        self.stop_reason, self.stop_sent_at = reason, time.monotonic()
        self.signal(signum)

    def signal(self, signum: int) -> None:
        """Send ``signum`` to the child's process group (a node may have forked), or to it."""
        try:
            os.killpg(self.process.pid, signum)
        except ProcessLookupError:
            if self.process.exitcode is None:  # alive, but not yet in a session of its own
                try:
                    os.kill(self.process.pid, signum)
                except ProcessLookupError:
                    pass

    def end(self) -> None:
        """
        Have the supervisor kill the run and everything it started (see :func:`run_child`).

        The supervisor is continued first: a run may have stopped its whole process group.
        """
        for signum in (signal.SIGCONT, signal.SIGTERM):
            try:
                os.kill(self.process.pid, signum)
            except ProcessLookupError:
                pass

    def kill_supervisor(self) -> None:
        """Kill the supervisor (its run dies with it: its parent-death signal is SIGKILL)."""
        try:
            os.kill(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    def failure(self) -> dict[str, Any]:
        """Return the report of a child that ended without a result."""
        reason = exit_reason(self.process.exitcode)
        if self.halted and self.stop_reason is not None:
            reason = f'{self.stop_reason} ({reason})'
        elif self.stop_reason is not None:
            reason = f'{self.stop_reason}; the run did not stop when asked ({reason})'
        self.finish_log()
        return {'error': reason, 'traceback': log_tail(self.log_path), 'metrics': None,
                'criteria': [], 'passed': False,
                'wall_time_s': time.monotonic() - self.started}

    def kill(self) -> None:
        """End the child now (the grader was interrupted) and clean up."""
        self.end()
        self.process.join(ABORT_GRACE_S)
        self.close()

    def finish_log(self) -> None:
        """Write what is left of the child's output to its log, and close the log."""
        if not self.log.file.closed:
            # Bounded: a process that escaped the supervisor may still hold the pipe.
            self.read_output(chunks=2 + LOG_TAIL_BYTES // OUTPUT_CHUNK_BYTES)
            try:
                self.log.close()
            except OSError as error:
                self.log_failure = self.log_failure or error.strerror or str(error)
                self.log.file.close()

    def close(self) -> None:
        """
        Kill what is left of the process group, close the pipes, remove the scratch folders.

        The run's own, and the sandboxes' parent its killed child could not remove (its lock
        ended with it: sim_bridge.runner.boundary.outside.sandbox_host.remove_leftover_scratch).
        """
        self.signal(signal.SIGKILL)  # a supervisor that did not end when asked
        self.process.join()
        self.finish_log()
        self.pipe.close()
        self.output.close()
        self.events.close()
        shutil.rmtree(self.scratch, ignore_errors=True)
        remove_leftover_scratch(Path(tempfile.gettempdir()))


def stopped_group(group: int) -> bool:
    """Tell whether a process of process group ``group`` is stopped (by a signal or tracer)."""
    return any(stat.pgrp == group and stat.state in STOPPED_STATES for stat in process_stats())
