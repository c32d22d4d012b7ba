"""
What a run's dedicated uid leaves on the machine: swept when the run ends and before a lease.

Without namespaces (PARTLY sandboxed, sim_bridge.runner.boundary.outside.sandbox) a run's uid
writes where any user may: the temp folders, ``/dev/shm`` (Fast DDS's shared-memory segments, their
locks and semaphores), POSIX message queues and lock folders; and it makes System V IPC objects.
None of that ends with its processes, and the uid is leased again to later runs (another
student's).
:func:`sweep_uid` removes everything the uid owns there (with namespaces a run's /tmp and
/dev/shm are its own and end with it, and the sweep finds nothing).
"""

import ctypes
import os
from pathlib import Path
import shutil
import stat
import tempfile

#: Folders any user may write to on a Linux machine (those that exist are swept).
WRITABLE_PLACES = ('/tmp', '/var/tmp', '/dev/shm', '/run/shm', '/dev/mqueue', '/run/lock',
                   '/var/lock', '/var/crash')
#: System V IPC objects as the kernel lists them: file in /proc/sysvipc -> its id column.
SYSV_IPC_TABLES = {'shm': 'shmid', 'sem': 'semid', 'msg': 'msqid'}
#: The IPC_RMID command of shmctl, semctl and msgctl.
IPC_RMID = 0


def writable_places() -> list[Path]:
    """Return the folders any user may write to (WRITABLE_PLACES and Python's temp folder)."""
    places = {os.path.realpath(path) for path in [*WRITABLE_PLACES, tempfile.gettempdir()]}
    return [Path(path) for path in sorted(places) if os.path.isdir(path)]


def sweep_uid(uid: int) -> list[str]:
    """
    Remove what ``uid`` owns in the writable places and its System V IPC objects; name them.

    Call it once the uid's processes are gone. A folder of the uid goes whole; a folder of
    another user is entered only where any user may write (the uid can have written there
    alone); symlinks are removed, never followed.
    """
    removed = []
    for place in writable_places():
        removed += sweep_folder(place, uid)
    return removed + remove_ipc_objects(uid)


def sweep_folder(folder: Path, uid: int) -> list[str]:
    """Remove the entries of ``folder`` (and of its world-writable folders) owned by ``uid``."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        try:
            status = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if status.st_uid == uid:
            if stat.S_ISDIR(status.st_mode):
                shutil.rmtree(entry.path, ignore_errors=True)
            else:
                Path(entry.path).unlink(missing_ok=True)
            removed.append(entry.path)
        elif stat.S_ISDIR(status.st_mode) and status.st_mode & stat.S_IWOTH:
            removed += sweep_folder(Path(entry.path), uid)
    return removed


def remove_ipc_objects(uid: int) -> list[str]:
    """Remove the System V shared memory, semaphores and queues that ``uid`` owns or made."""
    libc = ctypes.CDLL(None, use_errno=True)
    remove = {'shm': lambda key: libc.shmctl(key, IPC_RMID, None),
              'sem': lambda key: libc.semctl(key, 0, IPC_RMID),
              'msg': lambda key: libc.msgctl(key, IPC_RMID, None)}
    removed = []
    for table, id_column in SYSV_IPC_TABLES.items():
        for row in ipc_rows(table):
            if str(uid) in (row.get('uid'), row.get('cuid')):
                remove[table](int(row[id_column]))
                removed.append(f'System V {table} {row[id_column]}')
    return removed


def ipc_rows(table: str) -> list[dict[str, str]]:
    """Return the rows of /proc/sysvipc/``table`` as column name -> value."""
    try:
        header, *lines = Path('/proc/sysvipc', table).read_text().splitlines()
    except (OSError, ValueError):
        return []
    return [dict(zip(header.split(), line.split())) for line in lines]
