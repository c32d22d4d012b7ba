"""
The child side of an isolated run: the forked process that runs one scenario run and reports.

sim_bridge.grading.isolate starts it from a fork server (:func:`fork_server`, which imports
the runner once for every child) and watches it; :func:`run_child` runs the job in a process
group of its own, ends whatever the student's code left running, and reports the run.
"""

import ctypes
import faulthandler
import multiprocessing
import multiprocessing.connection
import multiprocessing.context
import multiprocessing.forkserver
import os
from pathlib import Path
import re
import resource
import signal
import sys
import time
import traceback
from typing import Any, Iterator, NamedTuple

from sim_bridge.common.errors import RunStopped
from sim_bridge.grading.limits import Job
from sim_bridge.grading.runs import run_scenario, RunReport
from sim_bridge.runner.stepped_run import memory_limit
from sim_bridge.runner.stepping import describe


#: What the fork server imports once for every child (see :func:`fork_server`).
PRELOADED = ('sim_bridge.runner.run', 'sim_bridge.ros.bridge', 'sim_bridge.media.plot',
             'rclpy.executors', 'geometry_msgs.msg', 'sensor_msgs.msg', 'nav_msgs.msg')
#: prctl(2) options, from linux/prctl.h.
PR_SET_PDEATHSIG = 1
PR_SET_CHILD_SUBREAPER = 36
#: Rounds of killing what is left below a supervisor: each round kills one more generation.
CLEANUP_ROUNDS = 100
#: The share of its wall-clock budget a run's processes must have had in CPU time for its
#: failure at the budget to be its own (see :func:`not_its_own_budget`).
OWN_BUDGET_SHARE = 0.5


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


class ProcessStat(NamedTuple):
    """What /proc/<pid>/stat says of a process: its id, state, parent and process group."""

    pid: int
    state: bytes
    ppid: int
    pgrp: int


def process_stats() -> Iterator[ProcessStat]:
    """Yield the state, parent and process group of every process (read from /proc)."""
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            with open(f'/proc/{entry}/stat', 'rb') as stat:
                # pid (command) state ppid pgrp ...: the command may hold spaces and parentheses.
                state, ppid, pgrp = stat.read().rpartition(b')')[2].split()[:3]
            yield ProcessStat(int(entry), state, int(ppid), int(pgrp))
        except (OSError, ValueError):  # it ended meanwhile
            continue


def children() -> list[int]:
    """Return the process ids of the processes whose parent is this one."""
    parent = os.getpid()
    return [stat.pid for stat in process_stats() if stat.ppid == parent]


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
    resource.setrlimit(resource.RLIMIT_AS, (job.limits.address_space_bytes,) * 2)
    # The supervisor ignores SIGABRT; after its dump, faulthandler ends the run with it.
    signal.signal(signal.SIGABRT, signal.SIG_DFL)
    faulthandler.enable()
    started = out_of_budget = False

    def stop(signum: int, frame: Any) -> None:
        nonlocal out_of_budget
        if signum == signal.SIGUSR1:
            raise RunStopped(f'no reply for {job.limits.stall_limit_s(started):g} s')
        out_of_budget = True
        raise RunStopped(f'wall-clock budget of {budget_s:g} s used up')

    def progress(sim_s: float, duration_s: float) -> None:
        nonlocal started
        started = True
        status.send(('progress', sim_s))

    signal.signal(signal.SIGUSR1, stop)
    signal.signal(signal.SIGUSR2, stop)
    wall_start = time.perf_counter()
    try:
        report = run_scenario(job.run, job.out_dir, progress=progress,
                              on_scoring=lambda: status.send(('scoring', None)), **job.options)
    except BaseException as error:  # noqa: B902 a node's sys.exit() at import ends only its run
        report = RunReport(job.run, job.out_dir, [], None, describe(error),
                           time.perf_counter() - wall_start, traceback.format_exc())
    signal.signal(signal.SIGUSR1, signal.SIG_IGN)
    signal.signal(signal.SIGUSR2, signal.SIG_IGN)
    report.error = with_memory_limit(report.error)
    if out_of_budget:
        report.rerun = not_its_own_budget(tree_cpu_s(), budget_s)
    status.send(('result', report.as_dict()))


def tree_cpu_s() -> float:
    """Return the CPU time (s) of this process and of its descendants that have ended."""
    return sum(usage.ru_utime + usage.ru_stime for usage in (
        resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)))


def not_its_own_budget(cpu_s: float, budget_s: float) -> str | None:
    """
    Say why a run stopped at its wall-clock budget is run again next time, or None.

    A run whose processes had less than OWN_BUDGET_SHARE of its budget in CPU time (``cpu_s``,
    s) waited for the CPU, not for its own work (lockstep keeps one of its processes busy):
    the machine was busy (its neighbours' runs, another program), and the failure is not
    its own. (Where each run has a cpu control group, its neighbours cannot starve it.)
    """
    if cpu_s >= OWN_BUDGET_SHARE * budget_s:
        return None
    return (f'it had {cpu_s:.1f} s of CPU in its wall-clock budget of {budget_s:g} s: the '
            'machine was busy, so its result is not kept')


def with_memory_limit(error: str | None) -> str | None:
    """Return a run's error naming the memory limit when it is a MemoryError that does not."""
    if error is None or not re.search(r'\bMemoryError\b', error) or 'memory limit' in error:
        return error
    return f'{error} (memory limit {memory_limit()} reached)'
