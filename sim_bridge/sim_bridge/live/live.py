"""
A lab task's processes: the simulator and the task's scan_pkg node, as the launch file starts them.

The task's node is the installed console script's, or a node file of the student's own.

The task table is sim_bridge.live.lab_tasks (the one lab.launch.py reads); running the
processes is sim_bridge.runner.processes'; the command is sim_bridge.commands.live.
May import common, runner and below.
"""

from importlib import metadata
import os
from pathlib import Path
import sys
from typing import Mapping, Sequence

from sim_bridge.common import paths
from sim_bridge.live.lab_tasks import LAB_TASKS
from sim_bridge.runner.processes import ProcessSpec
from sim_bridge.runner.targets import node_command

#: The simulator's executable name (its console script), as launch names its process.
BRIDGE_EXECUTABLE = 'sim_bridge'


def package_params_file(package: str, name: str) -> Path | None:
    """
    Return ``params/<name>`` of ``package`` (scan_pkg, sim_bridge), or None when it has none.

    From the source checkout (``<repo>/<package>/params``) when this module runs from one,
    else from the package's installed share directory (a colcon or pip install).
    """
    root = paths.repo_root()
    if root is not None and (root / package).is_dir():
        path = root / package / 'params' / name
        return path if path.is_file() else None
    share = None
    if os.environ.get('AMENT_PREFIX_PATH'):
        from ament_index_python.packages import get_package_share_directory
        from ament_index_python.packages import PackageNotFoundError
        try:
            share = Path(get_package_share_directory(package))
        except PackageNotFoundError:
            pass
    if share is None:
        share = Path(sys.prefix) / 'share' / package
    path = share / 'params' / name
    return path if path.is_file() else None


def node_module(executable: str) -> tuple[str, str]:
    """
    Return (module, function) of the console script ``executable`` (a scan_pkg node).

    Read from the installed entry points; ``scan_pkg.<executable>``'s ``main`` when the script
    is not installed (a checkout on the path).
    """
    for entry in metadata.entry_points(group='console_scripts', name=executable):
        module, _, function = entry.value.partition(':')
        return module.strip(), (function.strip() or 'main')
    return f'scan_pkg.{executable}', 'main'


def python_command(module: str, function: str = 'main', python: str = sys.executable
                   ) -> list[str]:
    """Return the command line running ``module.function()`` as its console script would."""
    if function == 'main':
        return [python, '-m', module]  # each node module calls main() when run as a script
    return [python, '-c', f'import sys; from {module} import {function}; sys.exit({function}())']


def ros_overrides(params: Mapping[str, str]) -> list[str]:
    """Return ``-p name:=value`` arguments for ``params`` (values as --ros-args types them)."""
    arguments = []
    for name, value in params.items():
        arguments += ['-p', f'{name}:={value}']
    return arguments


def bridge_spec(world: str, *, gui: bool = False, real_time_factor: float = 1.0,
                robot: str | None = None, robot_pose: Sequence[float] | None = None,
                params: Mapping[str, str] | None = None, python: str = sys.executable
                ) -> ProcessSpec:
    """
    Return the simulator's process: ``world`` (a name or a path), its window, its pace.

    As sim.launch.py starts it: the params file ``sim.yaml``, then ``world`` and ``gui``;
    here also ``real_time_factor`` (× wall-clock speed), the robot model ``robot`` to spawn
    instead of the world's and its ``robot_pose`` (x m, y m, yaw rad), and ``params``
    overrides.
    """
    cmd = [*python_command('sim_bridge.ros.bridge', python=python), '--ros-args']
    params_file = package_params_file('sim_bridge', 'sim.yaml')
    if params_file is not None:
        cmd += ['--params-file', str(params_file)]
    spawn = {}
    if robot is not None:
        spawn['robot'] = robot
    if robot_pose is not None:
        spawn['robot_pose'] = f"[{', '.join(repr(float(value)) for value in robot_pose)}]"
    cmd += ros_overrides({'world': world, 'gui': 'true' if gui else 'false',
                          'real_time_factor': repr(float(real_time_factor)), **spawn,
                          **(params or {})})
    return ProcessSpec(BRIDGE_EXECUTABLE, tuple(cmd))


def node_spec(executable: str, *, params: Mapping[str, str] | None = None,
              python: str = sys.executable, node_file: Path | None = None) -> ProcessSpec:
    """
    Return a scan_pkg node's process, as lab.launch.py starts it, with ``params`` overrides.

    ``--ros-args --params-file params/<executable>.yaml`` (when scan_pkg ships one)
    ``-p use_sim_time:=true``, then ``-p name:=value`` for each of ``params``. With
    ``node_file`` (a student's own node, such as their scan_pkg's ``wall_follow.py``), that
    file run as written (``python3 FILE``, launch's name its file name), without the kit's
    params file, which is its own nodes'.
    """
    if node_file is not None:
        cmd = [python, str(node_file.resolve()), '--ros-args']
    else:
        cmd = [*python_command(*node_module(executable), python=python), '--ros-args']
        params_file = package_params_file('scan_pkg', executable + '.yaml')
        if params_file is not None:
            cmd += ['--params-file', str(params_file)]
    cmd += ros_overrides({'use_sim_time': 'true', **(params or {})})
    return ProcessSpec(node_file.name if node_file is not None else executable, tuple(cmd))


def task_specs(task: str, *, world: str | None = None, gui: bool = False,
               real_time_factor: float = 1.0, robot: str | None = None,
               robot_pose: Sequence[float] | None = None,
               params: Mapping[str, Mapping[str, str]] | None = None,
               python: str = sys.executable, node_file: Path | None = None
               ) -> list[ProcessSpec]:
    """
    Return the processes of lab task ``task``: the simulator, then the task's node.

    ``world`` replaces the task's world, ``robot`` (a model name) the world's robot (the lab
    robot in every task's world), ``robot_pose`` (x m, y m, yaw rad) its start; ``params``
    maps a node name (``sim_bridge`` or the task's node) to its parameter overrides;
    ``node_file`` runs that file as the task's node (see :func:`node_spec`). ValueError for an
    unknown task or for ``params`` naming another node; FileNotFoundError for a ``node_file``
    that is not a file.
    """
    if task not in LAB_TASKS:
        raise ValueError(f"unknown task '{task}': choose one of {', '.join(LAB_TASKS)}")
    lab_task = LAB_TASKS[task]
    if node_file is not None and not node_file.is_file():
        raise FileNotFoundError(f'--node {node_file}: no such file')
    params = dict(params or {})
    unknown = set(params) - {BRIDGE_EXECUTABLE, lab_task.node}
    if unknown:
        raise ValueError(f"parameters for {', '.join(sorted(unknown))}: task '{task}' runs "
                         f'the nodes {BRIDGE_EXECUTABLE} and {lab_task.node}')
    return [bridge_spec(world or lab_task.world, gui=gui, real_time_factor=real_time_factor,
                        robot=robot, robot_pose=robot_pose,
                        params=params.get(BRIDGE_EXECUTABLE), python=python),
            node_spec(lab_task.node, params=params.get(lab_task.node), python=python,
                      node_file=node_file)]


def shown_command(spec: ProcessSpec) -> str:
    """Return a process's command as a terminal shows it: ``ros2 run`` a node, file names."""
    arguments = list(spec.cmd[spec.cmd.index('--ros-args'):]) if '--ros-args' in spec.cmd else []
    return node_command(spec.executable, [os.path.basename(argument) if os.path.isabs(argument)
                                          else argument for argument in arguments])
