"""
Run a node file as its own process, as ``python3 FILE`` or ``ros2 run`` starts it.

The pieces a runner needs for a file it cannot step (sim_bridge.node_styles): the command line
that runs the file's own ``main()``, and a ROS environment private to the run (a domain of its
own, discovery on this machine only), so the node and the runner's live simulator see each
other and nothing else. Starting, printing and stopping the process is sim_bridge.live's.
"""

import fcntl
import os
from pathlib import Path
import re
import sys
import traceback
from typing import ContextManager, Iterable, Mapping, Sequence

from sim_bridge.live import DISCOVERY_VARIABLE, ProcessSpec
from sim_bridge.node_styles import has_main_guard
from sim_bridge.run_environment import environment_set

#: Private domains are taken from [DOMAIN_BASE, DOMAIN_BASE + DOMAIN_COUNT): ids Fast DDS can
#: open ports for on Linux, away from the default domain 0.
DOMAIN_BASE = 1
DOMAIN_COUNT = 100
#: Longest wait (wall s) for a node run as a process to join the ROS graph.
NODE_START_TIMEOUT_S = 20.0
#: Lines of a node process's output kept to read its traceback from, should it die.
OUTPUT_TAIL_LINES = 400
#: A frame of a traceback as Python prints it, and the error a ROS-module hint reads.
FRAME_LINE = re.compile(r'  File "(?P<file>.+)", line (?P<line>\d+), in (?P<name>.+)$')
MISSING_MODULE = re.compile(r"ModuleNotFoundError: No module named '(?P<name>[\w.]+)'")
#: Where the runs on this machine reserve their domains, a lock file each: one folder for all
#: of them, whatever a run's TMPDIR (a graded run's is its own scratch folder).
LOCK_FOLDER = Path('/tmp')


class DomainReservation:
    """
    A ROS_DOMAIN_ID no other run on this machine holds, until :meth:`release`.

    Each id has a lock file in LOCK_FOLDER, taken with ``flock``: two runs at once (a grader's
    ``--jobs 2``) never share a domain, so one's node never hears the other's simulator. The
    search starts at an id spread by ``pid``; a run that dies frees its lock with its process,
    and the lock is not inherited by the node's process (Python opens files close-on-exec).
    """

    def __init__(self, pid: int | None = None, folder: Path = LOCK_FOLDER) -> None:
        start = (os.getpid() if pid is None else pid) % DOMAIN_COUNT
        for offset in range(DOMAIN_COUNT):
            domain_id = DOMAIN_BASE + (start + offset) % DOMAIN_COUNT
            lock = open(folder / f'lab-ros-domain-{domain_id}.lock', 'a')
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:  # another run holds it
                lock.close()
                continue
            self.domain_id, self.lock = domain_id, lock
            return
        raise RuntimeError(f'every ROS domain from {DOMAIN_BASE} to '
                           f'{DOMAIN_BASE + DOMAIN_COUNT - 1} is held by another run on this '
                           'machine')

    def release(self) -> None:
        """Free the domain for another run."""
        self.lock.close()


def process_environment(base: Mapping[str, str], domain_id: int) -> dict[str, str]:
    """Return ``base`` on domain ``domain_id`` with discovery on this machine only."""
    env = dict(base)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env[DISCOVERY_VARIABLE] = 'LOCALHOST'
    env.pop('ROS_STATIC_PEERS', None)
    return env


def node_spec(path: Path, ros_arguments: Sequence[str], python: str = sys.executable
              ) -> ProcessSpec:
    """
    Return the process running the node file ``path`` with ``ros_arguments`` (``--ros-args``).

    Its ``if __name__ == '__main__'`` block when it has one, as ``python3 FILE`` runs it;
    otherwise its ``main()`` called as ``ros2 run``'s console script calls it, with the file's
    folder first on the import path, as ``python3 FILE`` would have it.
    """
    path = Path(path).resolve()
    if has_main_guard(path.read_text(encoding='utf-8')):
        cmd = (python, str(path), *ros_arguments)
    else:
        code = ('import runpy, sys; sys.argv[0] = {0!r}; sys.path.insert(0, {1!r}); '
                "sys.exit(runpy.run_path({0!r}, run_name='node_file')['main']())").format(
                    str(path), str(path.parent))
        cmd = (python, '-c', code, *ros_arguments)
    return ProcessSpec(path.stem, cmd)


def private_ros_environment(domain_id: int) -> ContextManager[None]:
    """Put this process on domain ``domain_id``, discovery local, while rclpy starts in it."""
    return environment_set({**process_environment({}, domain_id), 'ROS_STATIC_PEERS': None})


def last_traceback(lines: Iterable[str]) -> tuple[list[traceback.FrameSummary], str] | None:
    """
    Return the frames (outermost first) and the error line of the last traceback in ``lines``.

    ``lines`` are what a Python process printed, as Python prints an uncaught exception; None
    when they hold no traceback. Only the last of chained exceptions is read: the one that
    ended the process.
    """
    lines = list(lines)
    starts = [index for index, line in enumerate(lines)
              if line.startswith('Traceback (most recent call last):')]
    if not starts:
        return None
    frames: list[list] = []
    for line in lines[starts[-1] + 1:]:
        match = FRAME_LINE.match(line)
        if match:
            frames.append([match['file'], int(match['line']), match['name'], ''])
        elif line.startswith('    '):
            code = line.strip()
            if frames and not frames[-1][3] and code.strip('^~ '):  # not 3.11's carets
                frames[-1][3] = code
        elif line.strip():
            summaries = [traceback.FrameSummary(file, number, name, lookup_line=False,
                                                line=code)
                         for file, number, name, code in frames]
            return summaries, line.strip()
    return None


def printed_error(error_line: str) -> BaseException | None:
    """
    Return what a hint needs of the error a node's process printed (``Type: message``), or None.

    A ``ModuleNotFoundError: No module named 'x'`` is that error, naming ``x``
    (sim_bridge.hints.ros_module_hint reads it); other errors are not rebuilt.
    """
    match = MISSING_MODULE.match(error_line)
    if match is None:
        return None
    return ModuleNotFoundError(error_line.partition(': ')[2], name=match['name'])
