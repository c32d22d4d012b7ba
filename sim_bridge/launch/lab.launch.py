"""
Start the simulator with the world of a lab task, and the task's scan_pkg node.

The node is ``ros2 run scan_pkg <task's node>``: the scan_pkg installed in the sourced
workspace, a student's own (``ros2 pkg create`` as the handout says, console scripts named
after the tasks' nodes) or the kit's reference one; with scan_pkg's ``params/<node>.yaml``
when that package ships one (a student's has none).

``ros2 launch sim_bridge lab.launch.py task:=wall_follow`` (tasks: see sim_bridge.live.lab_tasks);
``world:=...`` overrides the task's world, ``robot:=NAME`` and ``robot_pose:='[x, y, yaw]'`` its
robot (the lab robot in every task's world; see sim.launch.py), ``gui:=true`` opens the pybullet
window.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription, OpaqueFunction
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from sim_bridge.live.lab_tasks import LAB_TASKS


def task_params_files(node: str) -> list[str]:
    """Return scan_pkg's params file for ``node`` (params/<node>.yaml) if it ships one."""
    path = os.path.join(get_package_share_directory('scan_pkg'), 'params', node + '.yaml')
    return [path] if os.path.isfile(path) else []


def start_task(context):
    task_name = LaunchConfiguration('task').perform(context)
    if task_name not in LAB_TASKS:
        raise ValueError(f"unknown task '{task_name}': choose one of {', '.join(LAB_TASKS)}")
    task = LAB_TASKS[task_name]
    world = LaunchConfiguration('world').perform(context) or task.world
    share = FindPackageShare('sim_bridge')
    return [
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(
                PathJoinSubstitution([share, 'launch', 'sim.launch.py'])),
            launch_arguments={'world': world, 'gui': LaunchConfiguration('gui'),
                              'rviz': LaunchConfiguration('rviz'),
                              'robot': LaunchConfiguration('robot'),
                              'robot_pose': LaunchConfiguration('robot_pose')}.items(),
        ),
        Node(package='scan_pkg', executable=task.node, output='screen',
             parameters=[*task_params_files(task.node), {'use_sim_time': True}]),
    ]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('task', default_value='scan_ahead',
                              description=f"lab task: {', '.join(LAB_TASKS)}"),
        DeclareLaunchArgument('world', default_value='',
                              description="world to use instead of the task's"),
        DeclareLaunchArgument('robot', default_value='',
                              description="robot model to spawn instead of the world's"),
        DeclareLaunchArgument('robot_pose', default_value='',
                              description="the robot's start [x, y, yaw] (m, m, rad)"),
        DeclareLaunchArgument('gui', default_value='false',
                              description='open the pybullet window'),
        DeclareLaunchArgument('rviz', default_value='false', description='start RViz'),
        OpaqueFunction(function=start_task),
    ])
