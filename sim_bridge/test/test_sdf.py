"""Tests of simulation.sdf: Gazebo model folders, collision shapes and lidar sensor blocks."""

from dataclasses import replace
import math
from pathlib import Path
import shutil

import pytest

from sim_bridge.common import paths
from sim_bridge.simulation.geometry import Shape
from sim_bridge.simulation.sdf import load_model, parse_model
from sim_bridge.simulation.sdf_lidar import LidarConfig
from sim_bridge.simulation.sdf_values import SdfError

MODEL_FILE = Path('robot/model.sdf')

CLASSIC_SENSOR = """
<sensor name="hokuyo" type="ray">
  <pose>0.05 0 0.2 0 0 0</pose>
  <update_rate>5</update_rate>
  <ray>
    <scan>
      <horizontal>
        <samples>720</samples>
        <resolution>1</resolution>
        <min_angle>-2.0</min_angle>
        <max_angle>2.0</max_angle>
      </horizontal>
    </scan>
    <range><min>0.2</min><max>30</max><resolution>0.02</resolution></range>
    <noise><type>gaussian</type><mean>0.001</mean><stddev>0.03</stddev></noise>
  </ray>
  <plugin name="laser" filename="libgazebo_ros_ray_sensor.so">
    <frame_name>base_scan</frame_name>
  </plugin>
</sensor>"""


def robot_sdf(sensor: str = '', link_pose: str = '', collision_pose: str = '0 0 0.1 0 0 0',
              geometry: str = '<cylinder><radius>0.2</radius><length>0.2</length></cylinder>'
              ) -> str:
    return f"""<?xml version="1.0"?>
<sdf version="1.8">
  <model name="robot">
    <link name="base_link">
      {f'<pose>{link_pose}</pose>' if link_pose else ''}
      <collision name="body">
        <pose>{collision_pose}</pose>
        <geometry>{geometry}</geometry>
      </collision>
      {sensor}
    </link>
  </model>
</sdf>"""


def parse(text: str):
    return parse_model(text, MODEL_FILE)


def test_shipped_robot_has_the_labs_lidar_and_a_round_base():
    robot = load_model(paths.find_model('lab_robot'))
    assert robot.name == 'lab_robot'
    assert robot.radius == pytest.approx(0.15)
    assert robot.height == pytest.approx(0.15)
    lidar = robot.lidar
    assert (lidar.samples, lidar.min_angle, lidar.max_angle) == (36, -1.57, 1.57)
    assert (lidar.range_min, lidar.range_max, lidar.range_resolution) == (0.12, 10.0, 0.01)
    assert (lidar.update_rate, lidar.noise_mean, lidar.noise_stddev) == (10.0, 0.0, 0.01)
    assert lidar.pose == (0.0, 0.0, 0.18, 0.0, 0.0, 0.0)
    assert lidar.frame_id == 'laser'
    # The lab robot states its noise; a model without <noise> has none (as in Gazebo).
    assert lidar == LidarConfig(pose=lidar.pose, noise_stddev=0.01)


def test_shipped_wall_follow_models_have_the_documented_shapes():
    box = load_model(paths.find_model('obstacle_box'))
    assert box.static
    assert box.shapes == (Shape('box', 0.0, 0.0, 0.5, size=(2.0, 1.0, 1.0)),)
    cylinder = load_model(paths.find_model('obstacle_cylinder'))
    assert cylinder.shapes == (Shape('cylinder', 0.0, 0.0, 0.5, radius=0.8, length=1.0),)
    l_shape = load_model(paths.find_model('obstacle_l_shape'))
    assert l_shape.shapes == (Shape('box', 0.0, -0.75, 0.5, size=(2.5, 1.0, 1.0)),
                              Shape('box', -0.75, 0.5, 0.5, size=(1.0, 1.5, 1.0)))
    # The concave corner: inside the L's bounding square but outside both arms.
    assert min(fp.distance(0.5, 0.5) for fp in l_shape.footprints) == pytest.approx(0.75)
    u_shape = load_model(paths.find_model('obstacle_u_shape'))
    assert u_shape.shapes == (Shape('box', 0.0, -1.25, 0.5, size=(2.6, 0.3, 1.0)),
                              Shape('box', -1.15, 0.15, 0.5, size=(0.3, 2.5, 1.0)),
                              Shape('box', 1.15, 0.15, 0.5, size=(0.3, 2.5, 1.0)))
    # The notch: 2 m wide, 2.5 m deep; its bottom's middle is 1 m from either arm.
    assert min(fp.distance(0.0, -1.1) for fp in u_shape.footprints) == pytest.approx(0.0)
    assert min(fp.distance(0.0, -0.5) for fp in u_shape.footprints) == pytest.approx(0.6)
    cross = load_model(paths.find_model('obstacle_cross'))
    assert cross.shapes == (Shape('box', 0.0, 0.0, 0.5, size=(3.0, 0.8, 1.0)),
                            Shape('box', 0.0, 0.0, 0.5, size=(0.8, 3.0, 1.0)))
    thin_wall = load_model(paths.find_model('obstacle_thin_wall'))
    assert thin_wall.shapes == (Shape('box', 0.0, 0.0, 0.5, size=(3.0, 0.1, 1.0)),)
    post = load_model(paths.find_model('obstacle_post'))
    assert post.shapes == (Shape('cylinder', 0.0, 0.0, 0.5, radius=0.1, length=1.0),)


def test_editing_the_sensor_block_of_a_copied_robot_model_changes_the_lidar(tmp_path):
    folder = tmp_path / 'my_robot'
    shutil.copytree(paths.find_model('lab_robot'), folder)
    sdf = folder / 'model.sdf'
    sdf.write_text(sdf.read_text().replace('<samples>36</samples>', '<samples>360</samples>')
                   .replace('<min_angle>-1.57</min_angle>', '<min_angle>-3.14</min_angle>'))
    lidar = load_model(folder).lidar
    assert (lidar.samples, lidar.min_angle, lidar.max_angle) == (360, -3.14, 1.57)
    assert lidar.angle_increment == pytest.approx((1.57 + 3.14) / 359)


def test_classic_ray_sensor_is_read_like_the_new_lidar_sensor():
    lidar = parse(robot_sdf(CLASSIC_SENSOR)).lidar
    assert (lidar.samples, lidar.min_angle, lidar.max_angle) == (720, -2.0, 2.0)
    assert (lidar.range_min, lidar.range_max, lidar.range_resolution) == (0.2, 30.0, 0.02)
    assert (lidar.update_rate, lidar.noise_mean, lidar.noise_stddev) == (5.0, 0.001, 0.03)
    assert lidar.pose == (0.05, 0.0, 0.2, 0.0, 0.0, 0.0)
    assert lidar.frame_id == 'base_scan'
    new_style = CLASSIC_SENSOR.replace('type="ray"', 'type="gpu_lidar"').replace(
        '<ray>', '<lidar>').replace('</ray>', '</lidar>')
    assert parse(robot_sdf(new_style)).lidar == lidar


def test_left_out_sensor_elements_take_the_lab_defaults_without_noise_and_the_link_frame():
    lidar = parse(robot_sdf('<sensor name="front" type="gpu_lidar"/>')).lidar
    assert lidar == LidarConfig(frame_id='base_link')
    assert lidar.noise_stddev == 0.0


def test_sensor_pose_is_composed_with_its_link_pose_and_may_tilt():
    sensor = ('<sensor name="laser" type="lidar"><gz_frame_id>laser</gz_frame_id>'
              '<pose degrees="true">0.1 0 0.05 0 10 90</pose></sensor>')
    lidar = parse(robot_sdf(sensor, link_pose=f'1 0 0.1 0 0 {math.pi / 2}')).lidar
    x, y, z, roll, pitch, yaw = lidar.pose
    assert (x, y, z) == pytest.approx((1.0, 0.1, 0.15))
    assert (roll, pitch) == pytest.approx((0.0, math.radians(10.0)))
    assert yaw == pytest.approx(-math.pi)


def test_horizontal_resolution_multiplies_the_number_of_beams():
    sensor = ('<sensor name="l" type="gpu_lidar"><lidar><scan><horizontal><samples>100'
              '</samples><resolution>2</resolution></horizontal></scan></lidar></sensor>')
    assert parse(robot_sdf(sensor)).lidar.beams == 200


def test_one_beam_has_zero_increment_and_ends_where_it_starts():
    lidar = LidarConfig(samples=1)
    assert lidar.angle_increment == 0.0
    assert lidar.last_angle == lidar.min_angle


def test_derived_lidar_values_follow_the_fields_and_are_kept_after_first_use():
    lidar = LidarConfig(samples=90, resolution=2.0, min_angle=-1.0, max_angle=2.0,
                        update_rate=8.0)
    assert lidar.beams == 180
    assert lidar.angle_increment == (2.0 - -1.0) / 179
    assert lidar.last_angle == -1.0 + (2.0 - -1.0) / 179 * 179
    assert lidar.scan_period == 1.0 / 8.0
    assert {'beams', 'angle_increment', 'last_angle', 'scan_period'} <= vars(lidar).keys()
    # A copy with other fields works its own out; the kept values play no part in equality.
    assert replace(lidar, samples=10).beams == 20
    assert lidar == replace(lidar) and hash(lidar) == hash(replace(lidar))


def test_model_without_lidar_and_noise_type_none():
    assert parse(robot_sdf()).lidar is None
    sensor = ('<sensor name="l" type="gpu_lidar"><lidar><noise><type>none</type></noise>'
              '</lidar></sensor>')
    assert parse(robot_sdf(sensor)).lidar.noise_stddev == 0.0


def test_other_sensors_are_ignored_and_the_first_lidar_wins():
    sensors = ('<sensor name="cam" type="camera"/>'
               '<sensor name="first" type="gpu_lidar"><update_rate>7</update_rate></sensor>'
               '<sensor name="second" type="ray"/>')
    model = parse(robot_sdf(sensors))
    assert model.lidar.update_rate == 7.0
    assert ('sensor', 'cam (camera)') in model.ignored


def test_model_config_names_the_sdf_file_newest_version_first(tmp_path):
    folder = tmp_path / 'thing'
    folder.mkdir()
    (folder / 'old.sdf').write_text(robot_sdf().replace('name="robot"', 'name="old"'))
    (folder / 'new.sdf').write_text(robot_sdf().replace('name="robot"', 'name="new"'))
    (folder / 'model.config').write_text(
        '<model><name>thing</name><sdf version="1.10">new.sdf</sdf>'
        '<sdf version="1.6">old.sdf</sdf></model>')
    assert load_model(folder).name == 'new'


def test_missing_model_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_model(tmp_path / 'nothing')


BAD_SENSOR = '<sensor name="laser" type="gpu_lidar"><lidar>{}</lidar></sensor>'
HORIZONTAL = '<scan><horizontal>{}</horizontal></scan>'


@pytest.mark.parametrize('text, element', [
    ('<sdf><model name="robot">', 'invalid XML'),
    ('<robot/>', '<robot>'),
    ('<sdf version="1.6"/>', '<sdf>'),
    (robot_sdf(geometry='<mesh><uri>x.dae</uri></mesh>'), '<geometry>/<mesh>/<uri>'),
    (robot_sdf(geometry='<sphere><radius>-0.5</radius></sphere>'), '<sphere>/<radius>'),
    (robot_sdf(geometry='<box><size>1 0 1</size></box>'), '<box>/<size>'),
    (robot_sdf(geometry='<box><size>1 1</size></box>'), '<box>/<size>'),
    (robot_sdf(geometry=''), '<collision name="body">/<geometry>'),
    (robot_sdf(collision_pose='0 0 zero 0 0 0'), '<collision name="body">/<pose>'),
    (robot_sdf(BAD_SENSOR.format(HORIZONTAL.format('<samples>abc</samples>'))),
     '<horizontal>/<samples>'),
    (robot_sdf(BAD_SENSOR.format(HORIZONTAL.format('<samples>0</samples>'))),
     '<horizontal>/<samples>'),
    (robot_sdf(BAD_SENSOR.format(HORIZONTAL.format('<min_angle>2</min_angle>'))),
     '<horizontal>/<min_angle>'),
    (robot_sdf(BAD_SENSOR.format(HORIZONTAL.format('<max_angle>nan</max_angle>'))),
     '<horizontal>/<max_angle>'),
    (robot_sdf(BAD_SENSOR.format('<range><min>1</min><max>0.5</max></range>')),
     '<range>/<max>'),
    (robot_sdf(BAD_SENSOR.format('<range><min>-1</min></range>')), '<range>/<min>'),
    (robot_sdf(BAD_SENSOR.format('<noise><type>poisson</type></noise>')), '<noise>/<type>'),
    (robot_sdf(BAD_SENSOR.format('<noise><stddev>-0.1</stddev></noise>')),
     '<noise>/<stddev>'),
    (robot_sdf('<sensor name="laser" type="ray"><update_rate>0</update_rate></sensor>'),
     '<sensor name="laser">/<update_rate>'),
    (robot_sdf('<sensor name="laser" type="ray"><ray/><lidar/></sensor>'),
     '<sensor name="laser">'),
    (robot_sdf('<sensor name="laser" type="ray"><pose relative_to="world">0 0 0 0 0 0</pose>'
               '</sensor>'), 'relative_to="world" names no frame'),
    (robot_sdf().replace('<link name="base_link">', '<include><uri>x</uri></include>'
                         '<link name="base_link">'), '<include>'),
])
def test_broken_model_files_are_rejected_naming_file_and_element(text, element):
    with pytest.raises(SdfError) as caught:
        parse(text)
    message = str(caught.value)
    assert message.startswith(f'{MODEL_FILE}: ')
    assert element in message


def test_lidar_config_rejects_impossible_values():
    for bad in ({'samples': 0}, {'samples': 2.5}, {'min_angle': 1.0, 'max_angle': 0.0},
                {'range_min': 5.0, 'range_max': 1.0}, {'update_rate': 0.0},
                {'noise_stddev': -1.0}, {'range_max': math.inf}, {'pose': (0.0,) * 3}):
        with pytest.raises(ValueError, match='invalid lidar'):
            LidarConfig(**bad)
