"""
Where a node process runs: a Sandbox (sim_bridge.runner.sandbox) of its own, for every TARGET.

A student's node file is copied, with the Python files beside it (its own modules), into the
sandbox's scratch folder, and runs from that copy, with the kit's scan_pkg library (its
``report``, ``laser``, ``cmd_vel`` helpers) readable but its reference nodes (the modules of
its console scripts) empty; the kit's own targets (a console script or
module such as ``wall_follow``, a file inside the kit) run sandboxed too, with the kit's
reference nodes readable. What the process prints names the copy: :class:`NodeSandbox`
maps it back to the student's own folder before anyone sees it.
"""

import importlib.machinery
import importlib.util
import os
from pathlib import Path
import resource
import sys
from typing import Mapping

from sim_bridge.runner.sandbox import ADDRESS_SPACE_SLACK_BYTES, KIT_PACKAGE, Sandbox, \
    SandboxError, SandboxLimits
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
AGENT_ARGV = [b'-m', b'sim_bridge.runner.agent']
#: A node process's wall time (s): this, plus a wall second per simulated second (the
#: grader's own budget, sim_bridge.grading.limits, ends the run first).
WALL_BASE_S = 120.0


def reference_node_files() -> list[str]:
    """
    Return the files of the kit's reference answers, to be hidden from a student's node.

    The modules of scan_pkg's console scripts (the lab's nodes), the pure controllers they run
    (``scan_pkg.behaviors``), and the bytecode Python cached of each (a student could load a
    ``.pyc`` by hand as well as a ``.py``), in every copy of scan_pkg a run could read
    (:func:`library_copies`: an autograder's venv holds one beside the kit's own).
    """
    sources = [Path(source) for source in reference_node_sources()]
    copies = library_copies()
    files = []
    for imported in library_folders():
        names = [source.relative_to(imported) for source in sources
                 if source.is_relative_to(imported)]
        for copy in copies:
            for name in names:
                source = copy / name
                if source.exists():
                    files.append(str(source))
                files += map(str, (source.parent / '__pycache__').glob(f'{source.stem}.*.pyc'))
    return list(dict.fromkeys(files))


def reference_node_sources() -> list[str]:
    """Return the source files of the kit's reference answers (see reference_node_files)."""
    files = [os.path.realpath(spec.origin) for spec in console_script_specs()]
    behaviors = importlib.util.find_spec('scan_pkg.behaviors')
    for folder in (behaviors.submodule_search_locations or []) if behaviors else []:
        files.extend(os.path.realpath(path) for path in sorted(Path(folder).glob('*.py')))
    return files


def console_script_specs() -> list[importlib.machinery.ModuleSpec]:
    """Return the specs of scan_pkg's console scripts' modules, as this process finds them."""
    from importlib.metadata import distribution, PackageNotFoundError
    try:
        scripts = [entry for entry in distribution('scan_pkg').entry_points
                   if entry.group == 'console_scripts']
    except PackageNotFoundError:
        return []
    specs = [importlib.util.find_spec(entry.module) for entry in scripts]
    return [spec for spec in specs if spec is not None and spec.origin]


def library_folders() -> list[Path]:
    """
    Return the folders of the kit's scan_pkg package as this process imports it, real paths.

    The folder of each console script's module's package (``scan_pkg`` imported from the
    workspace's top is a namespace of the ament package's folder; its modules are not).
    """
    folders = [Path(os.path.realpath(spec.origin)).parents[spec.name.count('.') - 1]
               for spec in console_script_specs()]
    spec = importlib.util.find_spec('scan_pkg')
    folders += [Path(os.path.realpath(folder)) for folder in
                ((spec.submodule_search_locations or []) if spec else [])
                if (Path(folder) / '__init__.py').is_file()]
    return list(dict.fromkeys(folders))


def library_copies() -> list[Path]:
    """
    Return every scan_pkg package folder a run could import (real paths).

    This process's (:func:`library_folders`), and any other on Python's path or in its site
    folders: a venv with the kit installed (Gradescope's setup.sh) holds a copy that a
    ``PYTHONPATH`` to the kit's source only shadows.
    """
    import site
    folders = library_folders()
    for entry in dict.fromkeys([*sys.path, *site.getsitepackages()]):
        candidate = Path(entry or '.') / 'scan_pkg'
        if (candidate / '__init__.py').is_file():
            folders.append(Path(os.path.realpath(candidate)))
    return list(dict.fromkeys(folders))


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
            folder = path.resolve().parent
            name = 'node'  # the copy's folder: shown as the student's own (see shown)
            files = {f'{name}/{sibling.name}': sibling for sibling in folder.glob('*.py')
                     if sibling.is_file()}
            files[f'{name}/{path.name}'] = path
            self.sandbox = Sandbox(files, limits, readable=readable, library=library_folders(),
                                   reference_nodes=True, hidden_files=reference_node_files())
            self.copy_folder = str(self.sandbox.scratch / name)
            self.own_folder = str(folder)
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
