"""Tests of reading Gazebo's own files: multi-link models, meshes, includes, plugins, worlds."""

import math
from pathlib import Path
import shutil

import numpy as np
import pytest

from sim_bridge.common import paths
from sim_bridge.simulation.geometry import triangulate
from sim_bridge.simulation.sdf import load_model, parse_model
from sim_bridge.simulation.sdf_drive import NO_SPEED_LIMIT
from sim_bridge.simulation.sdf_model import describe_ignored
from sim_bridge.simulation.sdf_values import SdfError
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World, WorldError


def extent(shapes) -> np.ndarray:
    """Return the (x, y, z) size (m) of the box holding every shape."""
    points = np.vstack([triangulate(shape)[0] @ shape.rotation().T + (shape.x, shape.y, shape.z)
                        for shape in shapes])
    return points.max(axis=0) - points.min(axis=0)


def sdf_model(name: str, body: str, pose: str = '') -> str:
    own_pose = f'<pose>{pose}</pose>' if pose else ''
    return f'<sdf version="1.9"><model name="{name}">{own_pose}{body}</model></sdf>'


def write_model(folder: Path, name: str, body: str, pose: str = '') -> Path:
    (folder / name).mkdir(parents=True, exist_ok=True)
    (folder / name / 'model.sdf').write_text(sdf_model(name, body, pose))
    return folder / name


BOX = ('<link name="link"><collision name="c"><pose>0 0 0.5 0 0 0</pose><geometry><box>'
       '<size>1 1 1</size></box></geometry></collision></link>')
LIDAR = ('<sensor name="{name}" type="gpu_lidar"><lidar><scan><horizontal><samples>{samples}'
         '</samples></horizontal></scan></lidar></sensor>')
DRIVE = ('<plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">'
         '<wheel_separation>0.3</wheel_separation><wheel_radius>0.05</wheel_radius></plugin>')
ROBOT = ('<link name="chassis"><collision name="c"><pose>0 0 0.1 0 0 0</pose><geometry>'
         '<cylinder><radius>0.1</radius><length>0.2</length></cylinder></geometry></collision>'
         + LIDAR.format(name='laser', samples=90) + '</link>' + DRIVE)


def test_the_project_burger_has_rolled_wheels_a_caster_its_lidar_and_drive():
    burger = load_model(paths.models_dir() / 'turtlebot3_burger')
    assert extent(burger.shapes) == pytest.approx((0.138, 0.178, 0.192), abs=1e-3)
    wheels = [shape for shape in burger.shapes if shape.kind == 'cylinder' and shape.roll]
    assert len(wheels) == 2 and {round(wheel.y, 3) for wheel in wheels} == {0.08, -0.08}
    assert all(wheel.roll == pytest.approx(-1.5708) for wheel in wheels)
    assert [shape.kind for shape in burger.shapes].count('sphere') == 1
    lidar = burger.lidar
    assert (lidar.samples, lidar.min_angle, lidar.max_angle) == (360, 0.0, 6.28)
    assert (lidar.range_min, lidar.range_max, lidar.update_rate) == (0.12, 3.5, 5.0)
    assert (lidar.frame_id, lidar.noise_stddev) == ('base_scan', 0.01)
    drive = burger.drive
    assert (drive.wheel_separation, drive.wheel_radius) == (0.160, 0.033)
    assert (drive.command_topic, drive.odometry_topic, drive.base_frame) == (
        'cmd_vel', 'odom', 'base_footprint')
    assert drive.limits.max_linear_accel == 1.0 and drive.command_timeout is None
    waffle = load_model(paths.models_dir() / 'turtlebot3_waffle')
    assert extent(waffle.shapes) == pytest.approx((0.281, 0.306, 0.141), abs=1e-3)
    assert waffle.drive.wheel_separation == 0.287 and waffle.is_robot


def test_the_lab_step_edits_the_burger_laser_to_36_samples_over_a_half_turn(tmp_path):
    folder = tmp_path / 'turtlebot3_burger'
    shutil.copytree(paths.models_dir() / 'turtlebot3_burger', folder)
    sdf = folder / 'model.sdf'
    sdf.write_text(sdf.read_text().replace('<samples>360</samples>', '<samples>36</samples>')
                   .replace('<min_angle>0</min_angle>', '<min_angle>-1.57</min_angle>')
                   .replace('<max_angle>6.28</max_angle>', '<max_angle>1.57</max_angle>'))
    lidar = load_model(folder).lidar
    assert (lidar.samples, lidar.min_angle, lidar.max_angle) == (36, -1.57, 1.57)
    assert lidar.frame_id == 'base_scan'


def test_link_and_collision_poses_compose_in_3d_with_relative_to():
    model = parse_model(sdf_model('m', (
        '<link name="a"><pose>1 0 0 0 0 1.5707963267948966</pose><collision name="c">'
        '<pose>1 0 0.5 0 0 0</pose><geometry><capsule><radius>0.1</radius><length>0.4'
        '</length></capsule></geometry></collision></link>'
        '<frame name="f"><pose relative_to="a">0 2 0 0 0 0</pose></frame>'
        '<link name="b"><pose relative_to="f">0 0 0 1.5707963267948966 0 0</pose>'
        '<collision name="e"><geometry><ellipsoid><radii>0.1 0.2 0.3</radii></ellipsoid>'
        '</geometry></collision></link>')), Path('m.sdf'))
    capsule, ellipsoid = model.shapes
    assert (capsule.kind, ellipsoid.kind) == ('capsule', 'ellipsoid')
    assert (capsule.x, capsule.y, capsule.z) == pytest.approx((1.0, 1.0, 0.5))
    assert (ellipsoid.x, ellipsoid.y) == pytest.approx((-1.0, 0.0))
    assert ellipsoid.size == pytest.approx((0.2, 0.4, 0.6))
    assert ellipsoid.roll == pytest.approx(math.pi / 2)


def test_meshes_stl_obj_and_a_dae_in_inches_are_scaled_as_gazebo_scales_them(
        tmp_path, monkeypatch):
    trimesh = pytest.importorskip('trimesh')
    meshes = tmp_path / 'crate' / 'meshes'
    meshes.mkdir(parents=True)
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    box.export(meshes / 'box.stl')
    box.export(meshes / 'box.obj')
    dae = trimesh.exchange.dae.export_collada(box).decode()
    assert '<unit' not in dae
    (meshes / 'box.dae').write_text(dae.replace('<up_axis>', '<unit name="inch" '
                                                'meter="0.0254"/><up_axis>'))

    def mesh(uri: str, scale: str = '1 1 1') -> str:
        return (f'<collision name="{uri}"><geometry><mesh><uri>{uri}</uri><scale>{scale}'
                '</scale><submesh><name>x</name></submesh></mesh></geometry></collision>')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path))
    body = ('<link name="l">' + mesh('model://crate/meshes/box.stl', '2 2 2')
            + mesh('meshes/box.obj') + mesh(f'file://{meshes}/box.dae', '10 10 10') + '</link>')
    (tmp_path / 'crate' / 'model.sdf').write_text(sdf_model('crate', body))
    model = load_model(tmp_path / 'crate')
    stl, obj, collada = model.shapes
    assert extent([stl]) == pytest.approx((2.0, 4.0, 6.0))
    assert extent([obj]) == pytest.approx((1.0, 2.0, 3.0))
    assert extent([collada]) == pytest.approx((0.254, 0.508, 0.762))
    assert 'submesh' in describe_ignored(model.ignored)
    assert meshes / 'box.stl' in [Path(source) for source in model.sources]


def test_nested_models_and_includes_replace_the_included_pose_name_and_static(
        tmp_path, monkeypatch):
    write_model(tmp_path, 'crate', BOX, pose='5 5 0 0 0 0')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path))
    outer = sdf_model('outer', (
        '<model name="inner"><pose>0 1 0 0 0 0</pose>' + BOX + '</model>'
        '<include><uri>model://crate</uri><pose>2 0 0 0 0 0</pose></include>'
        '<include><uri>model://crate</uri></include>'))
    model = parse_model(outer, tmp_path / 'outer.sdf')
    centres = [(shape.x, shape.y) for shape in model.shapes]
    assert centres == [(0.0, 1.0), (2.0, 0.0), (5.0, 5.0)]
    world = tmp_path / 'w.world'
    world.write_text('<sdf version="1.6"><world name="w"><include><uri>model://crate</uri>'
                     '<name>box_a</name><pose>1 2 0 0 0 0</pose><static>true</static></include>'
                     f'<model name="bot"><pose>-1 0 0 0 0 0.5</pose>{ROBOT}</model>'
                     '</world></sdf>')
    loaded = World.load(world)
    box = loaded.obstacle('box_a')
    assert (box.shapes[0].x, box.shapes[0].y) == (1.0, 2.0)
    assert loaded.robot_start == (-1.0, 0.0, 0.5) and loaded.robot_model == 'bot'


def test_the_lidar_has_more_than_one_sample_or_is_named(tmp_path):
    body = ('<link name="l">' + LIDAR.format(name='cliff', samples=1)
            + LIDAR.format(name='front', samples=90) + '</link><link name="r">'
            + LIDAR.format(name='rear', samples=45) + '</link>')
    text = sdf_model('m', body)
    model = parse_model(text, Path('m.sdf'))
    assert (model.lidar.samples, model.lidar.frame_id) == (90, 'l')
    assert 'cliff (1 beam lidar)' in describe_ignored(model.not_simulated)
    rear = parse_model(text, Path('m.sdf'), lidar='rear').lidar
    assert (rear.samples, rear.frame_id) == (45, 'r')
    with pytest.raises(SdfError, match="no lidar sensor named 'side' .*cliff, front, rear"):
        parse_model(text, Path('m.sdf'), lidar='side')


def test_gazebo_sim_diff_drive_limits_and_defaults():
    plugin = ('<plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">'
              '<max_velocity>2.0</max_velocity><max_linear_velocity>0.5</max_linear_velocity>'
              '<max_angular_velocity>1.0</max_angular_velocity>'
              '<min_linear_acceleration>-3</min_linear_acceleration>'
              '<max_linear_acceleration>1.5</max_linear_acceleration></plugin>')
    drive = parse_model(sdf_model('ros_robot', '<link name="chassis"/>' + plugin),
                        Path('m.sdf')).drive
    assert (drive.limits.max_linear_speed, drive.limits.max_angular_speed) == (0.5, 1.0)
    assert drive.limits.max_linear_accel == 1.5 and drive.limits.max_angular_accel == math.inf
    assert (drive.command_topic, drive.odometry_topic) == ('/model/ros_robot/cmd_vel',
                                                           '/model/ros_robot/odometry')
    assert (drive.odometry_frame, drive.base_frame) == ('ros_robot/odom', 'ros_robot/chassis')
    assert drive.odometry_rate == 50.0 and drive.wheel_separation is None
    bare = parse_model(sdf_model('r', DRIVE), Path('m.sdf')).drive
    assert bare.limits.max_linear_speed == NO_SPEED_LIMIT


def test_gazebo_classic_diff_drive_with_remapping_and_wheel_acceleration():
    plugin = ('<plugin name="dd" filename="libgazebo_ros_diff_drive.so"><ros>'
              '<namespace>/demo</namespace><remapping>cmd_vel:=cmd_demo</remapping></ros>'
              '<update_rate>30</update_rate><wheel_separation>0.4</wheel_separation>'
              '<wheel_diameter>0.2</wheel_diameter><max_wheel_acceleration>1.0'
              '</max_wheel_acceleration><odometry_frame>odom_demo</odometry_frame>'
              '<publish_odom_tf>true</publish_odom_tf></plugin>')
    drive = parse_model(sdf_model('r', plugin), Path('m.sdf')).drive
    assert (drive.wheel_separation, drive.wheel_radius) == (0.4, 0.1)
    assert (drive.command_topic, drive.odometry_topic) == ('/demo/cmd_demo', '/demo/odom')
    assert (drive.odometry_frame, drive.base_frame) == ('odom_demo', 'base_footprint')
    assert drive.limits.max_linear_accel == 1.0
    assert drive.limits.max_angular_accel == pytest.approx(2.0 * 1.0 / 0.4)
    assert (drive.odometry_rate, drive.publish_tf) == (30.0, True)


WORLD = """<?xml version="1.0"?>
<sdf version="1.8"><world name="default">
  <physics type="ode"><max_step_size>0.004</max_step_size></physics>
  <plugin filename="gz-sim-sensors-system" name="gz::sim::systems::Sensors"/>
  <light name="lamp" type="point"/>
  <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground Plane</uri></include>
  <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Sun</uri></include>
  <model name="floor"><static>true</static><link name="l"><collision name="c"><geometry>
    <plane><normal>0 0 1</normal><size>8 6</size></plane></geometry></collision></link></model>
  <model name="crate"><pose>2 0 0 0 0 0</pose>{box}</model>
  {robot}
</world></sdf>"""


def test_an_sdf_world_has_its_floor_physics_step_robot_and_ignored_line(tmp_path):
    path = tmp_path / 'lab.sdf'
    joint = '<joint name="j" type="fixed"><parent>chassis</parent><child>chassis</child></joint>'
    path.write_text(WORLD.format(box=BOX, robot=f'<model name="bot">{ROBOT}{joint}</model>'))
    world = World.load(path)
    assert world.name == 'lab' and world.physics_step_s == 0.004
    assert world.floor_size == (100.0, 100.0)  # the first ground plane: Fuel's, 100 m
    assert [obstacle.name for obstacle in world.obstacles] == ['crate']
    assert world.robot.lidar.samples == 90 and world.robot.drive.wheel_separation == 0.3
    assert world.ignored.startswith('ignored: ')
    for part in ('2 lights', '1 joint,', 'plugin gz-sim-sensors-system',
                 'model held fixed crate'):
        assert part in world.ignored
    moved = world.with_robot(paths.models_dir() / 'turtlebot3_burger', (-2.0, 1.0, 0.5))
    assert (moved.robot_model, moved.robot_start) == ('turtlebot3_burger', (-2.0, 1.0, 0.5))
    assert 'plugin gz-sim-sensors-system' in moved.ignored  # the world's, kept
    assert '5 joints' in moved.ignored  # the new robot's, not the old one's


def test_world_errors_name_the_file_and_say_what_to_do(tmp_path):
    no_robot = tmp_path / 'empty.world'
    no_robot.write_text(WORLD.format(box=BOX, robot=''))
    with pytest.raises(WorldError, match=r'empty.world: has no robot .*pass one with --robot'):
        World.load(no_robot)
    assert World.load(no_robot, robot='turtlebot3_burger').robot_model == 'turtlebot3_burger'
    fuel = tmp_path / 'fuel.world'
    fuel.write_text(WORLD.format(box=BOX, robot='<include><uri>https://fuel.gazebosim.org/1.0/'
                                 'OpenRobotics/models/Tree</uri></include>'))
    with pytest.raises(WorldError, match=r'fuel.world: <world name="default">/<include>/<uri>'
                       r'.*Tree is a Gazebo Fuel model.*gz fuel download.*GZ_SIM_RESOURCE_PATH'):
        World.load(fuel)
    xml_as_yaml = tmp_path / 'lab.yaml'
    xml_as_yaml.write_text(no_robot.read_text())
    with pytest.raises(WorldError, match=r'lab.yaml: holds XML \(an SDF world\), not YAML'):
        World.load(xml_as_yaml)
    yaml_as_world = tmp_path / 'room.world'
    yaml_as_world.write_text('name: room\n')
    with pytest.raises(WorldError, match=r'room.world: holds YAML .*name it .yaml'):
        World.load(yaml_as_world)


def test_a_yaml_world_places_a_model_replacing_its_own_pose(tmp_path, monkeypatch):
    write_model(tmp_path, 'crate', BOX, pose='5 5 0 0 0 0')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path))
    world = World.from_dict({'obstacles': [{'name': 'c', 'type': 'model', 'model': 'crate',
                                            'pose': [2.0, 0.0]}],
                             'robot': {'pose': [-2.0, 0.0]}})
    assert (world.obstacle('c').shapes[0].x, world.obstacle('c').shapes[0].y) == (2.0, 0.0)


def test_a_plane_is_the_floor_and_a_polyline_is_extruded():
    body = ('<link name="l"><collision name="ground"><geometry><plane><normal>0 0 1</normal>'
            '<size>20 10</size></plane></geometry></collision>'
            '<collision name="wedge"><geometry><polyline><point>0 0</point><point>2 0</point>'
            '<point>0 1</point><height>0.5</height></polyline></geometry></collision></link>')
    model = parse_model(sdf_model('m', body), Path('m.sdf'))
    assert [(plane.z, plane.size) for plane in model.planes] == [(0.0, (20.0, 10.0))]
    (wedge,) = model.shapes
    assert wedge.kind == 'mesh' and extent([wedge]) == pytest.approx((2.0, 1.0, 0.5))
    tilted = body.replace('<normal>0 0 1</normal>', '<normal>1 0 0</normal>')
    with pytest.raises(SdfError, match=r'<plane>/<normal>: only a horizontal plane'):
        parse_model(sdf_model('m', tilted), Path('m.sdf'))


def test_a_fuel_model_downloaded_to_gazebos_cache_is_used(tmp_path, monkeypatch):
    cache = tmp_path / 'fuel'
    write_model(cache / 'fuel.gazebosim.org' / 'openrobotics' / 'models' / 'crate', '2', BOX)
    write_model(cache / 'fuel.gazebosim.org' / 'openrobotics' / 'models' / 'crate', '10', BOX,
                pose='1 0 0 0 0 0')
    monkeypatch.setenv('GZ_FUEL_CACHE_PATH', str(cache))
    world = tmp_path / 'w.sdf'
    world.write_text(WORLD.format(box=BOX, robot=(
        f'<model name="bot">{ROBOT}</model><include><uri>https://fuel.gazebosim.org/1.0/'
        'OpenRobotics/models/Crate</uri></include>')))
    fuel_crate = World.load(world).obstacles[-1]
    assert fuel_crate.pose[0] == 1.0  # version 10, the newest, with its own pose


def test_a_world_robots_lidar_can_be_named(tmp_path):
    two_lidars = ROBOT.replace('</link>', LIDAR.format(name='rear', samples=45) + '</link>')
    path = tmp_path / 'lab.sdf'
    path.write_text(WORLD.format(box=BOX, robot=f'<model name="bot">{two_lidars}</model>'))
    assert World.load(path).robot.lidar.samples == 90
    world = World.load(path, lidar='rear')
    assert world.robot.lidar.samples == 45
    assert 'laser (lidar not used)' in world.ignored
    with pytest.raises(WorldError, match="lab.sdf: has no robot with a lidar sensor named 'x'"):
        World.load(path, lidar='x')
    assert World.load('room', lidar='laser').robot.lidar.frame_id == 'laser'
    with pytest.raises(WorldError, match="room.yaml: robot: 'model': .*no lidar sensor named 'x' "
                       r'\(lidars: laser\)'):
        World.load('room', lidar='x')


def test_classic_ground_plane_and_sun_work_offline(tmp_path, monkeypatch):
    monkeypatch.setenv('HOME', str(tmp_path / 'home'))  # no ~/.gazebo/models/ground_plane
    path = tmp_path / 'classic.world'
    path.write_text('<sdf version="1.6"><world name="default"><include><uri>model://ground_plane'
                    '</uri></include><include><uri>model://sun</uri></include>'
                    f'<model name="bot">{ROBOT}</model></world></sdf>')
    world = World.load(path)
    assert world.floor_size == (100.0, 100.0) and world.obstacles == ()
    assert world.ignored == 'ignored: 1 light'


def test_the_kits_waffle_drives_through_a_gap_only_its_own_outline_fits(tmp_path):
    # Two cubes leave 0.40 m; the Waffle is 0.306 m wide (a circle round its outline, 0.47 m
    # across, would not fit).
    world_file = tmp_path / 'gap.yaml'
    world_file.write_text('robot: {model: turtlebot3_waffle, pose: [0.0, 0.0, 0.0]}\n'
                          'obstacles:\n'
                          '  - {name: left, type: cube, size: [1, 1, 0.5], pose: [1.5, 0.7]}\n'
                          '  - {name: right, type: cube, size: [1, 1, 0.5], pose: [1.5, -0.7]}\n')
    world = World.load(world_file)
    assert world.floor_slice.robot_radius > 0.2
    with Simulator(world) as sim:
        sim.set_command(0.2, 0.0)
        for _ in range(1500):
            sim.step(0.01)
        assert sim.collisions == []
        assert sim.pose[0] > 2.5
