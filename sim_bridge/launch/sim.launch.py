"""
Start the simulator bridge for one world, optionally with its pybullet window and RViz.

``robot:=NAME`` spawns the robot model NAME (a model folder, also from GZ_SIM_RESOURCE_PATH)
instead of the world's, at ``robot_pose:='[x, y, yaw]'`` (m, m, rad; default: the world's robot
start), as ros_gz_sim's create does in a Gazebo world.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare
import yaml


def start_bridge(context):
    """Return the sim_bridge node; robot_pose is given to it only when the argument is set."""
    spawn = {'robot': LaunchConfiguration('robot').perform(context)}
    pose = LaunchConfiguration('robot_pose').perform(context)
    if pose:
        spawn['robot_pose'] = [float(value) for value in yaml.safe_load(pose)]
    return [Node(
        package='sim_bridge',
        executable='sim_bridge',
        output='screen',
        parameters=[
            LaunchConfiguration('params_file'),
            {
                'world': LaunchConfiguration('world'),
                'gui': ParameterValue(LaunchConfiguration('gui'), value_type=bool),
                **spawn,
            },
        ],
    )]


def generate_launch_description():
    share = FindPackageShare('sim_bridge')
    return LaunchDescription([
        DeclareLaunchArgument('world', default_value='obstacles',
                              description='world name (worlds/<name>.yaml) or path'),
        DeclareLaunchArgument('robot', default_value='',
                              description="robot model to spawn instead of the world's"),
        DeclareLaunchArgument('robot_pose', default_value='',
                              description="the robot's start [x, y, yaw] (m, m, rad; default: "
                                          "the world's)"),
        DeclareLaunchArgument('gui', default_value='false',
                              description='open the pybullet window'),
        DeclareLaunchArgument('rviz', default_value='false', description='start RViz'),
        DeclareLaunchArgument('params_file',
                              default_value=PathJoinSubstitution([share, 'params', 'sim.yaml']),
                              description='parameters of the sim_bridge node'),
        OpaqueFunction(function=start_bridge),
        Node(
            package='rviz2',
            executable='rviz2',
            arguments=['-d', PathJoinSubstitution([share, 'params', 'lab.rviz'])],
            parameters=[{'use_sim_time': True}],
            condition=IfCondition(LaunchConfiguration('rviz')),
        ),
    ])
