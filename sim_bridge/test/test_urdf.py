"""
Tests of simulation.urdf: URDF and xacro robots spawned as ``ros_gz_sim create`` spawns them.

The robots are written here: a URDF with ``package://`` meshes and Gazebo Classic
``<gazebo>`` tags, and a xacro robot with a macro, ``model://`` and ``package://`` meshes and
Gazebo Sim tags.
"""

import math

import pytest
from sim_bridge.ros.rviz import robot_description
from sim_bridge.runner.run import run_simulation
from sim_bridge.simulation.sdf import load_model
from sim_bridge.simulation.sdf_values import SdfError
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World
import trimesh
import xacro

LINKS = """
  <link name="base_footprint"/>
  <joint name="base_joint" type="fixed">
    <parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0 0 0.01" rpy="0 0 0"/>
  </joint>
  <link name="base_link">
    <collision>
      <origin xyz="-0.02 0 0.06" rpy="0 0 0"/>
      <geometry><mesh filename="{body}" scale="1 1 1"/></geometry>
    </collision>
  </link>
  <joint name="wheel_left_joint" type="continuous">
    <parent link="base_link"/><child link="wheel_left_link"/>
    <origin xyz="0 0.08 0.023" rpy="-1.5708 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <link name="wheel_left_link">
    <collision><geometry><cylinder length="0.018" radius="0.033"/></geometry></collision>
  </link>
  <joint name="scan_joint" type="fixed">
    <parent link="base_link"/><child link="base_scan"/>
    <origin xyz="-0.03 0 0.17" rpy="0 0 0"/>
  </joint>
  <link name="base_scan">
    <collision><geometry><cylinder length="0.03" radius="0.05"/></geometry></collision>
  </link>
"""

CLASSIC_TAGS = """
  <gazebo reference="base_scan">
    <sensor type="ray" name="hls_lfcd_lds">
      <update_rate>5</update_rate>
      <ray><scan><horizontal><samples>360</samples><min_angle>0</min_angle>
        <max_angle>6.28319</max_angle></horizontal></scan>
        <range><min>0.12</min><max>3.5</max></range></ray>
      <plugin name="scan" filename="libgazebo_ros_ray_sensor.so">
        <ros><remapping>~/out:=scan</remapping></ros>
        <output_type>sensor_msgs/LaserScan</output_type><frame_name>base_scan</frame_name>
      </plugin>
    </sensor>
  </gazebo>
  <gazebo>
    <plugin name="diff_drive" filename="libgazebo_ros_diff_drive.so">
      <left_joint>wheel_left_joint</left_joint><right_joint>wheel_right_joint</right_joint>
      <wheel_separation>0.160</wheel_separation><wheel_diameter>0.066</wheel_diameter>
      <max_wheel_torque>20</max_wheel_torque><max_wheel_acceleration>1.0</max_wheel_acceleration>
      <command_topic>cmd_vel</command_topic><publish_odom_tf>true</publish_odom_tf>
      <odometry_frame>odom</odometry_frame><robot_base_frame>base_footprint</robot_base_frame>
    </plugin>
  </gazebo>
"""

SIM_XACRO = """<?xml version="1.0"?>
<robot name="xbot" xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:property name="lidar_samples" value="720"/>
  <xacro:macro name="bumper" params="side y">
    <link name="bumper_${side}">
      <collision><geometry><mesh filename="model://xbot_meshes/bumper.stl"/></geometry>
      </collision>
    </link>
    <joint name="bumper_${side}_joint" type="fixed">
      <parent link="base_link"/><child link="bumper_${side}"/>
      <origin xyz="0.08 ${y} 0.03" rpy="0 0 0"/>
    </joint>
  </xacro:macro>
  """ + LINKS + """
  <xacro:bumper side="left" y="0.05"/>
  <xacro:bumper side="right" y="-0.05"/>
  <gazebo reference="base_scan">
    <sensor name="gpu_lidar" type="gpu_lidar">
      <gz_frame_id>base_scan</gz_frame_id><update_rate>10</update_rate>
      <lidar><scan><horizontal><samples>${lidar_samples}</samples><min_angle>-3.14159</min_angle>
        <max_angle>3.14159</max_angle></horizontal></scan>
        <range><min>0.1</min><max>8.0</max></range></lidar>
    </sensor>
  </gazebo>
  <gazebo>
    <plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">
      <left_joint>wheel_left_joint</left_joint><right_joint>wheel_right_joint</right_joint>
      <wheel_separation>0.16</wheel_separation><wheel_radius>0.033</wheel_radius>
      <topic>cmd_vel</topic><frame_id>odom</frame_id><child_frame_id>base_footprint</child_frame_id>
    </plugin>
  </gazebo>
</robot>
"""


@pytest.fixture
def packages(tmp_path, monkeypatch):
    """Make an install prefix holding my_robot's body mesh, and a model folder's bumper."""
    share = tmp_path / 'install' / 'share' / 'my_robot' / 'meshes'
    share.mkdir(parents=True)
    trimesh.creation.box((0.14, 0.14, 0.1)).export(share / 'body.stl')
    (tmp_path / 'models' / 'xbot_meshes').mkdir(parents=True)
    trimesh.creation.box((0.02, 0.04, 0.04)).export(tmp_path / 'models' / 'xbot_meshes' /
                                                    'bumper.stl')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'install'))
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path / 'models'))
    return tmp_path


def write_urdf(folder, body='package://my_robot/meshes/body.stl'):
    path = folder / 'robot.urdf'
    path.write_text('<?xml version="1.0"?>\n<robot name="cbot">' + LINKS.format(body=body)
                    + CLASSIC_TAGS + '</robot>\n')
    return path


def write_xacro(folder):
    path = folder / 'xbot.urdf.xacro'
    path.write_text(SIM_XACRO.replace('{body}', 'package://my_robot/meshes/body.stl'))
    return path


def test_a_urdf_robot_has_its_links_meshes_and_classic_lidar_and_drive(packages):
    model = load_model(write_urdf(packages))
    assert model.name == 'cbot'
    body, wheel, scanner = model.shapes
    # Joint origins chain: base_link 1 cm up, the body's origin 6 cm above that.
    assert (body.kind, body.x, body.z) == ('mesh', pytest.approx(-0.02), pytest.approx(0.07))
    assert body.mesh.source.endswith('share/my_robot/meshes/body.stl')
    assert (wheel.y, wheel.z, wheel.roll) == (pytest.approx(0.08), pytest.approx(0.033),
                                              pytest.approx(-1.5708))
    assert scanner.z == pytest.approx(0.18)
    lidar = model.lidar
    assert (lidar.samples, lidar.range_max, lidar.update_rate, lidar.frame_id) == \
        (360, 3.5, 5.0, 'base_scan')
    assert lidar.pose[:3] == pytest.approx((-0.03, 0.0, 0.18))
    drive = model.drive
    assert (drive.wheel_separation, drive.wheel_radius, drive.base_frame) == \
        (0.16, 0.033, 'base_footprint')
    assert 'joint' in dict(model.not_simulated)


def test_a_xacro_robot_has_its_macros_expanded_and_sim_tags_read(packages):
    model = load_model(write_xacro(packages))
    assert model.name == 'xbot'
    assert len(model.shapes) == 5  # body, wheel, scanner, two bumpers from the macro
    bumpers = [shape for shape in model.shapes
               if shape.kind == 'mesh' and 'bumper' in shape.mesh.source]
    assert [round(shape.y, 3) for shape in bumpers] == [0.05, -0.05]
    assert (model.lidar.samples, model.lidar.frame_id) == (720, 'base_scan')
    assert model.lidar.min_angle == pytest.approx(-math.pi, abs=1e-5)
    assert (model.drive.wheel_separation, model.drive.base_frame) == (0.16, 'base_footprint')


def test_a_urdf_robot_drives_and_scans_in_a_world(packages):
    world = World.load('room', robot=write_xacro(packages), robot_pose=(0.0, 0.0, 0.0))
    with Simulator(world) as simulator:
        assert len(simulator.scan().ranges) == 720
        simulator.set_command(0.2, 0.0)
        for _ in range(100):
            simulator.step(0.01)
        assert simulator.pose[0] > 0.1


def test_the_runner_spawns_a_urdf_robot_as_its_robot_parameter(packages, tmp_path):
    result = run_simulation('room', ['wanderbot'], duration_s=2.0, robot=str(write_urdf(packages)),
                            start=(0.0, 0.0, 0.0), out_dir=tmp_path / 'run', quiet=True,
                            record=False, plot=False)
    assert result.ok and result.metrics['distance_m'] > 0.05


@pytest.mark.parametrize('body, problem', [
    ('package://nowhere/meshes/body.stl', r'mesh package://nowhere/meshes/body.stl: not found'),
    ('http://example.org/body.stl', 'unsupported URI'),
])
def test_a_urdf_mesh_that_cannot_be_found_says_where_it_looked(body, problem, packages):
    with pytest.raises(SdfError, match=problem) as caught:
        load_model(write_urdf(packages, body))
    assert str(caught.value).startswith(str(packages / 'robot.urdf'))


def test_a_broken_xacro_is_one_error_naming_the_file(tmp_path):
    path = tmp_path / 'broken.xacro'
    path.write_text('<robot xmlns:xacro="http://ros.org/wiki/xacro"><xacro:undefined_macro/>'
                    '</robot>')
    with pytest.raises(SdfError, match='broken.xacro: xacro cannot expand it'):
        load_model(path)


def test_a_urdf_robots_description_for_rviz_is_its_own_file_expanded(packages):
    path = write_xacro(packages)
    model = load_model(path)
    assert robot_description(model, 'base_footprint', 'base_scan', (0.0,) * 6) == (
        xacro.process_file(str(path)).toxml())


#: A robot in nav2_minimal_tb4_description's gz form: the RPLIDAR's joint turns its link
#: +90° (rpy="0 0 ${pi/2}") 4 cm behind the centre, and its gpu_lidar scans 0..6.28 rad in that
#: link's frame (<gz_frame_id>).
TB4_FORM_XACRO = """<?xml version="1.0"?>
<robot name="tb4_form" xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:property name="cm2m" value="${1/100.0}"/>
  <link name="base_link">
    <collision><origin xyz="0 0 0.06"/>
      <geometry><cylinder length="0.1" radius="0.17"/></geometry></collision>
  </link>
  <joint name="rplidar_joint" type="fixed">
    <parent link="base_link"/><child link="rplidar_link"/>
    <origin xyz="${-4*cm2m} 0 ${19.3*cm2m}" rpy="0 0 ${pi/2}"/>
  </joint>
  <link name="rplidar_link">
    <collision><origin xyz="0 ${1.3*cm2m} ${-1.9*cm2m}"/>
      <geometry><box size="0.071 0.1 0.06"/></geometry></collision>
  </link>
  <gazebo reference="rplidar_link">
    <sensor name="rplidar" type="gpu_lidar">
      <update_rate>10.0</update_rate><gz_frame_id>rplidar_link</gz_frame_id>
      <lidar><scan><horizontal><samples>360</samples><resolution>1.0</resolution>
        <min_angle>0.000</min_angle><max_angle>6.280000</max_angle></horizontal></scan>
        <range><min>0.164</min><max>20.0</max><resolution>0.01</resolution></range></lidar>
    </sensor>
  </gazebo>
  <gazebo>
    <plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">
      <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
      <wheel_separation>0.233</wheel_separation><wheel_radius>0.03575</wheel_radius>
      <topic>cmd_vel</topic><frame_id>odom</frame_id><child_frame_id>base_link</child_frame_id>
    </plugin>
  </gazebo>
</robot>
"""


#: A wall 2.5 m from the robot's centre (x0, y0, x1, y1 in m), by where it stands.
WALLS = {'ahead': (2.575, -3.0, 2.575, 3.0), 'left': (-3.0, 2.575, 3.0, 2.575)}


@pytest.mark.parametrize('side', ['ahead', 'left'])
def test_a_lidar_turned_on_its_joint_scans_from_where_its_link_points(side, tmp_path):
    # Gazebo's gpu_lidar casts angle 0 along its link's x axis: for a TurtleBot4 that is the
    # robot's left (+y), so with a wall only ahead ranges[0] is inf in Gazebo too, and the
    # wall is at 3π/2 in the scan (index 269 of 360: 6.28 rad over 359 steps).
    robot = tmp_path / 'tb4_form.urdf.xacro'
    robot.write_text(TB4_FORM_XACRO)
    x0, y0, x1, y1 = WALLS[side]
    world_file = tmp_path / 'wall.yaml'
    world_file.write_text(f'walls:\n  - start: [{x0}, {y0}]\n    end: [{x1}, {y1}]\n')
    world = World.load(world_file, robot=robot)
    lidar = world.robot.lidar
    assert lidar.frame_id == 'rplidar_link'
    assert lidar.pose == pytest.approx((-0.04, 0.0, 0.193, 0.0, 0.0, math.pi / 2))
    assert ('base_link', 'rplidar_link') in [joint[:2] for joint in world.robot.joints]
    with Simulator(world) as simulator:
        scan = simulator.scan()
    ahead = round(1.5 * math.pi / scan.angle_increment)
    if side == 'ahead':  # 2.5 m from the wall's face to the centre, 2.54 m to the lidar
        assert math.isinf(scan.ranges[0])
        assert scan.ranges[ahead] == pytest.approx(2.54, abs=0.01)
    else:
        assert scan.ranges[0] == pytest.approx(2.5, abs=0.01)
        assert math.isinf(scan.ranges[ahead])
