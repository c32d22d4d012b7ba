"""
One graded run in a child process of its own, bounded in wall-clock time and memory.

The grader never runs a student's code in its own process. For each scenario run it forks a
child from a server process that has imported rclpy, pybullet and the runner once
(:func:`fork_server`). The child (:func:`run_child`) first makes itself a session of its own
(the terminal's Ctrl-C goes to the grader only), sends its stdout and stderr to the run's
``log.txt``, works in a scratch directory with a trimmed environment
(:func:`trimmed_environment`) and a bounded address space; then it runs the scenario with
:func:`sim_bridge.grade.run_scenario` exactly as an in-process run does, sending its progress
in simulated seconds and, when it ends, the run's report over a pipe.

The parent (:class:`Child`) watches that pipe. When no simulated second has passed for
``Limits.stall_s`` of wall time, it sends SIGUSR1; when the run's wall-clock budget is used up,
SIGUSR2. The child turns either into :class:`sim_bridge.run.RunStopped`, raised wherever
Python is: inside a node's callback that ends the run as failed, naming the node, the callback
and the line, with every output written. A child that does not end within ``GRACE_S`` gets
SIGABRT (faulthandler writes every thread's Python stack to the log), then SIGKILL. A child
that dies without a result (``os._exit``, a segfault, the kernel's OOM killer) fails its run
with its exit status or signal and the end of its log.
"""

from dataclasses import dataclass, field
import faulthandler
import multiprocessing
import multiprocessing.connection
import multiprocessing.context
import os
from pathlib import Path
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from typing import Any

from sim_bridge.scenario import ScenarioRun

#: Wall seconds a run may take: BUDGET_BASE_S (start-up, writing outputs) plus this many per
#: simulated second (a run slower than real time is a node doing far too much per callback).
BUDGET_BASE_S = 60.0
BUDGET_PER_SIM_S = 1.0
#: Wall seconds without a simulated second passing before the run is stopped.
DEFAULT_STALL_S = 30.0
#: Wall seconds a child may take to start (rclpy, pybullet, the nodes' constructors) before
#: simulated time starts, if the stall limit is shorter.
DEFAULT_STARTUP_S = 30.0
DEFAULT_MEMORY_BYTES = 2 * 2 ** 30
#: Wall seconds a stopped run gets to write its outputs, and a SIGABRT for its stack dump.
GRACE_S = 10.0
ABORT_GRACE_S = 2.0
LOG_NAME = 'log.txt'
#: What the fork server imports once for every child (see :func:`fork_server`).
PRELOADED = ('sim_bridge.run', 'sim_bridge.bridge', 'sim_bridge.plot',
             'rclpy.executors', 'geometry_msgs.msg', 'sensor_msgs.msg', 'nav_msgs.msg')
#: Lines of a dead child's log kept in its report.
LOG_TAIL_LINES = 40
#: Variables a child keeps: what Python, ROS 2 and the numeric libraries need to run. Anything
#: else (credentials, tokens, the user's settings) stays with the grader.
KEPT_VARIABLES = ('PATH', 'LANG', 'LANGUAGE', 'TZ', 'PYTHONPATH', 'PYTHONHASHSEED',
                  'LD_LIBRARY_PATH', 'AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH',
                  'CMAKE_PREFIX_PATH', 'VIRTUAL_ENV', 'OMP_NUM_THREADS')
KEPT_PREFIXES = ('LC_', 'ROS_', 'RMW_', 'RCUTILS_', 'FASTRTPS_', 'FASTDDS_', 'OPENBLAS_')


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

    def budget_s(self, duration_s: float) -> float:
        """Return the wall-clock budget (s) of a run of ``duration_s`` simulated seconds."""
        if self.timeout_s is not None:
            return self.timeout_s
        return BUDGET_BASE_S + BUDGET_PER_SIM_S * duration_s


@dataclass(frozen=True)
class Job:
    """A run for a child: the scenario run, its output folder, its limits and runner options."""

    run: ScenarioRun
    out_dir: Path
    limits: Limits
    options: dict[str, Any] = field(default_factory=dict)


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
    """Return the last ``lines`` lines of a log file, or None when it is empty or missing."""
    try:
        text = path.read_text(encoding='utf-8', errors='replace')
    except OSError:
        return None
    return '\n'.join(text.rstrip().splitlines()[-lines:]) or None


class Child:
    """
    One run in a child process: started, watched, stopped when over its limits, and reported.

    :meth:`poll` reads the child's progress and enforces the limits; it returns the run's
    report dict (as ``RunReport.as_dict``) once the child has ended, else None.
    """

    def __init__(self, job: Job) -> None:
        self.job = job
        self.budget_s = job.limits.budget_s(job.run.scenario.duration_s)
        self.sim_s: float | None = None
        self.result: dict[str, Any] | None = None
        self.stop_reason: str | None = None
        self.stop_sent_at: float | None = None
        self.aborted = False
        job.out_dir.mkdir(parents=True, exist_ok=True)
        self.log_path = job.out_dir / LOG_NAME
        self.scratch = Path(tempfile.mkdtemp(prefix='lab-grade-'))
        context = fork_server()
        self.pipe, writer = context.Pipe(duplex=False)
        self.process = context.Process(
            target=run_child, name=f'grade {job.run.name}',
            args=(job, writer, self.log_path, self.scratch, trimmed_environment(self.scratch)))
        self.process.start()
        writer.close()
        self.started = self.progressed = time.monotonic()

    def fileno(self) -> int:
        """Return the progress pipe (for select)."""
        return self.pipe.fileno()

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
            return False
        return True

    def poll(self) -> dict[str, Any] | None:
        """Read progress, enforce the limits; return the report dict once the child ended."""
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
        """Ask a child over a limit to stop; abort, then kill, one that does not."""
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
            self.signal(signal.SIGKILL)

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

    def failure(self) -> dict[str, Any]:
        """Return the report of a child that ended without a result."""
        reason = exit_reason(self.process.exitcode)
        if self.stop_reason is not None:
            reason = f'{self.stop_reason}; the run did not stop when asked ({reason})'
        return {'error': reason, 'traceback': log_tail(self.log_path), 'metrics': None,
                'criteria': [], 'passed': False,
                'wall_time_s': time.monotonic() - self.started}

    def kill(self) -> None:
        """End the child now (the grader was interrupted) and clean up."""
        self.signal(signal.SIGKILL)
        self.process.join()
        self.close()

    def close(self) -> None:
        """Kill what is left of the process group, close the pipe, remove the scratch folder."""
        self.signal(signal.SIGKILL)
        self.pipe.close()
        self.process.join()
        shutil.rmtree(self.scratch, ignore_errors=True)


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


def run_child(job: Job, status: multiprocessing.connection.Connection, log: Path,
              scratch: Path, environ: dict[str, str]) -> None:
    """
    Run ``job`` in this process, the child (see the module docstring); send its report.

    First the child makes itself what the module docstring says: a session of its own, output
    to the ``log`` file, working directory ``scratch``, environment ``environ``, bounded memory.
    """
    os.setsid()
    log_fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
        os.dup2(log_fd, stream.fileno())
        stream.reconfigure(line_buffering=True)
    os.close(log_fd)
    os.chdir(scratch)
    os.environ.clear()
    os.environ.update(environ)
    resource.setrlimit(resource.RLIMIT_AS, (job.limits.memory_bytes,) * 2)
    faulthandler.enable()
    from sim_bridge.grade import RunReport, run_scenario
    from sim_bridge.run import RunStopped
    from sim_bridge.stepping import describe
    started = False

    def stop(signum: int, frame: Any) -> None:
        if signum == signal.SIGUSR1:
            raise RunStopped(f'no reply for {job.limits.stall_limit_s(started):g} s')
        raise RunStopped(f'wall-clock budget of {job.limits.budget_s(duration):g} s used up')

    def progress(sim_s: float, duration_s: float) -> None:
        nonlocal started
        started = True
        status.send(('progress', sim_s))

    duration = job.run.scenario.duration_s
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
    status.send(('result', report.as_dict()))
