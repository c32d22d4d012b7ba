"""
Tests of finding the files Gazebo and ROS users name: relative includes, ``$(find)``, packages.

The workspaces here are written by the tests in the forms users' files take: a course's world
``src/lab05/worlds/ex_5_2.sdf`` including ``file://src/lab05/description/robot.sdf`` (relative
to where the author starts Gazebo), and a ROS 1 description package whose xacro includes
``$(find PKG)/urdf/...`` and names ``package://PKG/meshes/...``, as ROBOTIS's TurtleBot3 does.
"""

import os
from pathlib import Path

import pytest

from sim_bridge.simulation.sdf import load_model
from sim_bridge.simulation.sdf_values import SdfError
from sim_bridge.simulation.world import World, WorldError

#: A robot SDF as a course writes one: a body, a 0..2π lidar and Gazebo Sim's diff drive.
ROBOT_SDF = """<?xml version="1.0"?>
<sdf version="1.8">
  <model name="{name}">
    <link name="base_link">
      <collision name="body"><pose>0 0 0.1 0 0 0</pose>
        <geometry><cylinder><radius>0.1</radius><length>0.2</length></cylinder></geometry>
      </collision>
      <sensor name="lidar" type="gpu_lidar"><pose>0 0 0.15 0 0 0</pose>
        <lidar><scan><horizontal><samples>{samples}</samples><min_angle>0</min_angle>
          <max_angle>6.28</max_angle></horizontal></scan>
          <range><min>0.12</min><max>3.5</max></range></lidar>
      </sensor>
    </link>
    <plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">
      <left_joint>left</left_joint><right_joint>right</right_joint>
      <wheel_separation>0.16</wheel_separation><wheel_radius>0.033</wheel_radius>
    </plugin>
  </model>
</sdf>
"""

#: The course's world: its robot included by a path relative to the workspace root.
COURSE_WORLD = """<?xml version="1.0"?>
<sdf version="1.8">
  <world name="ex_5_2">
    <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground Plane</uri>
    </include>
    <include><uri>{uri}</uri><pose>0 0 0 0 0 0</pose></include>
    <model name="wall"><static>true</static><pose>2 0 0.5 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><box><size>0.2 4 1</size></box>
      </geometry></collision></link></model>
  </world>
</sdf>
"""


#: Real third-party Gazebo assets beside the repository (../shared/gazebo_assets, see its
#: README), read in place; GAZEBO_ASSETS names another copy.
ASSETS = Path(os.environ.get('GAZEBO_ASSETS') or
              Path(__file__).resolve().parents[3] / 'shared' / 'gazebo_assets')


def course_workspace(root: Path, uri: str = 'file://src/lab05/description/robot.sdf') -> Path:
    """Write a course workspace under ``root``; return its world file."""
    description = root / 'src' / 'lab05' / 'description'
    worlds = root / 'src' / 'lab05' / 'worlds'
    description.mkdir(parents=True)
    worlds.mkdir(parents=True)
    (description / 'robot.sdf').write_text(ROBOT_SDF.format(name='lab05_bot', samples=360))
    world = worlds / 'ex_5_2.sdf'
    world.write_text(COURSE_WORLD.format(uri=uri))
    return world


@pytest.mark.parametrize('uri', ['file://src/lab05/description/robot.sdf',
                                 'src/lab05/description/robot.sdf'])
def test_an_include_relative_to_where_gazebo_starts_is_found(uri, tmp_path, monkeypatch):
    world_file = course_workspace(tmp_path / 'ws', uri)
    monkeypatch.chdir(tmp_path / 'ws')
    world = World.load(world_file)
    assert world.robot_model == 'lab05_bot' and world.robot.lidar.samples == 360
    assert [obstacle.name for obstacle in world.obstacles] == ['wall']


@pytest.mark.skipif(not (ASSETS / 'turtlebot3_gazebo_sim').is_dir(),
                    reason='../shared/gazebo_assets is not beside the repository')
def test_robotis_burger_folder_included_relative_to_where_gazebo_starts(tmp_path, monkeypatch):
    world_file = tmp_path / 'lab.sdf'  # ROBOTIS's folder, read in place, named from ASSETS
    world_file.write_text(COURSE_WORLD.format(
        uri='file://turtlebot3_gazebo_sim/models/turtlebot3_burger'))
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(ASSETS / 'turtlebot3_gazebo_sim' / 'models'))
    monkeypatch.chdir(ASSETS)
    world = World.load(world_file)
    assert world.robot_model == 'turtlebot3_burger' and world.robot.lidar.frame_id == 'base_scan'
    assert ASSETS.resolve() in world.robot.path.resolve().parents


def test_the_working_directory_wins_over_the_world_folder_as_in_sdformat(
        tmp_path, monkeypatch):
    world_file = course_workspace(tmp_path / 'ws', uri='file://robot.sdf')
    (world_file.parent / 'robot.sdf').write_text(ROBOT_SDF.format(name='beside', samples=90))
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    assert World.load(world_file).robot_model == 'beside'  # found beside the world only
    (elsewhere / 'robot.sdf').write_text(ROBOT_SDF.format(name='from_cwd', samples=180))
    monkeypatch.chdir(elsewhere)
    assert World.load(world_file).robot_model == 'from_cwd'


def test_an_include_on_sdf_path_or_the_resource_path_is_found(tmp_path, monkeypatch):
    world_file = course_workspace(tmp_path / 'ws')
    monkeypatch.chdir(tmp_path)  # not the workspace root
    monkeypatch.setenv('SDF_PATH', str(tmp_path / 'ws'))
    assert World.load(world_file).robot_model == 'lab05_bot'
    monkeypatch.delenv('SDF_PATH')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path / 'ws'))
    assert World.load(world_file).robot_model == 'lab05_bot'


def test_an_include_found_nowhere_names_the_working_directory_and_what_to_do(
        tmp_path, monkeypatch):
    world_file = course_workspace(tmp_path / 'ws')
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv('GZ_SIM_RESOURCE_PATH', raising=False)
    with pytest.raises(WorldError) as caught:
        World.load(world_file)
    message = str(caught.value)
    assert 'file://src/lab05/description/robot.sdf not found in the working directory' in message
    assert str(tmp_path) in message and 'GZ_SIM_RESOURCE_PATH' in message
    assert '\n' not in message


#: A ROS 1 description package's main xacro, as ROBOTIS's turtlebot3_burger.urdf.xacro is
#: written: its parts included by $(find), a package:// mesh, Gazebo Classic ROS 1 tags.
ROS1_XACRO = """<?xml version="1.0" ?>
<robot name="rbot" xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:include filename="$(find {package})/urdf/common_properties.xacro"/>
  <xacro:include filename="$(find {package})/urdf/rbot.gazebo.xacro"/>
  <link name="base_footprint"/>
  <joint name="base_joint" type="fixed">
    <parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0.0 0.0 0.010" rpy="0 0 0"/>
  </joint>
  <link name="base_link">
    <collision><origin xyz="-0.032 0 0.070" rpy="0 0 0"/>
      <geometry><mesh filename="package://{package}/meshes/bases/base.stl"/></geometry>
    </collision>
  </link>
  <joint name="scan_joint" type="fixed">
    <parent link="base_link"/><child link="base_scan"/>
    <origin xyz="-0.032 0 0.172" rpy="0 0 0"/>
  </joint>
  <link name="base_scan">
    <collision><origin xyz="0.015 0 -0.0065" rpy="0 0 0"/>
      <geometry><cylinder length="0.0315" radius="${{lds_radius}}"/></geometry>
    </collision>
  </link>
</robot>
"""
COMMON_XACRO = """<?xml version="1.0" ?>
<robot name="xacro_properties" xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:property name="lds_radius" value="0.055"/>
</robot>
"""
#: ROS 1's gazebo_ros plugins: libgazebo_ros_laser.so, and the diff drive's camelCase names.
GAZEBO_XACRO = """<?xml version="1.0" ?>
<robot name="rbot_sim" xmlns:xacro="http://ros.org/wiki/xacro">
  <gazebo reference="base_scan">
    <sensor type="ray" name="lds_lfcd_sensor">
      <update_rate>5</update_rate>
      <ray><scan><horizontal><samples>360</samples><resolution>1</resolution>
        <min_angle>0.0</min_angle><max_angle>6.28319</max_angle></horizontal></scan>
        <range><min>0.120</min><max>3.5</max><resolution>0.015</resolution></range></ray>
      <plugin name="gazebo_ros_lds_lfcd_controller" filename="libgazebo_ros_laser.so">
        <topicName>scan</topicName><frameName>base_scan</frameName>
      </plugin>
    </sensor>
  </gazebo>
  <gazebo>
    <plugin name="rbot_controller" filename="libgazebo_ros_diff_drive.so">
      <commandTopic>cmd_vel</commandTopic><odometryTopic>odom</odometryTopic>
      <odometryFrame>odom</odometryFrame><publishOdomTF>true</publishOdomTF>
      <robotBaseFrame>base_footprint</robotBaseFrame><updateRate>30</updateRate>
      <leftJoint>wheel_left_joint</leftJoint><rightJoint>wheel_right_joint</rightJoint>
      <wheelSeparation>0.160</wheelSeparation><wheelDiameter>0.066</wheelDiameter>
      <wheelAcceleration>1</wheelAcceleration><wheelTorque>10</wheelTorque>
    </plugin>
  </gazebo>
</robot>
"""
PACKAGE_XML = """<?xml version="1.0"?>
<package format="2"><name>{name}</name><version>1.0.0</version>
  <description>test</description><maintainer email="a@b.c">a</maintainer>
  <license>Apache 2.0</license><buildtool_depend>catkin</buildtool_depend></package>
"""


def ros1_description(src: Path, package: str = 'rbot_description') -> Path:
    """Write a ROS 1 description package into workspace folder ``src``; return its xacro."""
    trimesh = pytest.importorskip('trimesh')
    folder = src / package
    (folder / 'urdf').mkdir(parents=True)
    (folder / 'meshes' / 'bases').mkdir(parents=True)
    (folder / 'package.xml').write_text(PACKAGE_XML.format(name=package))
    trimesh.creation.box((0.14, 0.14, 0.143)).export(folder / 'meshes' / 'bases' / 'base.stl')
    (folder / 'urdf' / 'common_properties.xacro').write_text(COMMON_XACRO)
    (folder / 'urdf' / 'rbot.gazebo.xacro').write_text(GAZEBO_XACRO)
    xacro_file = folder / 'urdf' / 'rbot.urdf.xacro'
    xacro_file.write_text(ROS1_XACRO.format(package=package))
    return xacro_file


@pytest.fixture
def no_ros(monkeypatch, tmp_path):
    """Neither a sourced ROS 2 workspace nor ROS 1's package path, away from the workspace."""
    for variable in ('AMENT_PREFIX_PATH', 'ROS_PACKAGE_PATH', 'GZ_SIM_RESOURCE_PATH'):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.chdir(tmp_path)


def test_a_ros1_xacro_finds_its_own_package_without_a_sourced_ros(no_ros, tmp_path):
    model = load_model(ros1_description(tmp_path / 'catkin_ws' / 'src'))
    assert model.name == 'rbot'
    body = next(shape for shape in model.shapes if shape.kind == 'mesh')
    assert body.z_range() == pytest.approx((0.0085, 0.1515))  # 0.143 m tall, centre 0.08 m
    lidar = model.lidar
    assert (lidar.samples, lidar.max_angle, lidar.frame_id) == (360, 6.28319, 'base_scan')
    drive = model.drive  # ROS 1's camelCase elements
    assert (drive.wheel_separation, drive.wheel_radius, drive.odometry_rate) == (0.16, 0.033,
                                                                                 30.0)
    assert drive.limits.max_linear_accel == 1.0 and drive.publish_tf


def test_a_sibling_package_of_the_workspace_and_ros_package_path_are_found(
        no_ros, tmp_path, monkeypatch):
    src = tmp_path / 'catkin_ws' / 'src'
    ros1_description(src)
    (src / 'rbot_gazebo' / 'urdf').mkdir(parents=True)
    (src / 'rbot_gazebo' / 'package.xml').write_text(PACKAGE_XML.format(name='rbot_gazebo'))
    sibling = src / 'rbot_gazebo' / 'urdf' / 'rbot.urdf.xacro'
    sibling.write_text(ROS1_XACRO.format(package='rbot_description'))
    assert load_model(sibling).lidar.samples == 360
    outside = tmp_path / 'robot.urdf.xacro'  # in no package: only ROS_PACKAGE_PATH finds it
    outside.write_text(ROS1_XACRO.format(package='rbot_description'))
    with pytest.raises(SdfError, match="ROS package 'rbot_description' not found"):
        load_model(outside)
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path / 'catkin_ws'))
    assert load_model(outside).lidar.samples == 360


def test_a_package_nowhere_is_one_line_naming_it_and_ros_package_path(
        no_ros, tmp_path, monkeypatch):
    src = tmp_path / 'catkin_ws' / 'src'
    xacro_file = ros1_description(src)
    (src / 'rbot_description' / 'CATKIN_IGNORE').touch()  # ignored by rospack, not by its own
    outside = tmp_path / 'robot.urdf.xacro'
    outside.write_text(ROS1_XACRO.format(package='rbot_description'))
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(src))
    with pytest.raises(SdfError) as caught:
        load_model(outside)
    message = str(caught.value)
    assert "ROS package 'rbot_description' not found" in message
    assert 'ROS_PACKAGE_PATH' in message and '\n' not in message
    assert 'AMENT_PREFIX_PATH is not set' not in message
    assert load_model(xacro_file).name == 'rbot'  # its own package tree still holds it
