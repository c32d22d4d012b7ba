"""
Where a node process runs: a Sandbox (boundary.outside.sandbox) of its own, for every TARGET.

A student's node file is copied, with the Python files beside it (its own modules), into the
sandbox's scratch folder, and runs from that copy, with the kit's scan_pkg library (its
``report``, ``laser``, ``cmd_vel`` helpers) readable but none of its answers, in any copy
(sim_bridge.runner.boundary.outside.kit_answers: hidden in the sandbox's namespaces, closed to its
uid without them); the kit's own targets (a console script or
module such as ``wall_follow``, a file inside the kit) run sandboxed too, with the kit's
reference nodes readable. What the process prints names the copy: :class:`NodeSandbox`
maps it back to the student's own folder before anyone sees it.
"""

import os
from pathlib import Path
import resource
import sys
from typing import Mapping

from sim_bridge.runner.boundary.outside.kit_answers import (
    answer_folders, library_copies, library_folders, reference_node_files)
from sim_bridge.runner.boundary.outside.sandbox import (
    ADDRESS_SPACE_SLACK_BYTES, Sandbox, SandboxError, SandboxLimits)
from sim_bridge.runner.boundary.outside.sandbox_view import KIT_PACKAGE, python_roots
from sim_bridge.runner.targets import split_target

#: What of the trusted side's environment a node process gets (its DDS domain, its checks,
#: the console format the trusted side reads its log lines by).
PASSED_VARIABLES = ('ROS_DOMAIN_ID', 'ROS_PYTHON_CHECK_FIELDS', 'RCUTILS_CONSOLE_OUTPUT_FORMAT')
#: Least memory (bytes) a node process's run gets, whatever limit the grader has; what it
#: gets when the grader has none.
LEAST_MEMORY_BYTES = 256 * 2 ** 20
DEFAULT_MEMORY_BYTES = 2 * 2 ** 30
#: Most processes between the one a sandbox starts and the node process (bwrap, its init).
MAX_WRAPPERS = 4
#: How the node process's command line goes on after its Python (boundary.agent_command).
AGENT_ARGV = [b'-m', b'sim_bridge.runner.boundary.inside.agent']
#: The folder of a student's files in a run's scratch: shown as the student's own.
COPY_FOLDER = 'node'
#: A node process's wall time (s): this, plus a wall second per simulated second (the
#: grader's own budget, sim_bridge.grading.limits, ends the run first).
WALL_BASE_S = 120.0


def student_files(node_file: Path) -> dict[str, Path]:
    """
    Return what a run of a student's ``node_file`` reads of the submission: name -> file.

    The node file and the Python files beside it (its own modules), under COPY_FOLDER in the
    sandbox's scratch folder; nothing else of the student's folder reaches the run.
    """
    folder = node_file.resolve().parent
    files = {f'{COPY_FOLDER}/{sibling.name}': sibling for sibling in sorted(folder.glob('*.py'))
             if sibling.is_file()}
    files[f'{COPY_FOLDER}/{node_file.name}'] = node_file
    return files


def node_limits(duration_s: float, address_space_bytes: int | None = None) -> SandboxLimits:
    """
    Return a node process's limits: the run's memory and wall-clock budget.

    Memory (bytes) is ``address_space_bytes``, by default this process's address-space limit
    (the grader's, see sim_bridge.grading.isolated_child), less the sandbox's reserve, so that
    the sandbox's limit never exceeds it; DEFAULT_MEMORY_BYTES when there is none. Wall time
    (s) is WALL_BASE_S plus ``duration_s`` (s of simulated time).
    """
    hard = address_space_bytes or resource.getrlimit(resource.RLIMIT_AS)[1]
    memory = DEFAULT_MEMORY_BYTES if hard == resource.RLIM_INFINITY \
        else max(LEAST_MEMORY_BYTES, hard - ADDRESS_SPACE_SLACK_BYTES)
    return SandboxLimits(memory_bytes=memory, wall_s=WALL_BASE_S + max(duration_s, 1.0))


def kit_answers() -> list[str]:
    """
    Return what a student's run must not read of the kit: answer files and folders.

    The answer files of every copy of scan_pkg (:func:`reference_node_files`) and the kit's
    folders of answers and copies (:func:`answer_folders`) but those holding what a run reads:
    its Python (the grader's, and the launcher's), the kit's packages.
    """
    needed = [*python_roots(), *map(str, library_folders()), str(KIT_PACKAGE),
              os.path.realpath(sys.executable)]
    return [*reference_node_files(), *answer_folders(needed)]


def is_kit_file(path: Path) -> bool:
    """Tell whether ``path`` is a file of the kit (its sim_bridge or scan_pkg package)."""
    resolved = path.resolve()
    return any(resolved.is_relative_to(folder) for folder in [KIT_PACKAGE, *library_copies()])


class NodeSandbox:
    """
    The sandbox of one TARGET's process: the target as the process names it, the way back.

    ``target``: what the process is told to run (the copy's path, for a student's file);
    ``sandbox``: its :class:`Sandbox`; :meth:`shown` maps the copy's folder in a text back to
    the student's folder. ``readable`` are more paths the process may read (its params file).
    """

    def __init__(self, target: str, limits: SandboxLimits, readable=()):
        where, class_name = split_target(target)
        path = Path(where)
        self.copy_folder = self.own_folder = ''
        if path.is_file() and not is_kit_file(path):
            self.sandbox = Sandbox(student_files(path), limits, readable=readable,
                                   library=library_folders(), reference_nodes=True,
                                   hidden_files=kit_answers())
            self.copy_folder = str(self.sandbox.scratch / COPY_FOLDER)
            self.own_folder = str(path.resolve().parent)
            inside = f'{self.copy_folder}/{path.name}'
            self.target = f'{inside}:{class_name}' if class_name else inside
        else:
            self.sandbox = Sandbox({}, limits, readable=readable, library=library_folders(),
                                   reference_nodes=True)
            # A kit file by its real path: the sandbox holds the package's real folder, not
            # the links to it that colcon's --symlink-install makes.
            inside = str(path.resolve()) if path.is_file() else where
            self.target = f'{inside}:{class_name}' if class_name and path.is_file() else \
                (inside if path.is_file() else target)

    def shown(self, text: str) -> str:
        """Return ``text`` with the copy's folder named as the student's own."""
        return text.replace(self.copy_folder, self.own_folder) if self.copy_folder else text

    def shown_bytes(self, data: bytes) -> bytes:
        """Return ``data`` (printed bytes) with the copy's folder named as the student's own."""
        if not self.copy_folder:
            return data
        return data.replace(os.fsencode(self.copy_folder), os.fsencode(self.own_folder))

    def node_pid(self, started: int) -> int:
        """
        Return the pid (as seen here) of the node process the sandbox's ``started`` runs.

        bwrap and its namespace's first process stand between: the node process is the first
        of ``started`` and its first descendants whose command is ``python AGENT_ARGV ...``;
        ``started`` when none is (yet).
        """
        pid = started
        for _ in range(MAX_WRAPPERS):
            try:
                if Path(f'/proc/{pid}/cmdline').read_bytes().split(b'\0')[1:3] == AGENT_ARGV:
                    return pid
                below = Path(f'/proc/{pid}/task/{pid}/children').read_text().split()
            except OSError:
                return started
            if not below:
                return started
            pid = int(below[0])
        return started

    def environment(self, passed: Mapping[str, str] = os.environ) -> dict[str, str]:
        """Return the process's clean environment, with PASSED_VARIABLES of ``passed``."""
        return self.sandbox.environment({name: passed[name] for name in PASSED_VARIABLES
                                         if name in passed})


def isolation_line(limits: SandboxLimits) -> str:
    """
    Return the line that says how node processes with ``limits`` would be isolated.

    When they cannot start at all here, the line says why (:class:`SandboxError`).
    """
    try:
        with Sandbox({}, limits) as sandbox:
            sandbox.check_reachable(sys.executable)  # a node process's Python (agent_command)
            return sandbox.isolation
    except SandboxError as error:
        return f'{error} (no run can start)'


def say_isolation(isolation: str) -> None:
    """Say on stderr, once, how node processes are isolated (loudly when they are not)."""
    print(f'node processes: {isolation}', file=sys.stderr, flush=True)


def isolation_warning(isolation: str) -> str | None:
    """
    Return the reports' warning for runs not fully sandboxed, or None.

    None too when ``isolation`` is '': no node process started (the simulator could not start).
    """
    if not isolation or isolation.startswith('bubblewrap'):
        return None
    if isolation.startswith('NOT sandboxed: '):
        return f'runs NOT sandboxed: {isolation.partition(": ")[2]}'
    return f'runs {isolation}'
