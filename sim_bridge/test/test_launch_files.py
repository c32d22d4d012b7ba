"""
Checks of the launch files that need no ROS 2: they parse, and name what exists.

The launch and launch_ros packages are not on PyPI, so the launch descriptions themselves are
only built on a ROS 2 machine (``ros2 launch sim_bridge lab.launch.py --show-args``).
"""

import ast
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from sim_bridge.common.paths import world_names
from sim_bridge.live.lab_tasks import LAB_TASKS

PACKAGE = Path(__file__).resolve().parents[1]
LAUNCH_FILES = sorted((PACKAGE / 'launch').glob('*.launch.py'))


def test_both_launch_files_ship():
    assert [path.name for path in LAUNCH_FILES] == ['lab.launch.py', 'sim.launch.py']


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda path: path.name)
def test_launch_file_defines_generate_launch_description(path):
    tree = ast.parse(path.read_text(), filename=str(path))
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert 'generate_launch_description' in functions


@pytest.mark.parametrize('task', sorted(LAB_TASKS))
def test_every_lab_task_runs_a_scan_pkg_console_script_in_a_shipped_world(task):
    scripts = {entry.name: entry.value for entry in entry_points(group='console_scripts')}
    assert scripts[LAB_TASKS[task].node].startswith('scan_pkg.')
    assert LAB_TASKS[task].world in world_names()


def test_sim_launch_reads_the_installed_params_file():
    source = (PACKAGE / 'launch' / 'sim.launch.py').read_text()
    assert "'params', 'sim.yaml'" in source
    assert (PACKAGE / 'params' / 'sim.yaml').is_file()


def declared_arguments(path: Path) -> set[str]:
    """Return the names of the launch arguments a launch file declares."""
    tree = ast.parse(path.read_text(), filename=str(path))
    return {call.args[0].value for call in ast.walk(tree)
            if isinstance(call, ast.Call) and getattr(call.func, 'id', '') ==
            'DeclareLaunchArgument'}


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda path: path.name)
def test_launch_files_spawn_a_robot_as_the_bridge_parameters_do(path):
    # robot:=NAME robot_pose:='[x, y, yaw]', the sim_bridge parameters of the same names.
    assert {'world', 'robot', 'robot_pose', 'gui', 'rviz'} <= declared_arguments(path)
