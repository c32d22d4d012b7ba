"""
What the machine gives each sandbox (boundary.outside.sandbox): an identity, groups, a folder.

- :class:`UidLease`: a dedicated uid (and gid) per concurrent run when the grader is root,
  leased machine-wide with a lock file in a root-only folder; :func:`kill_uid` ends every
  process of it, and what it left where any user writes goes before the uid is leased again
  (sim_bridge.runner.boundary.outside.sandbox_leftovers).
- :class:`RunCgroup`: the memory, pids and cpu control groups of a run's whole tree (root only).
- :func:`unreachable_by_others` and :func:`close_to_runs`: what a run without namespaces (its
  uid alone) can read of the host's files, and the kit's answers made unreadable to it.
- :func:`grader_folder`: this grader's scratch parent, whose lock file the grader holds while
  it lives; :func:`remove_leftover_scratch` removes only the parents whose lock it can take
  (a pid says nothing across pid namespaces and containers sharing /tmp).
"""

import errno
import fcntl
import functools
import os
from pathlib import Path
import shutil
import signal
import stat
import tempfile
import time
from typing import Mapping, Sequence

from sim_bridge.runner.boundary.outside.sandbox_leftovers import sweep_uid

#: Dedicated uids (and gids of the same number) for runs of a grader running as root.
UID_BASE = 60100
UID_COUNT = 900
#: Without namespaces, the group that alone may read the files a run must not (the kit's
#: reference answers): a run of the kit's own nodes has it, a student's run does not.
ANSWERS_GID = UID_BASE - 1
#: Root-only folder of the uid leases' lock files (machine-wide), else in the temp folder.
LEASE_FOLDERS = (Path('/run/lab-sandbox'), Path(tempfile.gettempdir()) / 'lab-sandbox-uids')
#: A grader's scratch parent is ``<temp>/lab-sandbox-XXXX`` beside its lock file ``.lock``.
SCRATCH_PREFIX = 'lab-sandbox-'
LOCK_SUFFIX = '.lock'
#: Where the kernel's control groups are mounted.
CGROUP_ROOT = Path('/sys/fs/cgroup')
#: The CPU weight of every run's group (v2's default weight, v1's default shares).
CPU_WEIGHT = 100
CPU_SHARES = 1024
#: The shell script that writes its pid into each file named before ``--``, then executes
#: what follows (exit status 125 when it cannot).
JOIN_SCRIPT = ('while [ "$1" != -- ]; do echo $$ > "$1" || exit 125; shift; done; shift; '
               'exec "$@"')
#: Wall seconds close() waits for the processes of a run to be gone before it gives up.
END_TIMEOUT_S = 10.0
#: Wall seconds between two looks at whether a run's processes are gone.
END_POLL_S = 0.01


def close_to_runs(paths: Sequence[str]) -> None:
    """
    Make ``paths`` unreadable by the runs' uids, but for group ANSWERS_GID (no o+rwx, g+r).

    A folder gets g+x too. Without a mount namespace a run sees the host's files: this hides
    the kit's answers from it (the change stays: other users of the machine cannot read them
    either). SandboxError when it cannot be done (a read-only installation).
    """
    for path in paths:
        try:
            status = os.stat(path)
            if status.st_gid != ANSWERS_GID or status.st_mode & 0o007:
                group = stat.S_IRGRP | (stat.S_IXGRP if stat.S_ISDIR(status.st_mode) else 0)
                os.chown(path, -1, ANSWERS_GID)
                os.chmod(path, stat.S_IMODE(status.st_mode) & ~0o007 | group)
        except OSError as error:
            raise SandboxError(f'cannot hide {path} from runs without namespaces: '
                               f'{error.strerror or error}') from None


class SandboxError(RuntimeError):
    """A run cannot start in its sandbox on this machine (the message says why, in one line)."""


def unreachable_by_others(path: str) -> str | None:
    """
    Return why users other than the owner cannot reach ``path``, or None when they can.

    A run's dedicated uid is such a user: it passes a folder with o+x, reads a file with o+r,
    on the way to ``path`` as named and to what it links to.
    """
    for way in dict.fromkeys([Path(os.path.abspath(path)), Path(os.path.realpath(path))]):
        for step in [*reversed(way.parents), way]:
            try:
                mode = os.stat(step).st_mode
            except OSError as error:
                return f'{step}: {error.strerror}'
            if not mode & (stat.S_IXOTH if stat.S_ISDIR(mode) else stat.S_IROTH):
                return f'{step} is closed to them ({stat.filemode(mode)})'
    return None


def lock_exclusive(path: Path, create: bool = True) -> int | None:
    """
    Return an fd holding ``path``'s flock, or None when another holds it.

    ``create``: make the file (0600) if missing; else a missing file, a symlink or a file of
    another user is not locked (None).
    """
    flags = os.O_RDWR | os.O_CLOEXEC | os.O_NOFOLLOW | (os.O_CREAT if create else 0)
    try:
        fd = os.open(path, flags, 0o600)
    except OSError:
        if create:
            raise
        return None
    if not create and os.fstat(fd).st_uid != os.geteuid():
        os.close(fd)
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def remove_leftover_scratch(folder: Path) -> list[Path]:
    """
    Remove the scratch parents in ``folder`` whose grader has ended; return them.

    A parent ``lab-sandbox-XXXX`` goes only when its lock file ``lab-sandbox-XXXX.lock`` (this
    user's) can be locked: a live grader holds it (:func:`grader_folder`), whatever its pid
    namespace.
    """
    removed = []
    for lock in sorted(folder.glob(f'{SCRATCH_PREFIX}*{LOCK_SUFFIX}')):
        fd = lock_exclusive(lock, create=False)
        if fd is None:
            continue
        try:
            parent = lock.with_suffix('')
            shutil.rmtree(parent, ignore_errors=True)
            lock.unlink(missing_ok=True)
            removed.append(parent)
        finally:
            os.close(fd)
    return removed


@functools.lru_cache(maxsize=None)
def grader_folder() -> Path:
    """
    Return this grader's scratch parent, created once, with its lock held until it exits.

    Made after removing the parents of graders that have ended. The lock file is made and
    locked before its folder exists; a lock another cleaner took and unlinked meanwhile is
    made anew. The parent is 0711: a run's uid reaches its own scratch, lists nothing.
    """
    temp = Path(tempfile.gettempdir())
    remove_leftover_scratch(temp)
    while True:
        fd, lock_path = tempfile.mkstemp(prefix=SCRATCH_PREFIX, suffix=LOCK_SUFFIX, dir=temp)
        fcntl.flock(fd, fcntl.LOCK_EX)
        if os.fstat(fd).st_nlink:
            break
        os.close(fd)
    os.set_inheritable(fd, False)
    folder = Path(lock_path).with_suffix('')
    folder.mkdir(mode=0o711)
    folder.chmod(0o711)
    return folder


class UidLease:
    """
    A dedicated uid (and gid) no other run on this machine uses, until :meth:`release`.

    Each uid has a lock file in a root-only folder (LEASE_FOLDERS); a grader that dies frees
    its leases with its process. What a dead grader's run of the uid left running is killed
    before the uid is handed out again.
    """

    def __init__(self) -> None:
        folder = lease_folder()
        start = os.getpid() % UID_COUNT
        for offset in range(UID_COUNT):
            uid = UID_BASE + (start + offset) % UID_COUNT
            fd = lock_exclusive(folder / f'uid-{uid}.lock')
            if fd is not None:
                self.uid, self.fd = uid, fd
                kill_uid(uid)
                sweep_uid(uid)  # what a dead grader's run of the uid left
                return
        raise RuntimeError(f'every sandbox uid from {UID_BASE} to {UID_BASE + UID_COUNT - 1} '
                           'is in use by a run on this machine')

    def release(self) -> None:
        """Hand the uid back, without what its run left where any user may write."""
        try:
            sweep_uid(self.uid)
        finally:
            os.close(self.fd)


def lease_folder() -> Path:
    """Return the root-only folder of the uid leases (made 0700 if missing; refused if not)."""
    for folder in LEASE_FOLDERS:
        try:
            folder.mkdir(mode=0o700, exist_ok=True)
        except OSError:
            continue
        status = folder.lstat()
        if folder.is_dir() and status.st_uid == 0 and not status.st_mode & 0o077:
            return folder
    raise RuntimeError('no root-only folder for the sandbox uid locks: '
                       + ', '.join(map(str, LEASE_FOLDERS)))


def uid_processes(uid: int) -> list[int]:
    """
    Return the pids of the live processes whose real uid is ``uid`` (from /proc/PID/status).

    Not /proc/PID's owner: a process that made itself non-dumpable shows as root's there.
    Zombies are dead (their parent has yet to reap them): not counted.
    """
    found = []
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            fields = dict(line.split(':', 1) for line in read_lines(Path(f'/proc/{entry}/status'))
                          if ':' in line)
            if (fields.get('Uid', '').split()[:1] == [str(uid)]
                    and fields.get('State', '').split()[:1] not in (['Z'], ['X'])):
                found.append(int(entry))
    return found


def kill_uid(uid: int, timeout_s: float = END_TIMEOUT_S) -> None:
    """
    Kill every process of ``uid`` (a run's dedicated uid); wait (wall s) until none is left.

    ``kill(-1, SIGKILL)`` sent as that uid, from a fork of this process (the uid may not
    reach any program), ends all of them at once, a fork bomb too; RuntimeError if some are
    still there after ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while uid_processes(uid):
        if time.monotonic() > deadline:
            raise RuntimeError(f'processes of uid {uid} still alive {timeout_s:g} s after '
                               'they were killed')
        killer = os.fork()
        if killer == 0:
            try:
                os.setgroups([])
                os.setgid(uid)
                os.setuid(uid)
                os.kill(-1, signal.SIGKILL)
            finally:
                os._exit(0)
        os.waitpid(killer, 0)


class RunCgroup:
    """
    Control groups holding a run's whole process tree: ``memory_bytes`` (bytes) and ``pids``.

    cgroup v2 where ``/sys/fs/cgroup`` is unified with the memory and pids controllers (a
    ``lab-sandbox`` group at its top, runs below); else v1's memory and pids hierarchies,
    below this grader's own groups. Root only: OSError when neither can be made.

    And its share of the CPU where the kernel has the cpu controller (``cpu``: True): every
    run's group has the same weight (CPU_WEIGHT, v1's CPU_SHARES), so the kernel shares the
    CPUs fairly between runs, however many processes each one starts: twelve busy loops
    weigh as much as a run's one node process.
    """

    def __init__(self, name: str, memory_bytes: int, pids: int) -> None:
        self.folders: list[Path] = []
        self.cpu = False
        try:
            controllers = set(read_words(CGROUP_ROOT / 'cgroup.controllers'))
            if {'memory', 'pids'} <= controllers:
                self.kind = 'cgroup v2'
                self.make_v2(name, memory_bytes, pids, 'cpu' in controllers)
            else:
                self.kind = 'cgroup v1'
                self.make_v1(name, memory_bytes, pids)
        except OSError:
            self.remove()
            raise

    def make_v2(self, name: str, memory_bytes: int, pids: int, cpu: bool) -> None:
        """Make the run's v2 group, with the controllers enabled on the way down."""
        parent = CGROUP_ROOT / 'lab-sandbox'
        parent.mkdir(exist_ok=True)
        for folder in (CGROUP_ROOT, parent):
            (folder / 'cgroup.subtree_control').write_text('+memory +pids')
        try:  # best effort: the kernel refuses it beside a realtime process
            for folder in (CGROUP_ROOT, parent) if cpu else ():
                (folder / 'cgroup.subtree_control').write_text('+cpu')
        except OSError:
            cpu = False
        self.make(parent / name, {'memory.max': memory_bytes, 'pids.max': pids,
                                  'memory.swap.max': 0, **({'cpu.weight': CPU_WEIGHT}
                                                           if cpu else {})})
        self.cpu = cpu

    def make_v1(self, name: str, memory_bytes: int, pids: int) -> None:
        """Make the run's groups in v1's memory and pids hierarchies (and cpu's, if mounted)."""
        memory, pids_folder = v1_folder('memory'), v1_folder('pids')
        if memory is None or pids_folder is None:
            raise OSError(errno.ENOENT, 'no cgroup v2 with memory and pids controllers, nor '
                                        'cgroup v1 memory and pids hierarchies')
        self.make(memory / name, {'memory.limit_in_bytes': memory_bytes,
                                  'memory.memsw.limit_in_bytes': memory_bytes})
        self.make(pids_folder / name, {'pids.max': pids})
        cpu = v1_folder('cpu')
        try:  # best effort: a cpu hierarchy this grader may not write to
            if cpu is not None:
                self.make(cpu / name, {'cpu.shares': CPU_SHARES})
                self.cpu = True
        except OSError:
            pass

    def make(self, folder: Path, values: Mapping[str, int]) -> None:
        """
        Make one group and write its limits (swap's only where the kernel has them).

        A group of the same name a dead grader left is reused: it is the leased uid's, and
        empty once the uid's processes were killed.
        """
        folder.mkdir(exist_ok=True)
        self.folders.append(folder)
        for file, value in values.items():
            try:
                (folder / file).write_text(str(value))
            except FileNotFoundError:
                if 'swap' not in file:
                    raise

    def joining(self, command: Sequence[str]) -> list[str]:
        """
        Return ``command`` run by a shell that first puts itself in the run's groups.

        Everything the command starts is in them from its first instruction on. (A shell, not
        a Popen preexec_fn: Python code between fork and exec may deadlock in a grader that
        runs threads.)
        """
        return ['/bin/sh', '-c', JOIN_SCRIPT, 'join',
                *(str(folder / 'cgroup.procs') for folder in self.folders), '--', *command]

    def pids(self) -> set[int]:
        """Return the pids of the processes in the run's groups."""
        return {int(word) for folder in self.folders
                for word in read_words(folder / 'cgroup.procs')}

    def kill(self) -> None:
        """SIGKILL every process in the groups, until none is left (END_TIMEOUT_S at most)."""
        deadline = time.monotonic() + END_TIMEOUT_S
        while pids := self.pids():
            if time.monotonic() > deadline:
                raise RuntimeError(f'processes {sorted(pids)} of a run still alive '
                                   f'{END_TIMEOUT_S:g} s after they were killed')
            for pid in pids:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            time.sleep(END_POLL_S)

    def peak_bytes(self) -> int | None:
        """Return the run's peak memory (bytes), as its memory group counted it."""
        for file in ('memory.peak', 'memory.max_usage_in_bytes'):
            words = read_words(self.folders[0] / file)
            if words:
                return int(words[0])
        return None

    def remove(self) -> None:
        """Remove the groups (empty once the run's processes are gone)."""
        for folder in reversed(self.folders):
            try:
                folder.rmdir()
            except OSError:
                pass
        self.folders = []


def read_words(path: Path) -> list[str]:
    """Return the whitespace-separated words of a small file, or [] when it is missing."""
    return ' '.join(read_lines(path)).split()


def v1_folder(controller: str) -> Path | None:
    """Return this process's group folder in the v1 hierarchy of ``controller``, if mounted."""
    base = CGROUP_ROOT / controller
    for line in read_lines(Path('/proc/self/cgroup')):
        _, names, path = line.split(':', 2)
        if controller in names.split(',') and (base / 'cgroup.procs').exists():
            return base / path.lstrip('/')
    return None


def read_lines(path: Path) -> list[str]:
    """Return the lines of a small text file, or [] when it cannot be read."""
    try:
        return path.read_text().splitlines()
    except OSError:
        return []
