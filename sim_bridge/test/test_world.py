"""Tests of simulation.world: the shipped worlds, the file format and its error messages."""

import math

import numpy as np
import pytest
from sim_bridge.common import paths
from sim_bridge.common.yaml_loader import load_yaml
from sim_bridge.simulation import world as world_module
from sim_bridge.simulation.geometry import Footprint, Shape, signed_distance
from sim_bridge.simulation.world import World, WORLD_FILE_LIMIT_BYTES, WorldError
import yaml

WALL_FOLLOW_WORLDS = ('wall_follow_box', 'wall_follow_box_rotated', 'wall_follow_cross',
                      'wall_follow_cylinder', 'wall_follow_l_shape', 'wall_follow_post',
                      'wall_follow_thin_wall', 'wall_follow_u_shape')
SHIPPED_WORLDS = ('obstacles', 'room') + WALL_FOLLOW_WORLDS
ROBOT_RADIUS = 0.15


def outline_points(footprint: Footprint, spacing: float = 0.01) -> np.ndarray:
    corners = footprint.outline(segments=720)
    closed = np.vstack((corners, corners[:1]))
    return np.vstack([np.linspace(start, end, max(2, int(np.hypot(*(end - start)) / spacing)))
                      for start, end in zip(closed[:-1], closed[1:])])


def gap(first, second) -> float:
    """Return the smallest distance (m) between two obstacles' outlines (approx. 1 cm)."""
    points = np.vstack([outline_points(fp) for fp in first.footprints])
    return float(np.min(signed_distance(points, second.footprints)))


def test_every_world_in_the_worlds_folder_is_shipped_and_loads():
    assert set(paths.world_names()) == set(SHIPPED_WORLDS)
    for name in SHIPPED_WORLDS:
        world = World.load(name)
        assert world.name == name
        assert world.robot_model == 'lab_robot'
        assert world.robot.radius == pytest.approx(ROBOT_RADIUS)


@pytest.mark.parametrize('name', SHIPPED_WORLDS)
def test_primitive_obstacles_are_where_the_file_says(name):
    world = World.load(name)
    entries = yaml.safe_load(paths.find_world(name).read_text())['obstacles']
    for entry in entries:
        obstacle = world.obstacle(entry['name'])
        x, y, *yaw = entry['pose']
        assert obstacle.pose == pytest.approx((x, y, yaw[0] if yaw else 0.0))
        if entry['type'] == 'model':
            assert obstacle.model == entry['model']
            continue
        (shape,) = obstacle.shapes
        assert (shape.x, shape.y) == pytest.approx((x, y))
        assert shape.z_range()[0] == pytest.approx(0.0)
        if entry['type'] == 'cube':
            assert shape.size == pytest.approx(entry['size'])
        else:
            assert shape.radius == pytest.approx(entry['radius'])


def test_obstacles_world_has_gazebos_default_cube_cylinder_and_sphere():
    world = World.load('obstacles')
    cube, cylinder, sphere = (world.obstacle(name).shapes[0]
                              for name in ('cube', 'cylinder', 'sphere'))
    assert cube.size == (1.0, 1.0, 1.0)
    assert (cylinder.radius, cylinder.length) == (0.5, 1.0)
    assert sphere.radius == 0.5
    assert world.robot_start == (0.0, 0.0, 0.0)
    assert world.obstacle('cube').distance(0.0, 0.0) == pytest.approx(2.0)


def test_room_world_is_enclosed_8_by_6_m_with_1_m_gaps_everywhere():
    world = World.load('room')
    walls = [obstacle for obstacle in world.obstacles if obstacle.kind == 'wall']
    assert sorted(wall.name for wall in walls) == ['room_east', 'room_north', 'room_south',
                                                   'room_west']
    inner = [world.obstacle('room_east').distance(0.0, 0.0),
             world.obstacle('room_north').distance(0.0, 0.0)]
    assert inner == pytest.approx([4.0, 3.0])
    # No way out: every point on a 4.5 m x 3.5 m loop outside the free area is in a wall.
    ring = outline_points(Footprint('box', 0.0, 0.0, half_x=4.075, half_y=3.075), 0.05)
    assert np.all(signed_distance(ring, [fp for wall in walls for fp in wall.footprints]) < 0)
    scattered = [obstacle for obstacle in world.obstacles if obstacle.kind != 'wall']
    assert len(scattered) >= 4
    for index, obstacle in enumerate(scattered):
        for other in scattered[index + 1:] + walls:
            assert gap(obstacle, other) >= 1.0 - 0.01, (obstacle.name, other.name)


@pytest.mark.parametrize('name', WALL_FOLLOW_WORLDS)
def test_wall_follow_world_starts_with_the_target_half_a_metre_to_the_right(name):
    world = World.load(name)
    target = world.obstacle(world.target)
    assert target.kind == 'model'
    x, y, yaw = world.robot_start
    assert target.distance(x, y) == pytest.approx(0.5)
    right = (x + 0.5 * math.sin(yaw), y - 0.5 * math.cos(yaw))
    left = (x - 0.5 * math.sin(yaw), y + 0.5 * math.cos(yaw))
    assert target.distance(*right) == pytest.approx(0.0, abs=1e-9)
    assert target.distance(*left) >= 1.0 - 1e-9
    assert world.obstacles == (target,)
    # Enough free floor to circle it: nothing else, and the floor reaches 3 m beyond it.
    xmin, ymin, xmax, ymax = np.array([fp.bounds() for fp in target.footprints]).T
    half_x, half_y = np.array(world.floor_size) / 2
    assert -half_x <= xmin.min() - 3 and xmax.max() + 3 <= half_x
    assert -half_y <= ymin.min() - 3 and ymax.max() + 3 <= half_y


@pytest.mark.parametrize('name', WALL_FOLLOW_WORLDS)
def test_mirrored_start_turns_round_so_the_target_is_on_the_left(name):
    world = World.load(name)
    mirrored = world.mirrored_start()
    x, y, yaw = mirrored.robot_start
    assert (x, y) == world.robot_start[:2]
    assert math.cos(yaw - world.robot_start[2]) == pytest.approx(-1.0)
    target = mirrored.obstacle(mirrored.target)
    left = (x - 0.5 * math.sin(yaw), y + 0.5 * math.cos(yaw))
    assert target.distance(*left) == pytest.approx(0.0, abs=1e-9)
    assert world.robot_start != mirrored.robot_start


def test_with_robot_start_moves_the_robot_but_refuses_an_overlap():
    world = World.load('wall_follow_box')
    moved = world.with_robot_start(3.0, -2.0, 7.0)
    assert moved.robot_start == pytest.approx((3.0, -2.0, 7.0 - 2 * math.pi))
    assert moved.obstacles == world.obstacles
    with pytest.raises(WorldError, match="overlaps obstacle 'box'") as caught:
        world.with_robot_start(1.0, 0.6, 0.0)
    assert (caught.value.entry, caught.value.field) == ('robot', 'pose')
    with pytest.raises(WorldError, match='finite'):
        world.with_robot_start(math.nan, 0.0, 0.0)
    # A scenario's start a km away (written in mm, say) is refused as a world file's pose is.
    with pytest.raises(WorldError, match='x and y within ±1000 m of the origin'):
        world.with_robot_start(0.0, 1.0e9, 0.0)
    assert world.with_robot_start(-1000.0, 1000.0, 0.0).robot_start[:2] == (-1000.0, 1000.0)


def test_a_robot_pose_without_a_robot_moves_the_worlds_own_robot():
    """As the bridge's ``robot_pose`` parameter does (a video read the world this way)."""
    world = World.load('wall_follow_box', robot_pose=(0.0, 1.0, 2.5))
    assert world.robot_start == pytest.approx((0.0, 1.0, 2.5))
    assert world.robot_model == World.load('wall_follow_box').robot_model
    with pytest.raises(WorldError, match=r'must be \(x, y, yaw\)'):
        World.load('wall_follow_box', robot_pose=(0.0, 1.0))


def test_walls_from_segments_and_the_room_helper():
    world = World.from_dict({
        'walls': [{'start': [1, 0], 'end': [1, 4], 'thickness': 0.2, 'height': 0.5},
                  {'name': 'hall', 'room': [2, 1], 'center': [5, 5]}],
    })
    wall = world.obstacle('wall_0')
    assert wall.shapes == (Shape('box', 1.0, 2.0, 0.25, math.pi / 2, size=(4.0, 0.2, 0.5)),)
    hall = [world.obstacle(f'hall_{side}') for side in ('north', 'south', 'east', 'west')]
    assert [obstacle.distance(5.0, 5.0) for obstacle in hall] == pytest.approx(
        [0.5, 0.5, 1.0, 1.0])
    assert all(obstacle.shapes[0].size[1:] == (0.15, 1.0) for obstacle in hall)
    assert world.bounds == pytest.approx((0.9, 0.0, 6.15, 5.65))


def test_default_bounds_without_walls_hold_obstacles_and_robot_plus_a_metre():
    world = World.from_dict({
        'robot': {'pose': [-2.0, 0.0, 0.0]},
        'obstacles': [{'name': 'b', 'type': 'cube', 'size': [1, 2, 1], 'pose': [1, 1]}],
    })
    assert world.bounds == pytest.approx((-3.15, -1.15, 2.5, 3.0))
    explicit = World.from_dict({'bounds': [-1, -2, 3, 4]})
    assert explicit.bounds == (-1.0, -2.0, 3.0, 4.0)


def test_heights_default_to_resting_on_the_floor_and_z_overrides():
    world = World.from_dict({'obstacles': [
        {'name': 'ball', 'type': 'sphere', 'radius': 0.3, 'pose': [2, 0]},
        {'name': 'lamp', 'type': 'cylinder', 'radius': 0.1, 'length': 0.4, 'pose': [0, 2],
         'z': 1.5},
        {'name': 'block', 'type': 'model', 'model': 'obstacle_box', 'pose': [0, -3, 1.0],
         'z': 0.2}]})
    assert world.obstacle('ball').shapes[0].z == pytest.approx(0.3)
    assert world.obstacle('lamp').shapes[0].z == pytest.approx(1.5)
    block = world.obstacle('block').shapes[0]
    assert (block.x, block.y, block.z, block.yaw) == pytest.approx((0.0, -3.0, 0.7, 1.0))
    assert world.floor_size is None


def test_the_documented_example_world_loads():
    text = world_module.__doc__.split('::', 1)[1].split('\nNumbers must be')[0]
    world = World.from_dict(yaml.safe_load(text))
    assert [obstacle.name for obstacle in world.obstacles] == [
        'divider', 'outer_north', 'outer_south', 'outer_east', 'outer_west', 'box', 'pillar',
        'ball', 'block']
    assert (world.name, world.target, world.bounds) == ('room', 'block', (-5, -4, 5, 4))
    assert world.floor_size == (12.0, 10.0)


def test_a_world_file_anywhere_loads_by_path(tmp_path):
    path = tmp_path / 'mine.yaml'
    path.write_text('robot: {pose: [1, 1]}\n')
    world = World.load(path)
    assert (world.name, world.path, world.robot_start) == ('mine', path, (1.0, 1.0, 0.0))
    assert world.obstacles == () and world.target is None


def test_a_world_names_the_files_it_was_read_from_each_once():
    world = World.load('wall_follow_post')
    models = paths.models_dir()
    assert world.sources == (paths.find_world('wall_follow_post'),
                             models / 'lab_robot' / 'model.sdf',
                             models / 'obstacle_post' / 'model.sdf')
    twice = World.from_dict({'obstacles': [
        {'name': name, 'type': 'model', 'model': 'obstacle_post', 'pose': [2, y]}
        for name, y in (('one', 0), ('two', 1))]})
    assert twice.sources == (models / 'lab_robot' / 'model.sdf',
                             models / 'obstacle_post' / 'model.sdf')


def test_unknown_world_name_is_file_not_found():
    with pytest.raises(FileNotFoundError, match='shipped worlds are'):
        World.load('no_such_world')


CUBE = {'name': 'box_a', 'type': 'cube', 'size': [1, 1, 1], 'pose': [3, 0]}


@pytest.mark.parametrize('text, entry, field, problem', [
    ('obstacles: [\n  {name: a,\n', None, None, 'invalid YAML: line'),
    ('- just\n- a list\n', None, None, 'must be a mapping'),
    ('obstacles:\n- {name: ball, type: sphere, radius: 1, radius: 2, pose: [3, 0]}\n', None,
     None, "invalid YAML: line 2, column 41: duplicate key 'radius'"),
    ('colour: red\n', None, 'colour', 'unknown key'),
    ('obstacles:\n- {name: box_a, type: cube, size: [1, 1, 1], pose: [3, 0], colour: red}\n',
     'obstacles[0] (box_a)', 'colour', 'unknown key'),
    ('obstacles:\n- {name: box_a, type: cube, pose: [3, 0]}\n', 'obstacles[0] (box_a)',
     'size', 'missing'),
    ('obstacles:\n- {name: box_a, type: cube, size: [1, -1, 1], pose: [3, 0]}\n',
     'obstacles[0] (box_a)', 'size', 'must be 3 positive finite numbers'),
    ('obstacles:\n- {name: ball, type: sphere, radius: -0.5, pose: [3, 0]}\n',
     'obstacles[0] (ball)', 'radius', 'must be a positive number'),
    ('obstacles:\n- {name: can, type: cylinder, radius: 0.5, length: big, pose: [3, 0]}\n',
     'obstacles[0] (can)', 'length', 'must be a finite number'),
    ('obstacles:\n- {name: ball, type: sphere, radius: true, pose: [3, 0]}\n',
     'obstacles[0] (ball)', 'radius', 'must be a finite number'),
    ("obstacles:\n- {name: ball, type: sphere, radius: '1e-1', pose: [3, 0]}\n",
     'obstacles[0] (ball)', 'radius', 'must be a finite number'),
    # Lab-sized: huge but finite sizes and positions (bounds in mm, say) are refused.
    ('floor: {size: [1.0e+300, 10]}\n', 'floor', 'size', 'must be at most 1000 m'),
    ('walls:\n- {room: [1.0e+9, 8]}\n', 'walls[0] (wall_0)', 'room', 'must be at most 1000 m'),
    ('walls:\n- {room: [4, 4], center: [0, 2000]}\n', 'walls[0] (wall_0)', 'center',
     'must be within ±1000 m of the origin'),
    ('walls:\n- {start: [0, 0], end: [1, 0], height: 1.0e+300}\n', 'walls[0] (wall_0)',
     'height', 'must be at most 1000 m'),
    ('obstacles:\n- {name: ball, type: sphere, radius: 1001, pose: [3, 0]}\n',
     'obstacles[0] (ball)', 'radius', 'must be at most 1000 m'),
    ('obstacles:\n- {name: ball, type: sphere, radius: 1, pose: [3, 0], z: -1.0e+300}\n',
     'obstacles[0] (ball)', 'z', 'must be within ±1000 m'),
    ('obstacles:\n- {name: box_a, type: cube, size: [1, 1, 1], pose: [3, 1.0e+300]}\n',
     'obstacles[0] (box_a)', 'pose', 'must be within ±1000 m'),
    ('bounds: [-5000, -4000, 5000, 4000]\n', None, 'bounds',
     'must be within ±1000 m of the origin (positions are in metres)'),
    ('obstacles:\n- {name: x, type: model, model: no_such_model, pose: [3, 0]}\n',
     'obstacles[0] (x)', 'model', "model 'no_such_model' not found"),
    ('obstacles:\n- {name: x, type: model, pose: [3, 0]}\n', 'obstacles[0] (x)', 'model',
     'missing'),
    ('obstacles:\n- {name: x, type: cone, pose: [3, 0]}\n', 'obstacles[0] (x)', 'type',
     'unknown type'),
    ('obstacles:\n- {name: x, pose: [3, 0]}\n', 'obstacles[0] (x)', 'type', 'missing'),
    ('obstacles:\n- {type: cube, size: [1, 1, 1], pose: [3, 0]}\n', 'obstacles[0]', 'name',
     'missing'),
    ('obstacles:\n- {name: box_a, type: cube, size: [1, 1, 1]}\n', 'obstacles[0] (box_a)',
     'pose', 'missing'),
    ('obstacles:\n- {name: box_a, type: cube, size: [1, 1, 1], pose: [3, 0, 0, 0]}\n',
     'obstacles[0] (box_a)', 'pose', 'must be [x, y] or [x, y, yaw]'),
    ('obstacles: {name: box_a}\n', None, 'obstacles', 'must be a list'),
    ('obstacles:\n- {name: a, type: cube, size: [1, 1, 1], pose: [3, 0]}\n'
     '- {name: a, type: sphere, radius: 1, pose: [-3, 0]}\n', 'obstacles[1] (a)', 'name',
     "duplicate name 'a' (also used by obstacles[0] (a))"),
    ('walls:\n- {name: room, room: [4, 4]}\nobstacles:\n'
     '- {name: room_east, type: sphere, radius: 0.2, pose: [1, 1]}\n',
     'obstacles[0] (room_east)', 'name', 'also used by walls[0] (room)'),
    ('target: nothing\n', None, 'target', "names no obstacle ('nothing')"),
    ('target: [a]\n', None, 'target', 'must be an obstacle name'),
    ('walls:\n- {start: [0, 0]}\n', 'walls[0] (wall_0)', 'end', 'missing'),
    ('walls:\n- {start: [0, 0], end: [0, 0]}\n', 'walls[0] (wall_0)', 'end',
     'must differ from start'),
    ('walls:\n- {room: [4, 3], start: [0, 0]}\n', 'walls[0] (wall_0)', 'start', 'not both'),
    ('walls:\n- {start: [0, 0], end: [1, 0], thickness: 0}\n', 'walls[0] (wall_0)',
     'thickness', 'must be a positive number'),
    ('robot: {model: no_such_robot}\n', 'robot', 'model', "model 'no_such_robot' not found"),
    ('robot: {pose: [3, 0]}\nobstacles:\n- {name: box_a, type: cube, size: [1, 1, 1], '
     'pose: [3, 0]}\n', 'robot', 'pose', "overlaps obstacle 'box_a'"),
    ('robot: {pose: [0, x, 0]}\n', 'robot', 'pose', 'must be 3 finite numbers'),
    ('floor: {size: [10, -1]}\n', 'floor', 'size', 'must be 2 positive finite numbers'),
    ('bounds: [1, 0, -1, 2]\n', None, 'bounds', 'xmin < xmax'),
    ('name: 42\n', None, 'name', 'must be a non-empty text'),
    ('obstacles:\n- {name: a, type: cube, size: [0, 0, 0], pose: [3, 0]}\n',
     'obstacles[0] (a)', 'size', 'must be 3 positive finite numbers, got [0, 0, 0]'),
    ('obstacles:\n- {name: [x], type: cube, size: [1, 1, 1], pose: [3, 0]}\n', 'obstacles[0]',
     'name', "must be text, got ['x'] (list)"),
    ('obstacles:\n- 5\n', 'obstacles[0]', None, 'must be a mapping, got 5 (int)'),
    ('walls: 5\n', None, 'walls', 'must be a list of entries, got 5 (int)'),
    ('robot: [0, 0]\n', 'robot', None, 'must be a mapping, got [0, 0] (list)'),
    ('robot: {model: 5}\n', 'robot', 'model', 'must be a model name, got 5 (int)'),
    ('obstacles:\n- {name: m, type: model, model: ../../etc, pose: [3, 0]}\n',
     'obstacles[0] (m)', 'model', 'model file not found: ../../etc'),
])
def test_broken_world_file_is_rejected_naming_file_entry_and_field(
        tmp_path, text, entry, field, problem):
    path = tmp_path / 'broken.yaml'
    path.write_text(text)
    with pytest.raises(WorldError) as caught:
        World.load(path)
    error = caught.value
    assert (error.entry, error.field) == (entry, field)
    assert problem in error.problem
    message = str(error)
    assert message.startswith(f'{path}: ')
    for part in (entry, repr(field) if field else None):
        if part:
            assert part in message


def test_a_world_file_that_is_not_utf8_or_too_large_is_named_not_a_traceback(tmp_path):
    (tmp_path / 'latin1.yaml').write_bytes('description: salle de caf\u00e9\n'.encode('latin-1'))
    with pytest.raises(WorldError, match=r'latin1.yaml: cannot read: not UTF-8 text'):
        World.load(tmp_path / 'latin1.yaml')
    (tmp_path / 'huge.yaml').write_text('#' * (WORLD_FILE_LIMIT_BYTES + 1))
    with pytest.raises(WorldError, match='huge.yaml: cannot read: larger than 16384 KiB'):
        World.load(tmp_path / 'huge.yaml')


def test_an_empty_world_file_is_an_endless_floor_with_the_lab_robot(tmp_path):
    (tmp_path / 'empty.yaml').write_text('')
    world = World.load(tmp_path / 'empty.yaml')
    assert (world.name, world.obstacles, world.robot_start) == ('empty', (), (0.0, 0.0, 0.0))


def test_the_largest_world_accepted_is_a_lab_sized_one_and_a_yaw_may_be_any_angle():
    world = World.from_dict({
        'floor': {'size': [1000, 1000]}, 'bounds': [-1000, -1000, 1000, 1000],
        'walls': [{'room': [1000, 999], 'center': [0, 0]}],
        'obstacles': [{'name': 'far', 'type': 'cube', 'size': [1000, 1, 1],
                       'pose': [-1000, 1000, 1.0e+6]}]})
    assert world.bounds == (-1000.0, -1000.0, 1000.0, 1000.0)
    assert world.floor_size == (1000.0, 1000.0)


@pytest.mark.parametrize('written, value', [
    ('1e3', 1000.0), ('1.0e3', 1000.0), ('1.0e+3', 1000.0), ('-2.5E-3', -0.0025),
    ('+1E2', 100.0), ('.5e1', 5.0), ('2.', 2.0), ('1_0.5', 10.5)])
def test_numbers_are_read_as_yaml_1_2_reads_them(tmp_path, written, value):
    """In YAML 1.1, which PyYAML reads, ``1e3`` and ``1.0e3`` are text; not in a world file."""
    path = tmp_path / 'room.yaml'
    path.write_text(f"robot: {{pose: [{written}, 0]}}\ndescription: '{written}'\n")
    world = World.load(path)
    assert world.robot_start[0] == value and type(world.robot_start[0]) is float
    assert world.description == written  # quoted, it stays text
    assert load_yaml(f'[{written}, 1e3x, 1e, e3, 0x1F, 012, 1_000, .inf, .nan, 1:30]') == \
        [value, '1e3x', '1e', 'e3', 31, 10, 1000, math.inf, pytest.approx(math.nan, nan_ok=True),
         90]


def test_a_broken_model_is_reported_with_the_entry_that_places_it(tmp_path, monkeypatch):
    model = tmp_path / 'models' / 'bad_model'
    model.mkdir(parents=True)
    (model / 'model.sdf').write_text('<sdf><model name="bad_model"><link name="l"><collision '
                                     'name="c"><geometry><mesh/></geometry></collision></link>'
                                     '</model></sdf>')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path / 'models'))
    with pytest.raises(WorldError) as caught:
        World.from_dict({'obstacles': [{'name': 'odd', 'type': 'model', 'model': 'bad_model',
                                        'pose': [2, 0]}]}, source='test.yaml')
    message = str(caught.value)
    assert message.startswith("test.yaml: obstacles[0] (odd): 'model': model 'bad_model' is "
                              'broken: ')
    assert '<geometry>/<mesh>' in message


def test_a_misspelt_key_is_named_with_the_key_it_looks_like_not_as_a_missing_one(tmp_path):
    path = tmp_path / 'typo.yaml'
    path.write_text('obstacles:\n- {name: can, type: cylinder, pose: [3, 0], raduis: 0.2}\n')
    with pytest.raises(WorldError) as caught:
        World.load(path)
    assert caught.value.field == 'raduis'
    assert caught.value.problem.startswith("unknown key (did you mean 'radius'?); expected")


@pytest.mark.parametrize('text, entry, problem', [
    ('colour: red\n', None, 'expected one of name, description, floor, robot, walls, '
     'obstacles, target, bounds'),
    ('robot: {model: lab_robot, speed: 1}\n', 'robot', 'expected one of model, pose'),
    ('obstacles:\n- {name: b, type: sphere, radius: 1, pose: [3, 0], size: [1, 1, 1]}\n',
     'obstacles[0] (b)', 'expected one of name, pose, z, type, radius'),
])
def test_an_unknown_key_is_named_with_the_keys_its_entry_may_have(
        tmp_path, text, entry, problem):
    path = tmp_path / 'keys.yaml'
    path.write_text(text)
    with pytest.raises(WorldError) as caught:
        World.load(path)
    assert caught.value.entry == entry and caught.value.problem == f'unknown key; {problem}'
