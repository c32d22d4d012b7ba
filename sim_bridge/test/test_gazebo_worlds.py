"""
Tests of opening what Gazebo opens: every SDF version, its examples' XML, what is not simulated.

The worlds and models here are written by the tests, in the forms Gazebo's own files take:
Gazebo Sim's ``empty.sdf`` (a comment quoting shell commands with ``--``, ``<gz:...>``
elements never declared, cameras, lights, system plugins), Classic's ``sun`` model folder,
3-D lidars, ``<cone>`` and ``<heightmap>`` collisions, sizes left to SDF's defaults.
"""

import math
import os
from pathlib import Path

import pytest

from sim_bridge.common import paths
from sim_bridge.simulation.sdf import load_model
from sim_bridge.simulation.sdf_values import SdfError
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World, WorldError

#: Real third-party Gazebo assets beside the repository (../shared/gazebo_assets, see its
#: README), read in place; GAZEBO_ASSETS names another copy.
ASSETS = Path(os.environ.get('GAZEBO_ASSETS') or
              Path(__file__).resolve().parents[3] / 'shared' / 'gazebo_assets')

#: A world as Gazebo Sim's examples/worlds/empty.sdf writes one (abridged, same XML forms).
EMPTY_SDF = """<?xml version="1.0" ?>
<!--
  Try inserting a model:

gz service -s /world/empty/create \\
--reqtype gz.msgs.EntityFactory \\
--timeout 300 \\
--req 'sdf: '\\
'"<?xml version=\\"1.0\\" ?>'\\
-->
<sdf version="{version}">
  <world name="empty">
    <physics name="1ms" type="ignored">
      <max_step_size>0.001</max_step_size>
      <real_time_factor>1.0</real_time_factor>
    </physics>
    <plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"></plugin>
    <plugin filename="gz-sim-scene-broadcaster-system"
      name="gz::sim::systems::SceneBroadcaster"></plugin>
    <gz:policies>
      <include_gui_default_plugins>false</include_gui_default_plugins>
    </gz:policies>
    <light type="directional" name="sun">
      <cast_shadows>true</cast_shadows>
      <direction>-0.5 0.1 -0.9</direction>
    </light>
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="collision">
          <geometry><plane><normal>0 0 1</normal><size>100 100</size></plane></geometry>
        </collision>
      </link>
    </model>
    {models}
  </world>
</sdf>
"""

SHAPES = """
    <model name="cone"><static>true</static><pose>2 0 0.5 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><cone><radius>0.5</radius>
        <length>1</length></cone></geometry></collision></link></model>
    <model name="ball"><static>true</static><pose>0 2 0.5 0 0 0</pose>
      <link name="l"><collision name="c"><geometry><sphere/></geometry></collision>
      </link></model>
    <model name="terrain"><static>true</static>
      <link name="l"><collision name="c"><geometry><heightmap><uri>h.png</uri></heightmap>
      </geometry></collision></link></model>
    <model name="velodyne"><static>true</static><pose>-2 -2 0.5 0 0 0</pose>
      <link name="l">
        <collision name="c"><geometry><box><size>0.2 0.2 1</size></box></geometry></collision>
        <sensor name="vlp16" type="gpu_lidar"><lidar><scan>
          <horizontal><samples>1800</samples></horizontal>
          <vertical><samples>16</samples><min_angle>-0.26</min_angle></vertical>
        </scan></lidar></sensor>
        <sensor name="eye" type="camera"><camera><horizontal_fov>1</horizontal_fov></camera>
        </sensor>
        <light name="lamp" type="spot"/>
      </link></model>
"""


@pytest.mark.parametrize('version', ['1.0', '1.4', '1.6', '1.9', '1.10', '1.11', '1.12'])
def test_an_empty_sdf_like_world_opens_in_every_sdf_version(version, tmp_path):
    path = tmp_path / 'empty.sdf'
    path.write_text(EMPTY_SDF.format(version=version, models=''))
    world = World.load(path, robot=paths.models_dir() / 'turtlebot3_burger')
    assert world.name == 'empty' and world.physics_step_s == 0.001
    assert world.floor_size == (100.0, 100.0) and world.obstacles == ()
    assert world.ignored.startswith('ignored: 1 light, ')
    assert 'plugins gz-sim-physics-system, gz-sim-scene-broadcaster-system' in world.ignored


def test_what_is_not_simulated_is_one_ignored_line_never_a_refused_world(tmp_path):
    path = tmp_path / 'shapes.sdf'
    path.write_text(EMPTY_SDF.format(version='1.11', models=SHAPES))
    world = World.load(path, robot=paths.models_dir() / 'turtlebot3_burger')
    for part in ('3-D lidar vlp16', 'sensor eye (camera)', '<heightmap> collision c',
                 '2 lights'):
        assert part in world.ignored
    assert world.ignored.count('\n') == 0
    # The cone is SDF's: base circle of 0.5 m on the floor, apex 1 m up; the sphere SDF's
    # default, radius 1 m.
    cone, ball, velodyne = (world.obstacle(name) for name in ('cone', 'ball', 'velodyne'))
    (cone_slice,) = world.obstacle_footprints('cone')
    low, high = world.floor_slice.band
    assert cone_slice.bounds()[2] - 2.0 == pytest.approx(0.5 * (1.0 - low), abs=0.01)
    assert ball.shapes[0].radius == 1.0 and velodyne.shapes
    assert world.robot.lidar.samples == 360  # the robot's lidar, not the 3-D one


#: A world as gz-sim's sensor examples (gpu_lidar_retro_values_sensor.sdf) write one: the
#: ground plane is a 20 x 20 x 0.1 m box centred on z = 0 (its <plane> commented out), a 3-D
#: lidar on a floating box, and two 1 m boxes standing on z = 0.
SLAB_GROUND_SDF = """<?xml version="1.0" ?>
<sdf version="1.6">
  <world name="retro">
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="collision">
          <geometry>
            <!--plane>
              <normal>0 0 1</normal>
              <size>100 100</size>
            </plane-->
            <box><size>20 20 0.1</size></box>
          </geometry>
        </collision>
      </link>
    </model>
    <model name="box_a"><pose>2 -1 0.5 0 0 0</pose>
      <link name="box_link"><collision name="c"><geometry><box><size>1 1 1</size></box>
      </geometry></collision></link></model>
    {mat}
    <model name="model_with_lidar"><pose>4 0 0.5 0 0.0 3.14</pose><static>true</static>
      <link name="link"><pose>0.05 0.05 0.05 0 0 0</pose>
        <collision name="collision"><geometry><box><size>0.1 0.1 0.1</size></box></geometry>
        </collision>
        <sensor name="gpu_lidar" type="gpu_lidar"><lidar><scan>
          <horizontal><samples>640</samples><min_angle>-1.396263</min_angle>
            <max_angle>1.396263</max_angle></horizontal>
          <vertical><samples>16</samples></vertical></scan></lidar></sensor>
      </link>
    </model>
  </world>
</sdf>
"""


def test_a_ground_plane_written_as_a_slab_is_the_floor_never_an_obstacle(tmp_path):
    path = tmp_path / 'retro.sdf'
    path.write_text(SLAB_GROUND_SDF.format(mat=''))
    world = World.load(path, robot=paths.models_dir() / 'turtlebot3_burger')
    assert [obstacle.name for obstacle in world.obstacles] == ['box_a', 'model_with_lidar']
    assert world.floor_size == (20.0, 20.0)
    # The robot stands on the slab's top, 0.05 m up: the box standing on z = 0 is 0.05 m
    # lower for it, as in Gazebo.
    assert world.obstacle('box_a').shapes[0].z_range() == pytest.approx((-0.05, 0.95))
    with Simulator(world) as simulator:
        scan = simulator.scan()
    ahead = scan.ranges[0]  # the Burger's 0 rad: straight ahead, between the two boxes
    assert math.isinf(ahead)


@pytest.mark.skipif(not (ASSETS / 'turtlebot3_gazebo_sim').is_dir(),
                    reason='../shared/gazebo_assets is not beside the repository')
def test_robotis_burger_spawns_on_a_slab_ground_plane(tmp_path, monkeypatch):
    models = ASSETS / 'turtlebot3_gazebo_sim' / 'models'  # read in place
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(models))
    path = tmp_path / 'retro.sdf'
    path.write_text(SLAB_GROUND_SDF.format(mat=''))
    world = World.load(path, robot=models / 'turtlebot3_burger')
    assert 'ground_plane' not in world.footprint_owners()
    assert world.robot.lidar.frame_id == 'base_scan' and world.floor_size == (20.0, 20.0)


def test_a_step_on_the_floor_smaller_than_a_floor_is_still_an_obstacle(tmp_path):
    step = ('<model name="step"><static>true</static><pose>0.5 0 0.1 0 0 0</pose><link name="l">'
            '<collision name="c"><geometry><box><size>2 2 0.1</size></box></geometry>'
            '</collision></link></model>')
    path = tmp_path / 'retro.sdf'
    path.write_text(SLAB_GROUND_SDF.format(mat=step))
    with pytest.raises(WorldError, match="overlaps obstacle 'step'"):
        World.load(path, robot=paths.models_dir() / 'turtlebot3_burger')


def test_a_model_folder_holding_only_a_light_is_a_light(tmp_path, monkeypatch):
    (tmp_path / 'sun').mkdir()
    (tmp_path / 'sun' / 'model.config').write_text(
        '<?xml version="1.0"?><model><name>Sun</name><sdf version="1.6">model.sdf</sdf></model>')
    (tmp_path / 'sun' / 'model.sdf').write_text(
        '<?xml version="1.0" ?><sdf version="1.6"><light type="directional" name="sun">'
        '<cast_shadows>true</cast_shadows><pose>0 0 10 0 0 0</pose></light></sdf>')
    monkeypatch.setenv('GAZEBO_MODEL_PATH', str(tmp_path))
    assert load_model(tmp_path / 'sun').not_simulated == (('light', 'sun'),)
    path = tmp_path / 'classic.world'
    path.write_text('<?xml version="1.0"?><sdf version="1.6"><world name="default"><include>'
                    '<uri>model://sun</uri></include></world></sdf>')
    world = World.load(path, robot=paths.models_dir() / 'turtlebot3_burger')
    assert world.ignored == 'ignored: 5 joints, light sun'  # the joints: the Burger's


def test_three_slash_model_uris_name_the_model(tmp_path, monkeypatch):
    trimesh = pytest.importorskip('trimesh')
    (tmp_path / 'crate' / 'meshes').mkdir(parents=True)
    trimesh.creation.box((1.0, 1.0, 1.0)).export(tmp_path / 'crate' / 'meshes' / 'box.stl')
    (tmp_path / 'crate' / 'model.sdf').write_text(
        '<sdf version="1.5"><model name="crate"><link name="l"><collision name="c"><geometry>'
        '<mesh><uri>model:///crate/meshes/box.stl</uri></mesh></geometry></collision></link>'
        '</model></sdf>')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path))
    (shape,) = load_model(tmp_path / 'crate').shapes
    assert shape.z_range() == (-0.5, 0.5)


def test_xml_gazebo_cannot_read_either_is_still_an_error(tmp_path):
    path = tmp_path / 'cut.sdf'
    path.write_text(EMPTY_SDF.format(version='1.6', models='')[:-40])
    with pytest.raises(Exception, match='invalid XML') as caught:
        World.load(path)
    assert 'cut.sdf' in str(caught.value)
    with pytest.raises(SdfError, match='invalid XML'):
        load_model(_unquoted_attribute_model(tmp_path))


def _unquoted_attribute_model(folder):
    (folder / 'bad').mkdir()
    (folder / 'bad' / 'model.sdf').write_text(
        '<sdf version="1.6"><model name="bad"><link name=l/></model></sdf>')
    return folder / 'bad'
