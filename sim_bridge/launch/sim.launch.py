"""Start the simulator bridge for one world, optionally with its pybullet window and RViz."""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    share = FindPackageShare('sim_bridge')
    return LaunchDescription([
        DeclareLaunchArgument('world', default_value='obstacles',
                              description='world name (worlds/<name>.yaml) or path'),
        DeclareLaunchArgument('gui', default_value='false',
                              description='open the pybullet window'),
        DeclareLaunchArgument('rviz', default_value='false', description='start RViz'),
        DeclareLaunchArgument('params_file',
                              default_value=PathJoinSubstitution([share, 'params', 'sim.yaml']),
                              description='parameters of the sim_bridge node'),
        Node(
            package='sim_bridge',
            executable='sim_bridge',
            output='screen',
            parameters=[
                LaunchConfiguration('params_file'),
                {
                    'world': LaunchConfiguration('world'),
                    'gui': ParameterValue(LaunchConfiguration('gui'), value_type=bool),
                },
            ],
        ),
        Node(
            package='rviz2',
            executable='rviz2',
            arguments=['-d', PathJoinSubstitution([share, 'params', 'lab.rviz'])],
            parameters=[{'use_sim_time': True}],
            condition=IfCondition(LaunchConfiguration('rviz')),
        ),
    ])
