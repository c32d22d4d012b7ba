"""
The container a student's code runs in: its own identity, files, network, limits and end.

A :class:`Sandbox` holds one run. Its processes (started with :meth:`Sandbox.popen`) see a
private, size-limited copy of the student's files as their working folder and HOME, the Python
and ROS installation read-only, the kit's ``sim_bridge`` package read-only (the stepping agent
lives there), and nothing else of the instructor's: not the kit's reference nodes (``scan_pkg``
is hidden), not scenarios, other submissions, outputs or the grader's environment. How much of
that holds depends on what the machine allows; :func:`isolation_mode` finds out once:

- as root (Gradescope, CI, containers), bubblewrap (``bwrap``, Debian's ``bubblewrap``) makes
  pid, network, IPC, UTS and mount namespaces, and the run drops to a dedicated unprivileged
  uid/gid (one of ``UID_COUNT`` from ``UID_BASE``, one per concurrent run on the machine,
  leased with a lock file), with a memory and pids control group on its whole tree where the
  kernel offers one (cgroup v2 or v1);
- as root where bwrap cannot make namespaces (Docker's default seccomp profile refuses them),
  or where the grader's environment sets NO_NAMESPACES_VARIABLE (to try that mode on a machine
  that has namespaces; a run's environment never holds it): the dedicated uid only, said
  loudly ("PARTLY sandboxed"); what a run executes and reads must then be reachable by other
  users (:func:`unreachable_by_others`), or its sandbox says why not in one line
  (:class:`SandboxError`);
- as an ordinary user, bubblewrap in a user namespace of its own;
- otherwise "NOT sandboxed: <why>", never silently (:attr:`Sandbox.isolation`).

Every process of a run gets rlimits (address space, processes, CPU time, file size) set by a
small launcher (``LAUNCHER``) before it runs anything of the student's. :meth:`Sandbox.close`
ends every process the run started, whatever it did (a pid namespace dies with its first
process; a cgroup and a dedicated uid are swept until empty), and removes the scratch folder.
"""

from dataclasses import dataclass, fields
import functools
import json
import os
from pathlib import Path
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from typing import Mapping, Sequence

from sim_bridge.runner.boundary.outside.kit_answers import grader_key_files
from sim_bridge.runner.boundary.outside.sandbox_host import (
    ANSWERS_GID, close_to_runs, END_TIMEOUT_S, grader_folder, kill_uid, read_lines, RunCgroup,
    SandboxError, SCRATCH_PREFIX, uid_processes, UidLease, unreachable_by_others)
from sim_bridge.runner.boundary.outside.sandbox_view import (
    hidden_mounts, hidden_package_folders, parent_folders, python_roots, system_mounts)
from sim_bridge.runner.boundary.outside.scratch import clean_environment, copy_student_files

#: Where a bwrap run's process finds the host copy of the student's files, read-only; the
#: launcher copies them into the run's size-limited scratch tmpfs.
FILES_MOUNT = '/run/lab-files'
#: Namespaces every bwrap run gets; an ordinary user's also gets a user namespace.
NAMESPACES = ('--unshare-ipc', '--unshare-pid', '--unshare-net', '--unshare-uts',
              '--unshare-cgroup-try')
#: The only capabilities root keeps in its sandbox, for the launcher to hand the run's
#: folders to the run's uid and drop to it (a setuid clears them all).
LAUNCHER_CAPS = ('CAP_SETUID', 'CAP_SETGID', 'CAP_CHOWN')
#: Seconds of CPU past ``cpu_s`` before the kernel's SIGKILL (SIGXCPU comes at ``cpu_s``).
CPU_HARD_GRACE_S = 1
#: Address space (bytes) a process gets beyond ``memory_bytes``: reserved, not used (an rclpy
#: node with Fast DDS reserves ~600 MiB of thread stacks and arenas for ~70 MiB used).
ADDRESS_SPACE_SLACK_BYTES = 2 ** 30
#: Above any limit a machine can honour (and below the kernel's RLIM_INFINITY).
LARGEST_LIMIT = 1e15
#: prctl(2)'s PR_SET_NO_NEW_PRIVS: no setuid binary gives a run its privileges back.
PR_SET_NO_NEW_PRIVS = 38
#: Set (to anything but '') in the grader's environment, runs get no namespaces: as root the
#: dedicated uid only (PARTLY sandboxed), as an ordinary user nothing (NOT sandboxed).
NO_NAMESPACES_VARIABLE = 'LAB_SANDBOX_NO_NAMESPACES'

#: The Python that runs LAUNCHER (any Python 3 a run's uid can execute).
LAUNCHER_PYTHON = sys.executable
#: Run by ``python -I -S`` as a run's first process, with a JSON spec and the command: sets the
#: rlimits, hands the run's folders to its uid and drops to it, copies the student's files into
#: the scratch tmpfs, and executes the command there.
LAUNCHER = """
import ctypes, json, os, resource, shutil, sys
spec = json.loads(sys.argv[1])
for name, soft, hard in spec["rlimits"]:
    resource.setrlimit(getattr(resource, name), (soft, hard))
if spec["uid"] is not None:
    for path in spec["own"]:
        os.chown(path, spec["uid"], spec["gid"])
    os.setgroups(spec["groups"])
    os.setgid(spec["gid"])
    os.setuid(spec["uid"])
ctypes.CDLL(None).prctl(%d, 1, 0, 0, 0)
if spec["copy_from"]:
    shutil.copytree(spec["copy_from"], spec["scratch"], symlinks=True, dirs_exist_ok=True)
os.chdir(spec["scratch"])
os.execvp(sys.argv[2], sys.argv[2:])
""" % PR_SET_NO_NEW_PRIVS


@dataclass(frozen=True)
class SandboxLimits:
    """
    What a whole run (its process tree) may use.

    ``memory_bytes`` (bytes): memory of the whole tree where a cgroup holds it (each process's
    address space is limited to it plus ADDRESS_SPACE_SLACK_BYTES in any case); ``pids``:
    processes and threads; ``cpu_s`` (s of CPU) per process;
    ``file_bytes`` (bytes): size of any file written; ``scratch_bytes`` (bytes): the scratch
    folder's size, and /tmp's and /dev/shm's each, in a bwrap run; ``wall_s`` (s): wall time
    from the first process's start, after which everything of the run is killed.
    """

    memory_bytes: int = 512 * 2 ** 20
    pids: int = 64
    cpu_s: float = 300.0
    file_bytes: int = 64 * 2 ** 20
    scratch_bytes: int = 128 * 2 ** 20
    wall_s: float = 1800.0

    def __post_init__(self) -> None:
        """Refuse, in one line, a limit that is not a positive number the kernel can hold."""
        for limit in fields(self):
            value = getattr(self, limit.name)
            whole = limit.type in (int, 'int')  # bytes and pids: whole numbers
            kind = (int,) if whole else (int, float)
            if (isinstance(value, bool) or not isinstance(value, kind)
                    or not 0 < value < LARGEST_LIMIT):
                raise ValueError(f'sandbox limit {limit.name} must be a positive '
                                 f'{"whole " if whole else ""}number below {LARGEST_LIMIT:.0e}, '
                                 f'not {value!r}')

    def rlimits(self, uid_counted: bool) -> list[tuple[str, int, int]]:
        """
        Return the launcher's rlimits as (resource name, soft, hard).

        ``uid_counted``: the run's processes are counted under a uid (or user namespace) of
        its own, so RLIMIT_NPROC bounds the run and not the grader's user.
        """
        cpu = max(1, round(self.cpu_s))
        space = self.memory_bytes + ADDRESS_SPACE_SLACK_BYTES
        limits = [('RLIMIT_AS', space, space),
                  ('RLIMIT_CPU', cpu, cpu + CPU_HARD_GRACE_S),
                  ('RLIMIT_FSIZE', self.file_bytes, self.file_bytes),
                  ('RLIMIT_CORE', 0, 0)]
        if uid_counted:
            limits.append(('RLIMIT_NPROC', self.pids, self.pids))
        return limits


@dataclass(frozen=True)
class IsolationMode:
    """
    How this machine isolates runs: ``kind`` ('bwrap-root', 'bwrap-user', 'uid', 'none').

    ``bwrap_program`` is the path of the bubblewrap program found on this process's PATH (run
    by its path: a run's launcher has a PATH of its own).
    """

    kind: str
    why: str = ''
    bwrap_program: str = ''

    @property
    def bwrap(self) -> bool:
        """Tell whether runs go into bubblewrap's namespaces."""
        return self.kind.startswith('bwrap')

    @property
    def dedicated_uid(self) -> bool:
        """Tell whether each run drops to a uid of its own (the grader is root)."""
        return self.kind in ('bwrap-root', 'uid')


@functools.lru_cache(maxsize=None)
def isolation_mode() -> IsolationMode:
    """Find out once what isolation this machine allows (runs bwrap once, ~10 ms)."""
    root = os.geteuid() == 0
    bwrap = shutil.which('bwrap')
    if os.environ.get(NO_NAMESPACES_VARIABLE):
        why = f'namespaces turned off by {NO_NAMESPACES_VARIABLE}'
    elif bwrap is None:
        why = 'bubblewrap is not installed (apt-get install bubblewrap)'
    else:
        probe = [bwrap, *NAMESPACES, *([] if root else ['--unshare-user']),
                 '--ro-bind', '/', '/', 'true']
        try:
            done = subprocess.run(probe, capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired) as error:
            why = f'bwrap did not run ({error})'
        else:
            if done.returncode == 0:
                return IsolationMode('bwrap-root' if root else 'bwrap-user',
                                     bwrap_program=bwrap)
            why = 'bwrap cannot make namespaces here: ' + (
                done.stderr.strip().splitlines() or [f'exit status {done.returncode}'])[-1]
    return IsolationMode('uid' if root else 'none', why)


class Sandbox:
    """
    One run's container (see the module docstring); a context manager, closed on exit.

    ``student_files`` maps a name in the scratch folder (``'wall_follow.py'``, ``'pkg/'``)
    to the file or folder to copy there; ``readable`` are more paths the run may read (the
    agent's files), read-only at the same place; ``library`` are package folders the run may
    read and import (the kit's scan_pkg, from where the grader imports it);
    ``reference_nodes``: the kit's reference nodes are not hidden there (a run of the kit's
    own nodes); ``hidden_files`` are files and folders the run sees empty (the kit's answers:
    sim_bridge.runner.boundary.outside.kit_answers), or, without namespaces, cannot read
    (:func:`close_to_runs`).
    :attr:`scratch` is the host folder with the copy; in a bwrap run, the run's working folder
    at that same path is a tmpfs of ``limits.scratch_bytes`` seeded from it (what the run
    writes stays in the sandbox).
    :attr:`isolation` says in one line how the run is isolated, or that it is NOT.
    """

    def __init__(self, student_files: Mapping[str, Path], limits: SandboxLimits = SandboxLimits(),
                 *, readable: Sequence[Path] = (), library: Sequence[Path] = (),
                 reference_nodes: bool = False, hidden_files: Sequence[str] = ()) -> None:
        self.limits = limits
        self.library = [Path(os.path.realpath(folder)) for folder in library]
        self.reference_nodes = reference_nodes
        self.hidden_files = list(hidden_files)
        self.mode = isolation_mode()
        self.readable = [os.path.realpath(path) for path in [*readable, *self.library]]
        self.processes: list[subprocess.Popen] = []
        self.inits: list[int] = []  # pidfds of the first process of each pid namespace
        self.timer: threading.Timer | None = None
        self.timed_out = False
        self.closed = False
        self.cgroup: RunCgroup | None = None
        self.lease: UidLease | None = None
        self.uid: int | None = None
        self.scratch = Path(tempfile.mkdtemp(prefix='run-', dir=grader_folder()))
        try:
            if self.mode.dedicated_uid:
                self.lease = UidLease()
                self.uid = self.lease.uid
            if self.mode.kind == 'uid':
                close_to_runs(self.hidden_files)  # not the grader's key (kit_answers)
            copy_student_files(student_files, self.scratch, limits.scratch_bytes)
            memory = self.limit_memory()
        except BaseException:
            self.close()
            raise
        self.isolation = self.describe(memory)

    def check_reachable(self, program: str) -> None:
        """
        Raise SandboxError unless the run's uid reaches what a command needs, no namespaces.

        The launcher's Python, ``program`` (the command's) and ``readable``: without a mount
        namespace the run sees them through the host's folders, as any other user would (with
        namespaces, they are mounted where the run reaches them: nothing to check).
        """
        if self.mode.kind != 'uid':
            return
        for path in dict.fromkeys([LAUNCHER_PYTHON, shutil.which(program) or program,
                                   *self.readable]):
            why = unreachable_by_others(path)
            if why:
                raise SandboxError(
                    f'PARTLY sandboxed: uid {self.uid} (no namespaces) cannot reach {path}: '
                    f'{why}; install the kit and its Python where other users can read them '
                    "(as the autograder's setup.sh does, in a venv of /usr/bin/python3)")

    def limit_memory(self) -> str:
        """Hand the scratch to the run's uid, make its cgroup if root; say how memory is held."""
        per_process = (f'memory {self.limits.memory_bytes // 2 ** 20} MiB per process, '
                       f'{self.limits.pids} processes')
        if self.uid is None:
            return per_process + ' (no cgroup as an ordinary user)'
        for folder, _, files in os.walk(self.scratch):
            for path in [folder, *(os.path.join(folder, name) for name in files)]:
                os.lchown(path, self.uid, self.uid)
        try:
            self.cgroup = RunCgroup(f'{SCRATCH_PREFIX}{self.uid}', self.limits.memory_bytes,
                                    self.limits.pids)
        except OSError as error:
            return f'{per_process} (no cgroup: {error})'
        return (f'{self.cgroup.kind}: memory {self.limits.memory_bytes // 2 ** 20} MiB and '
                f'{self.limits.pids} processes for the whole run'
                + (', a fair share of the CPU' if self.cgroup.cpu else ''))

    def describe(self, memory: str) -> str:
        """Return :attr:`isolation`'s line, from the mode and how memory is held."""
        namespaces = 'pid/net/ipc/uts/mount namespaces'
        if self.mode.kind == 'bwrap-root':
            return f'bubblewrap: uid {self.uid}, {namespaces}, {memory}'
        if self.mode.kind == 'bwrap-user':
            return f'bubblewrap: user namespace of uid {os.getuid()}, {namespaces}, {memory}'
        if self.mode.kind == 'uid':
            return (f'PARTLY sandboxed: uid {self.uid} only, no namespaces ({self.mode.why}): '
                    "the run can read world-readable files (not the kit's answers) and use the "
                    f'network; {memory}')
        return f'NOT sandboxed: {self.mode.why}'

    def environment(self, extra: Mapping[str, str] = {}) -> dict[str, str]:
        """Return the run's clean environment: :func:`clean_environment` in its scratch."""
        return clean_environment(self.scratch, extra, self.library)

    @property
    def sandboxed(self) -> bool:
        """Tell whether runs are fully isolated (namespaces), not partly or not at all."""
        return self.mode.bwrap

    def __enter__(self) -> 'Sandbox':
        """Return the sandbox."""
        return self

    def __exit__(self, *exc_info: object) -> None:
        """Close the sandbox."""
        self.close()

    def launcher(self, argv: Sequence[str]) -> list[str]:
        """Return the command that starts ``argv`` through LAUNCHER, with its JSON spec."""
        root_in_bwrap = self.mode.kind == 'bwrap-root'
        answers = self.reference_nodes and not self.hidden_files  # a run of the kit's nodes
        spec = {'rlimits': self.limits.rlimits(uid_counted=self.mode.kind != 'none'),
                'uid': self.uid, 'gid': self.uid, 'scratch': str(self.scratch),
                'groups': [ANSWERS_GID] if answers else [],
                'own': [str(self.scratch), '/tmp', '/dev/shm'] if root_in_bwrap else [],
                'copy_from': FILES_MOUNT if self.mode.bwrap else None}
        return [LAUNCHER_PYTHON, '-I', '-S', '-c', LAUNCHER, json.dumps(spec), *argv]

    def bwrap_arguments(self, info_fd: int) -> list[str]:
        """Return bwrap's options for this run (the command follows them)."""
        size = str(self.limits.scratch_bytes)
        roots = python_roots()
        arguments = ['--die-with-parent', '--new-session', *NAMESPACES, '--hostname', 'sandbox']
        if self.mode.kind == 'bwrap-user':
            arguments.append('--unshare-user')
        else:
            arguments += ['--cap-drop', 'ALL']
            for capability in LAUNCHER_CAPS:
                arguments += ['--cap-add', capability]
        arguments += ['--proc', '/proc', '--dev', '/dev', '--size', size, '--tmpfs', '/dev/shm',
                      '--size', size, '--tmpfs', '/tmp', *system_mounts()]
        binds = [*roots, *self.readable, str(self.scratch), FILES_MOUNT]
        for folder in parent_folders(binds):
            arguments += ['--perms', '0755', '--dir', folder]
        for path in [*roots, *self.readable]:
            arguments += ['--ro-bind', path, path]
        hidden = [] if self.reference_nodes else hidden_package_folders([*roots, *self.readable])
        for folder in hidden:
            arguments += ['--tmpfs', folder, '--remount-ro', folder]
        arguments += hidden_mounts([*self.hidden_files, *grader_key_files()],
                                   [*roots, *self.readable])
        return arguments + ['--ro-bind', str(self.scratch), FILES_MOUNT, '--size', size,
                            '--tmpfs', str(self.scratch), '--info-fd', str(info_fd)]

    def popen(self, argv: Sequence[str], env: Mapping[str, str], pass_fds: Sequence[int] = (),
              **popen_kwargs) -> subprocess.Popen:
        """
        Start ``argv`` in the sandbox, in the scratch folder, with exactly ``env``.

        ``pass_fds`` are the fds the run inherits (its channels to the trusted side); other
        ``popen_kwargs`` go to subprocess.Popen. Call it from a thread that lives as long as
        the run: bwrap's --die-with-parent ends the run with the thread that started it.
        """
        if self.closed:
            raise RuntimeError('the sandbox is closed')
        self.check_reachable(argv[0])
        command = self.launcher(argv)
        info_read = info_write = None
        if self.mode.bwrap:
            info_read, info_write = os.pipe()
            command = [self.mode.bwrap_program, *self.bwrap_arguments(info_write), '--',
                       *command]
        if self.cgroup is not None:
            command = self.cgroup.joining(command)
        try:
            process = subprocess.Popen(
                command, env=dict(env), cwd=popen_kwargs.pop('cwd', '/'),
                pass_fds=[*pass_fds, *([info_write] if info_write is not None else [])],
                **popen_kwargs)
        finally:
            if info_write is not None:
                os.close(info_write)
        self.processes.append(process)
        if info_read is not None:
            self.watch_namespace(process, info_read)
        if self.timer is None:
            self.timer = threading.Timer(self.limits.wall_s, self.expire)
            self.timer.daemon = True
            self.timer.start()
        return process

    def watch_namespace(self, process: subprocess.Popen, info_read: int) -> None:
        """Keep a pidfd of the first process of ``process``'s pid namespace (bwrap's info)."""
        with os.fdopen(info_read, 'rb') as info:
            data = info.read()  # bwrap writes it once its child exists, then closes it
        try:
            pid = json.loads(data)['child-pid']
            pidfd = os.pidfd_open(pid)
        except (ValueError, KeyError, ProcessLookupError):  # bwrap failed, or it ended
            return
        if parent_pid(pid) == process.pid:  # the same process, not a pid reused since
            self.inits.append(pidfd)
        else:
            os.close(pidfd)

    def expire(self) -> None:
        """End the run: its wall time ``limits.wall_s`` is used up."""
        self.timed_out = True
        self.kill()

    def kill(self) -> None:
        """SIGKILL every process of the run, a daemon in a session of its own included."""
        for process in self.processes:
            process.kill()
        for pidfd in self.inits:
            try:
                signal.pidfd_send_signal(pidfd, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self.cgroup is not None:
            self.cgroup.kill()
        if self.uid is not None:
            kill_uid(self.uid)

    def alive(self) -> set[int]:
        """List the pids of the run's live processes: its uid's, its cgroup's."""
        alive = set(self.cgroup.pids()) if self.cgroup else set()
        alive.update(uid_processes(self.uid) if self.uid is not None else ())
        alive.update(process.pid for process in self.processes if process.poll() is None)
        return alive

    def memory_peak_bytes(self) -> int | None:
        """Return the run's peak memory (bytes) as its cgroup counted it (None: no cgroup)."""
        return self.cgroup.peak_bytes() if self.cgroup else None

    def close(self) -> None:
        """End every process the run started, whatever it did, and remove its scratch."""
        if self.closed:
            return
        self.closed = True
        if self.timer is not None:
            self.timer.cancel()
        try:
            self.kill()
            for process in self.processes:
                process.wait(END_TIMEOUT_S)
            for pidfd in self.inits:  # readable once the namespace's processes are gone
                select.select([pidfd], [], [], END_TIMEOUT_S)
                os.close(pidfd)
        finally:
            if self.cgroup is not None:
                self.cgroup.remove()
            shutil.rmtree(self.scratch, ignore_errors=True)
            if self.lease is not None:
                self.lease.release()


def parent_pid(pid: int) -> int | None:
    """Return the parent's pid of process ``pid`` (None once it has ended)."""
    for line in read_lines(Path(f'/proc/{pid}/status')):
        if line.startswith('PPid:'):
            return int(line.split()[1])
    return None
