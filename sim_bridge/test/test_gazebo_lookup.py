"""
Tests of finding the files Gazebo and ROS users name: relative includes, ``$(find)``, packages.

The workspaces here are written by the tests in the forms users' files take: a course's world
``src/lab05/worlds/ex_5_2.sdf`` including ``file://src/lab05/description/robot.sdf`` (relative
to where the author starts Gazebo), and a ROS 1 description package whose xacro includes
``$(find PKG)/urdf/...`` and names ``package://PKG/meshes/...``, as ROBOTIS's TurtleBot3 does.
"""

from pathlib import Path

import pytest

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


def test_the_working_directory_wins_over_the_world_folder_as_in_sdformat(tmp_path,
                                                                        monkeypatch):
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


def test_an_include_found_nowhere_names_the_working_directory_and_what_to_do(tmp_path,
                                                                            monkeypatch):
    world_file = course_workspace(tmp_path / 'ws')
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv('GZ_SIM_RESOURCE_PATH', raising=False)
    with pytest.raises(WorldError) as caught:
        World.load(world_file)
    message = str(caught.value)
    assert 'file://src/lab05/description/robot.sdf not found in the working directory' in message
    assert str(tmp_path) in message and 'GZ_SIM_RESOURCE_PATH' in message
    assert '\n' not in message
