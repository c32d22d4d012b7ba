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
address space; it runs the scenario with :func:`sim_bridge.grading.run_scenario` exactly as an
in-process run does, sending its progress in simulated seconds and, when it ends, the run's
report over a pipe. It then ends at once, whatever threads a node left running (they are
named in the report's ``metrics['warnings']``). However the run ends, the supervisor then kills
every process it started (a process in a session of its own or a double fork included: as a
subreaper, the supervisor inherits them) and exits with the run's status.

The parent (:class:`Child`) watches the pipes. When no simulated second has passed for
``Limits.stall_s`` of wall time, it sends SIGUSR1; when the run's wall-clock budget is used up,
SIGUSR2. The run turns either into :class:`sim_bridge.run.RunStopped`, raised wherever
Python is: inside a node's callback that ends the run as failed, naming the node, the callback
and the line, with every output written. A run that does not end within ``GRACE_S`` gets
SIGABRT (faulthandler writes every thread's Python stack to the log), then is killed. A run
that dies without a result (``os._exit``, a segfault, the kernel's OOM killer) fails with its
exit status or signal and the end of its log.

Nothing outlives the grader: the supervisor gets SIGTERM when the fork server dies, which it
does when the grader dies, however (SIGKILL included); the run is killed with its supervisor.
The scratch folders are named after the grader's process id, and a grader removes those of
graders no longer running when it starts a run.
"""

import ctypes
from dataclasses import dataclass, field
import faulthandler
import fcntl
import multiprocessing
import multiprocessing.connection
import multiprocessing.context
import multiprocessing.forkserver
import os
from pathlib import Path
import re
import resource
import select
import shutil
import signal
import sys
import sysconfig
import tempfile
import time
import traceback
from typing import Any

from sim_bridge.grading import LOG_NAME, run_scenario, RunReport
from sim_bridge.process_run import NODE_START_TIMEOUT_S
from sim_bridge.scenario import ScenarioRun
from sim_bridge.targets import run_mode

#: Wall seconds a run may take: BUDGET_BASE_S (start-up, writing outputs) plus this many per
#: simulated second (a stepped run slower than real time is a node doing far too much per
#: callback).
BUDGET_BASE_S = 60.0
BUDGET_PER_SIM_S = 1.0
#: A node file run as its own process (sim_bridge.process_run) runs at real time, after its
#: process has joined the ROS graph (up to NODE_START_TIMEOUT_S): its budget allows this many
#: wall seconds per simulated second, for a loaded machine whose live simulator falls behind
#: the wall clock.
PROCESS_BUDGET_PER_SIM_S = 2.0
#: Wall seconds without a simulated second passing before the run is stopped.
DEFAULT_STALL_S = 30.0
#: Wall seconds a child may take to start (rclpy, pybullet, the nodes' constructors) before
#: simulated time starts, if the stall limit is shorter.
DEFAULT_STARTUP_S = 30.0
DEFAULT_MEMORY_BYTES = 2 * 2 ** 30
#: Wall seconds a stopped run gets to write its outputs, and a SIGABRT for its stack dump.
GRACE_S = 10.0
ABORT_GRACE_S = 2.0
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
#: What the fork server imports once for every child (see :func:`fork_server`).
PRELOADED = ('sim_bridge.run', 'sim_bridge.bridge', 'sim_bridge.plot',
             'rclpy.executors', 'geometry_msgs.msg', 'sensor_msgs.msg', 'nav_msgs.msg')
#: Lines of a dead child's log kept in its report, from at most its last LOG_TAIL_READ bytes.
LOG_TAIL_LINES = 40
LOG_TAIL_READ = 16 * 2 ** 10
#: Variables a child keeps: what Python, ROS 2 and the numeric libraries need to run, and
#: where Gazebo's models and worlds are (sim_bridge.paths looks a world's models up there).
#: Anything else (credentials, tokens, the user's settings) stays with the grader.
KEPT_VARIABLES = ('PATH', 'LANG', 'LANGUAGE', 'TZ', 'PYTHONPATH', 'PYTHONHASHSEED',
                  'LD_LIBRARY_PATH', 'AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH',
                  'CMAKE_PREFIX_PATH', 'VIRTUAL_ENV', 'OMP_NUM_THREADS',
                  'GZ_SIM_RESOURCE_PATH', 'IGN_GAZEBO_RESOURCE_PATH', 'GAZEBO_MODEL_PATH',
                  'GAZEBO_RESOURCE_PATH')
KEPT_PREFIXES = ('LC_', 'ROS_', 'RMW_', 'RCUTILS_', 'FASTRTPS_', 'FASTDDS_', 'OPENBLAS_')
#: Scratch folders are ``lab-grade-<grader's pid>-<random>`` in the temporary folder.
SCRATCH_PREFIX = 'lab-grade-'
SCRATCH_NAME = re.compile(re.escape(SCRATCH_PREFIX) + r'(\d+)-[a-z0-9_]+')
#: prctl(2) options, from linux/prctl.h.
PR_SET_PDEATHSIG = 1
PR_SET_CHILD_SUBREAPER = 36
#: Rounds of killing what is left below a supervisor: each round kills one more generation.
CLEANUP_ROUNDS = 100


@dataclass(frozen=True)
class Limits:
    """
    What a child run may use, in wall-clock time and memory.

    ``timeout_s`` (s) is the run's wall-clock budget (None: derived from its duration),
    ``stall_s`` (s) the wall time without simulated progress it may take, ``startup_s`` (s)
    what it may take to start if that is longer, ``memory_bytes`` its address space.
    """

    timeout_s: float | None = None
    stall_s: float = DEFAULT_STALL_S
    memory_bytes: int = DEFAULT_MEMORY_BYTES
    startup_s: float = DEFAULT_STARTUP_S

    def stall_limit_s(self, started: bool) -> float:
        """Return the wall seconds (s) a run may go without progress, before or once started."""
        return self.stall_s if started else max(self.stall_s, self.startup_s)

    def budget_s(self, duration_s: float, process: bool = False) -> float:
        """
        Return the wall-clock budget (s) of a run of ``duration_s`` simulated seconds.

        ``process``: the run's node file runs as its own process, at real time (see
        PROCESS_BUDGET_PER_SIM_S); otherwise it is stepped, far faster than real time.
        """
        if self.timeout_s is not None:
            return self.timeout_s
        if process:
            return (BUDGET_BASE_S + NODE_START_TIMEOUT_S
                    + PROCESS_BUDGET_PER_SIM_S * duration_s)
        return BUDGET_BASE_S + BUDGET_PER_SIM_S * duration_s


@dataclass(frozen=True)
class Job:
    """A run for a child: the scenario run, its output folder, its limits and runner options."""

    run: ScenarioRun
    out_dir: Path
    limits: Limits
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def budget_s(self) -> float:
        """
        Return the run's wall-clock budget (s): its limits' for its duration and run mode.

        The mode is read from the node files' source, as the runner reads it
        (sim_bridge.targets.run_mode): a file that cannot be stepped runs at real time.
        """
        scenario = self.run.scenario
        process = any(not run_mode(target).steppable for target in scenario.nodes)
        return self.limits.budget_s(scenario.duration_s, process)


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
        remove_leftover_scratch()
        self.scratch = Path(tempfile.mkdtemp(prefix=f'{SCRATCH_PREFIX}{os.getpid()}-'))
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
            self.log.write(data)

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
        """Ask a child over a limit to stop; abort, then end, a run that does not."""
        if self.stop_reason is None:
            if now - self.started > self.budget_s:
                self.stop(signal.SIGUSR2, f'wall-clock budget of {self.budget_s:g} s used up')
            elif now - self.progressed > self.job.limits.stall_limit_s(self.sim_s is not None):
                self.stop(signal.SIGUSR1, 'no reply for '
                          f'{self.job.limits.stall_limit_s(self.sim_s is not None):g} s')
        elif not self.aborted and now - self.stop_sent_at > GRACE_S:
            self.aborted = True
            self.signal(signal.SIGABRT)
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
        """Have the supervisor kill the run and everything it started (see :func:`run_child`)."""
        try:
            os.kill(self.process.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass

    def failure(self) -> dict[str, Any]:
        """Return the report of a child that ended without a result."""
        reason = exit_reason(self.process.exitcode)
        if self.stop_reason is not None:
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
            self.log.close()

    def close(self) -> None:
        """Kill what is left of the process group, close the pipes, remove the scratch folder."""
        self.signal(signal.SIGKILL)  # a supervisor that did not end when asked
        self.process.join()
        self.finish_log()
        self.pipe.close()
        self.output.close()
        self.events.close()
        shutil.rmtree(self.scratch, ignore_errors=True)


def remove_leftover_scratch(folder: str | None = None) -> None:
    """Remove the scratch folders that graders no longer running left in ``folder``."""
    folder = folder or tempfile.gettempdir()
    try:
        names = os.listdir(folder)
    except OSError:
        return
    for name in names:
        match = SCRATCH_NAME.fullmatch(name)
        if match and not process_exists(int(match.group(1))):
            shutil.rmtree(os.path.join(folder, name), ignore_errors=True)


def process_exists(pid: int) -> bool:
    """Tell whether a process ``pid`` exists (another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    return True


def fork_server() -> multiprocessing.context.ForkServerContext:
    """
    Return the context that forks children from a server process with PRELOADED imported.

    Importing rclpy, pybullet, numpy and matplotlib takes about a second; the server does it
    once, and each child starts as a fork of it. Nothing there has started a thread that a fork
    would lose: rclpy starts DDS only at ``rclpy.init``, in the child.
    """
    context = multiprocessing.get_context('forkserver')
    context.set_forkserver_preload(list(PRELOADED))
    return context


def prctl(option: int, value: int) -> None:
    """Set an attribute of this process with the prctl system call; OSError when it fails."""
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(option, value, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), f'prctl({option}, {value})')


class Ended(BaseException):
    """The supervisor's SIGTERM: the grader (or the fork server, dying with it) ends the run."""


def run_child(job: Job, status: multiprocessing.connection.Connection,
              output: multiprocessing.connection.Connection, scratch: Path,
              environ: dict[str, str], grader: int) -> None:
    """
    Supervise one run of ``job`` in this process, the child (see the module docstring).

    The child makes itself a session of its own with its output on the ``output`` pipe, and
    the subreaper of its descendants; it forks the run (:func:`run_job`) and waits for it.
    On SIGTERM, from the grader or when its parent (the fork server) dies, it kills the run.
    Then it kills whatever is left below it and ends as the run ended.
    """
    os.setsid()
    signal.signal(signal.SIGTERM, end_run)
    prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    # The fork server exits when every holder of its "alive" pipe has gone: the grader and
    # each child. A child lets go of it, so that the fork server ends with the grader (and the
    # SIGTERM above comes then). This child creates no process through the fork server.
    server = multiprocessing.forkserver._forkserver
    if getattr(server, '_forkserver_alive_fd', None) is not None:
        os.close(server._forkserver_alive_fd)
        server._forkserver_alive_fd = None
    if not process_exists(grader):  # it died before the line above
        os._exit(1)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
        os.dup2(output.fileno(), stream.fileno())
    output.close()
    prctl(PR_SET_CHILD_SUBREAPER, 1)
    # The grader's stop and abort reach the process group: they are for the run.
    for signum in (signal.SIGUSR1, signal.SIGUSR2, signal.SIGABRT):
        signal.signal(signum, signal.SIG_IGN)
    supervisor = os.getpid()
    run = os.fork()
    if run == 0:
        returncode = 1
        try:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
            if os.getppid() == supervisor:  # else the supervisor died before the line above
                run_job(job, status, scratch, environ)
                returncode = 0
        except BaseException:  # noqa: B902 the log says why the run ended without its result
            traceback.print_exc()
        finally:
            for stream in (sys.stdout, sys.stderr):
                stream.flush()
            os._exit(returncode)  # now: a thread a node left running does not keep it alive
    status.close()
    try:
        returncode = wait_for(run)
    except Ended:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        os.kill(run, signal.SIGKILL)
        returncode = wait_for(run)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    end_descendants()
    end_as(returncode)


def end_run(signum: int, frame: Any) -> None:
    """Turn the supervisor's SIGTERM into :class:`Ended`."""
    raise Ended


def wait_for(pid: int) -> int:
    """Return the exit code (negative: the signal) of child ``pid``, reaping orphans meanwhile."""
    while True:
        ended, status = os.wait()
        if ended == pid:
            return os.waitstatus_to_exitcode(status)


def children() -> list[int]:
    """Return the process ids of the processes whose parent is this one (read from /proc)."""
    parent = os.getpid()
    found = []
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            with open(f'/proc/{entry}/stat', 'rb') as stat:
                # pid (command) state ppid ...: the command may hold spaces and parentheses.
                ppid = int(stat.read().rpartition(b')')[2].split()[1])
        except (OSError, IndexError, ValueError):  # it ended meanwhile
            continue
        if ppid == parent:
            found.append(int(entry))
    return found


def end_descendants() -> None:
    """
    Kill every process below this one, a subreaper, and reap them.

    Each round kills the children; the children of a killed one become this process's own,
    and the next round kills them, until none is left.
    """
    for _ in range(CLEANUP_ROUNDS):
        pids = children()
        if not pids:
            return
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        for pid in pids:
            try:
                os.waitpid(pid, 0)
            except ChildProcessError:
                pass


def end_as(returncode: int) -> None:
    """End this process as the run ended: with its exit status, or killed by its signal."""
    if returncode < 0:
        signal.signal(-returncode, signal.SIG_DFL)
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # the run dumped its own core
        os.kill(os.getpid(), -returncode)
    os._exit(returncode if returncode >= 0 else 128 - returncode)


def run_job(job: Job, status: multiprocessing.connection.Connection, scratch: Path,
            environ: dict[str, str]) -> None:
    """
    Run ``job`` in this process, the run (see the module docstring), and send its report.

    First it makes itself what the module docstring says: working directory ``scratch``,
    environment ``environ``, bounded memory.
    """
    budget_s = job.budget_s  # as the supervisor's parent has it: read before the chdir
    for stream in (sys.stdout, sys.stderr):
        stream.reconfigure(line_buffering=True)
    os.chdir(scratch)
    os.environ.clear()
    os.environ.update(environ)
    resource.setrlimit(resource.RLIMIT_AS, (job.limits.memory_bytes,) * 2)
    # The supervisor ignores SIGABRT; after its dump, faulthandler ends the run with it.
    signal.signal(signal.SIGABRT, signal.SIG_DFL)
    faulthandler.enable()
    from sim_bridge.run import RunStopped
    from sim_bridge.stepping import describe
    started = False

    def stop(signum: int, frame: Any) -> None:
        if signum == signal.SIGUSR1:
            raise RunStopped(f'no reply for {job.limits.stall_limit_s(started):g} s')
        raise RunStopped(f'wall-clock budget of {budget_s:g} s used up')

    def progress(sim_s: float, duration_s: float) -> None:
        nonlocal started
        started = True
        status.send(('progress', sim_s))

    signal.signal(signal.SIGUSR1, stop)
    signal.signal(signal.SIGUSR2, stop)
    wall_start = time.perf_counter()
    try:
        report = run_scenario(job.run, job.out_dir, progress=progress, **job.options)
    except BaseException as error:  # noqa: B902 a node's sys.exit() at import ends only its run
        report = RunReport(job.run, job.out_dir, [], None, describe(error),
                           time.perf_counter() - wall_start, traceback.format_exc())
    signal.signal(signal.SIGUSR1, signal.SIG_IGN)
    signal.signal(signal.SIGUSR2, signal.SIG_IGN)
    report.error = with_memory_limit(report.error)
    status.send(('result', report.as_dict()))


def with_memory_limit(error: str | None) -> str | None:
    """Return a run's error naming the memory limit when it is a MemoryError that does not."""
    from sim_bridge.run import memory_limit
    if (error is None or not re.search(r'\bMemoryError\b', error) or 'memory limit' in error
            or memory_limit() is None):
        return error
    return f'{error} (memory limit {memory_limit()} reached)'


def is_standard_library(filename: str) -> bool:
    """Tell whether a Python file is part of the standard library (not an installed package)."""
    paths = sysconfig.get_paths()
    return (filename.startswith(paths['stdlib'] + os.sep)
            and not filename.startswith((paths['purelib'] + os.sep, paths['platlib'] + os.sep)))
