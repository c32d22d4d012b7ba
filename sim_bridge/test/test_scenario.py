"""Scenario files and pass criteria: parsing, judging, validation errors, node overrides."""

import os
from pathlib import Path
import textwrap

import pytest

from sim_bridge.common.yaml_loader import FILE_LIMIT_BYTES
from sim_bridge.grading.criteria import parse_criterion
from sim_bridge.grading.scenario import (
    load_scenario, load_scenarios, ScenarioError, with_node_overrides)
from sim_bridge.runner.options import MAX_SEED
from sim_bridge.runner.targets import target_name

METRICS = {
    'collisions': 0, 'laps': -2, 'min_clearance_m': 0.21, 'turns_deg': [104.5, 171.0, 95.25],
    'lap_times_s': [], 'node_errors': [], 'coverage': None,
    'wall_distance_m': {'mean': 0.52, 'mae': 0.043, 'rms': 0.05, 'setpoint': 0.5},
}


@pytest.mark.parametrize('text, passed, shown', [
    ('collisions == 0', True, '0'),
    ('collisions != 0', False, '0'),
    ('laps <= -1', True, '-2'),
    ('laps>=1', False, '-2'),
    ('abs(laps) >= 2', True, '2'),
    ('wall_distance_m.mae <= 0.10', True, '0.043'),
    ('wall_distance_m.mae < 4.3e-2', False, '0.043'),
    ('min_clearance_m >= 0.15', True, '0.21'),
    ('min(turns_deg) > 90', True, '95.25'),
    ('max(turns_deg) < 171', False, '171'),
    ('len(node_errors) == 0', True, '0'),
    ('all(turns_deg) > 100', False, '3 values, min 95.25, max 171'),
    ('any(turns_deg) > 170', True, '3 values, min 95.25, max 171'),
    ('all(lap_times_s) < 10', True, 'no values'),
    ('any(lap_times_s) < 10', False, 'no values'),
    ('min(lap_times_s) < 10', False, 'null'),
    ('coverage >= 0.1', False, 'null'),
    ('max_stationary_s < inf', False, 'null'),
])
def test_criteria_judge_the_measured_value(text, passed, shown):
    result = parse_criterion(text).evaluate(METRICS)
    assert (result.passed, result.shown) == (passed, shown)
    assert result.criterion == text.strip()


def test_a_criterion_result_keeps_the_raw_value_for_the_report():
    assert parse_criterion('min(turns_deg) > 90').evaluate(METRICS).as_dict() == {
        'criterion': 'min(turns_deg) > 90', 'passed': True, 'value': 95.25, 'shown': '95.25'}


@pytest.mark.parametrize('text, message', [
    ('laps =< -1', "cannot read 'laps =< -1'"),
    ('laps <= one', 'cannot read'),
    ('laps <=', 'cannot read'),
    ("__import__('os').system('true') == 0", 'cannot read'),
    ('collisions == 0 or True', 'cannot read'),
    ('lapz <= -1', "unknown metric 'lapz'; metrics are sim_time_s"),
    ('wall_distance_m.median <= 1', "unknown metric 'wall_distance_m.median'"),
    ('turns_deg > 90', "'turns_deg' is a list; use min(turns_deg)"),
    ('min(laps) > 1', 'min() needs a list metric'),
    ('wall_distance_m > 0', "'wall_distance_m' is a group of metrics"),
    ('sum(turns_deg) > 90', "unknown function 'sum'"),
])
def test_unreadable_or_unknown_criteria_are_refused_with_the_reason(text, message):
    with pytest.raises(ValueError, match=message.replace('(', r'\(').replace(')', r'\)')):
        parse_criterion(text)


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


VALID = textwrap.dedent("""\
    description: follow the box
    world: wall_follow_box
    nodes: [wall_follow, ../students/wf.py:Follower]
    params:
      wall_follow: {side: left, distance: 0.5, seed: $seed}
    duration: 76.2
    seeds: [1, 2, 3]
    start: mirrored
    criteria:
      - laps >= 1
      - collisions == 0
""")


def test_a_scenario_file_loads_with_paths_relative_to_it(tmp_path):
    scenario = load_scenario(write(tmp_path, 'box_ccw.yaml', VALID))
    assert scenario.name == 'box_ccw'
    assert scenario.world == 'wall_follow_box'
    assert scenario.nodes == ('wall_follow', f'{tmp_path}/../students/wf.py:Follower')
    assert scenario.duration_s == 76.2 and scenario.start == 'mirrored'
    assert [criterion.text for criterion in scenario.criteria] == ['laps >= 1', 'collisions == 0']
    assert scenario.description == 'follow the box'


def test_numbers_are_read_as_yaml_1_2_reads_them_as_in_world_files(tmp_path):
    """As read by PyYAML alone (YAML 1.1), ``1.0e2`` and ``5e-1`` would be text."""
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID.replace(
        'duration: 76.2', 'duration: 1.0e2').replace('distance: 0.5', 'distance: 5e-1')))
    assert scenario.duration_s == 100.0
    assert scenario.params['wall_follow']['distance'] == 0.5


def test_each_seed_is_a_run_with_its_own_output_name_and_seeded_params(tmp_path):
    runs = load_scenario(write(tmp_path, 'box_ccw.yaml', VALID)).runs()
    assert [run.name for run in runs] == ['box_ccw/seed_1', 'box_ccw/seed_2', 'box_ccw/seed_3']
    assert runs[1].params == {'wall_follow': {'side': 'left', 'distance': 0.5, 'seed': 2}}


def test_defaults_one_seed_zero_and_the_world_start(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', """\
        world: worlds/mine.yaml
        nodes: scan_ahead
        duration: 5
        criteria: [collisions == 0]
    """))
    assert scenario.seeds == (0,) and scenario.start is None and scenario.params == {}
    assert scenario.world == f'{tmp_path}/worlds/mine.yaml'
    assert scenario.nodes == ('scan_ahead',)


def test_a_start_pose_is_three_numbers(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID.replace('mirrored', '[1, 2.5, -3]')))
    assert scenario.start == (1.0, 2.5, -3.0)


@pytest.mark.parametrize('change, field, problem', [
    (('duration: 76.2', 'duration: -1'), 'duration', 'must be a positive number of seconds'),
    (('duration: 76.2', 'duration: .nan'), 'duration', 'positive number'),
    (('duration: 76.2\n', ''), 'duration', 'missing'),
    (('world: wall_follow_box', 'world: [a]'), 'world', 'must be a world name or path'),
    (('nodes: [wall_follow, ../students/wf.py:Follower]', 'nodes: []'), 'nodes', 'non-empty'),
    (('nodes: [wall_follow, ../students/wf.py:Follower]', 'nodes: [wall_follow, 3]'),
     'nodes[1]', 'must be a TARGET text'),
    (('seeds: [1, 2, 3]', 'seeds: [1, true]'), 'seeds[1]', 'non-negative integer'),
    (('seeds: [1, 2, 3]', 'seeds: [1, 1]'), 'seeds', 'repeated seeds'),
    (('seeds: [1, 2, 3]', 'seed: 1.5'), 'seed', 'non-negative integer'),
    (('seeds: [1, 2, 3]', 'seed: true'), 'seed', 'non-negative integer up to'),
    (('seeds: [1, 2, 3]', 'seed: -1'), 'seed', 'non-negative integer up to'),
    (('seeds: [1, 2, 3]', 'seed: 9223372036854775808'), 'seed',
     'must be a non-negative integer up to 9223372036854775807 (a ROS integer parameter is '
     'int64), got 9223372036854775808'),
    (('seeds: [1, 2, 3]', 'seeds: [1, 9223372036854775808]'), 'seeds[1]', 'int64'),
    (('seeds: [1, 2, 3]', 'seeds: [1]\nseed: 2'), 'seeds', "either 'seed' or 'seeds'"),
    (('start: mirrored', 'start: [1, 2]'), 'start', "must be 'mirrored' or [x, y, yaw]"),
    (('start: mirrored', 'start: mirror'), 'start', "must be 'mirrored'"),
    (('{side: left, distance: 0.5, seed: $seed}', '7'), 'params.wall_follow',
     'must map parameter names to values'),
    (('distance: 0.5', 'distance: {a: 1}'), 'params.wall_follow.distance',
     'must be a bool, number, text or a list'),
    (('  - collisions == 0', '  - collisions = 0'), 'criteria[1]', "cannot read 'collisions = 0'"),
    (('criteria:\n  - laps >= 1\n  - collisions == 0', 'criteria: []'), 'criteria',
     'non-empty list'),
    (('start: mirrored', 'start: mirrored\nrobot: [a]'), 'robot', 'must be a robot model name'),
    (('start: mirrored', 'start: mirrored\nremap: {a: b}'), 'remap', 'list of remapping rules'),
    (('start: mirrored', 'start: mirrored\nremap: [/a:=/b, /scan]'), 'remap[1]',
     "'/scan' is not a remapping rule: expected FROM:=TO or NODE:FROM:=TO"),
    (('start: mirrored', 'start: mirrored\nremap: [n:a:b:=c]'), 'remap[0]', 'not a remapping'),
    (('start: mirrored', 'start: mirrored\nremap: [/a:=]'), 'remap[0]', 'not a remapping'),
    (('start: mirrored', 'start: mirrored\nsetpoint: 0.5'), 'setpoint', 'must map metrics'),
    (('start: mirrored', 'start: mirrored\nsetpoint: {distance: 0.5}'), 'setpoint.distance',
     'unknown; setpoints are wall_distance_m'),
    (('start: mirrored', 'start: mirrored\nsetpoint: {wall_distance_m: .inf}'),
     'setpoint.wall_distance_m', 'must be a number (m)'),
    (('description: follow the box', 'descripton: follow the box'), 'descripton',
     "unknown key (did you mean 'description'?); expected one of description, world"),
    (('seeds: [1, 2, 3]', 'seeds: []'), 'seeds', 'must be a non-empty list of integers'),
    (('duration: 76.2', 'duration: ten'), 'duration', "(a day), got 'ten'"),
    (('duration: 76.2', 'duration: 1e9'), 'duration', 'at most 86400 (a day), got 1000000000.0'),
    (('criteria:\n  - laps >= 1\n  - collisions == 0', 'criteria: collisions == 0'),
     'criteria', "non-empty list of criteria, got the text 'collisions == 0'"),
    (('  - collisions == 0', '  - 3'), 'criteria[1]', 'must be a text like'),
    (('  - collisions == 0', '  - __import__("os").system("id") == 0'), 'criteria[1]',
     'cannot read'),
    (('  - collisions == 0', '  - speed_of_light > 3'), 'criteria[1]',
     "unknown metric 'speed_of_light'"),
    (('params:\n  wall_follow: {side: left, distance: 0.5, seed: $seed}', 'params: [1, 2]'),
     'params', 'must map node names to parameters, got a list'),
], ids=lambda value: None)
def test_every_invalid_field_is_named_with_its_file(tmp_path, change, field, problem):
    path = write(tmp_path, 'broken.yaml', VALID.replace(*change))
    with pytest.raises(ScenarioError) as error:
        load_scenario(path)
    assert str(error.value).startswith(f'{path}: {field}: ')
    assert problem in str(error.value)


def test_unreadable_files_are_named(tmp_path):
    with pytest.raises(ScenarioError, match=r'missing.yaml: cannot read'):
        load_scenario(tmp_path / 'missing.yaml')
    with pytest.raises(ScenarioError, match=r'bad.yaml: invalid YAML at line \d+, column \d+'):
        load_scenario(write(tmp_path, 'bad.yaml', 'world: a\nnodes: [b\n'))
    with pytest.raises(ScenarioError, match=r'list.yaml: must be a mapping of keys, got a list'):
        load_scenario(write(tmp_path, 'list.yaml', '- a\n'))
    (tmp_path / 'empty').mkdir()
    with pytest.raises(ScenarioError, match='empty: no .yaml scenario files'):
        load_scenarios([tmp_path / 'empty'])


def test_a_file_that_is_not_utf8_not_a_file_or_huge_is_named_not_read_without_end(tmp_path):
    (tmp_path / 'latin1.yaml').write_bytes(VALID.replace('follow the box', 'caf\u00e9')
                                           .encode('latin-1'))
    with pytest.raises(ScenarioError, match=r'latin1.yaml: not UTF-8 text: .* at byte \d+$'):
        load_scenario(tmp_path / 'latin1.yaml')
    (tmp_path / 'zero.yaml').symlink_to('/dev/zero')
    with pytest.raises(ScenarioError, match='zero.yaml: cannot read: not a regular file'):
        load_scenario(tmp_path / 'zero.yaml')
    os.mkfifo(tmp_path / 'pipe.yaml')  # opening it would wait for a writer for ever
    with pytest.raises(ScenarioError, match='pipe.yaml: cannot read: not a regular file'):
        load_scenario(tmp_path / 'pipe.yaml')
    write(tmp_path, 'huge.yaml', VALID + '#' * FILE_LIMIT_BYTES)
    with pytest.raises(ScenarioError, match='huge.yaml: cannot read: larger than 1024 KiB'):
        load_scenario(tmp_path / 'huge.yaml')
    (tmp_path / 'loop.yaml').symlink_to('loop.yaml')
    with pytest.raises(ScenarioError, match='loop.yaml: cannot read: Too many levels'):
        load_scenario(tmp_path / 'loop.yaml')


def test_an_empty_file_and_a_billion_laughs_are_refused_at_once(tmp_path):
    with pytest.raises(ScenarioError, match='empty.yaml: must be a mapping of keys, got nothing'):
        load_scenario(write(tmp_path, 'empty.yaml', ''))
    # Nine lists of nine aliases, nine deep: 9**9 texts if anything expanded it.
    laughs = ['a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]'] + [
        f"a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * 9)}]" for level in range(1, 9)]
    bomb = VALID.replace('wall_follow: {side: left, distance: 0.5, seed: $seed}',
                         'wall_follow:\n' + '\n'.join('    ' + line for line in laughs))
    with pytest.raises(ScenarioError, match=r'params.wall_follow.a1: must be a bool, number, '):
        load_scenario(write(tmp_path, 'bomb.yaml', bomb))


def test_a_folder_stands_for_its_scenario_files_in_name_order(tmp_path):
    for name in ('b.yaml', 'a.yaml'):
        write(tmp_path, name, VALID)
    (tmp_path / 'notes.txt').write_text('not a scenario')
    assert [scenario.name for scenario in load_scenarios([tmp_path])] == ['a', 'b']


def test_a_scenario_given_twice_runs_once_and_two_of_one_name_are_refused(tmp_path):
    for folder in ('a', 'b'):
        (tmp_path / folder).mkdir()
    write(tmp_path, 'a/box.yaml', VALID)
    write(tmp_path, 'a/cyl.yaml', VALID)
    scenarios = load_scenarios([tmp_path / 'a' / 'box.yaml', tmp_path / 'a',
                                tmp_path / 'a' / '..' / 'a' / 'box.yaml'])
    assert [scenario.name for scenario in scenarios] == ['box', 'cyl']
    write(tmp_path, 'b/box.yaml', VALID)
    clash = r"b/box.yaml: its name 'box' is also the name of .*a/box.yaml \(runs are named"
    with pytest.raises(ScenarioError, match=clash):
        load_scenarios([tmp_path / 'a', tmp_path / 'b' / 'box.yaml'])


@pytest.mark.parametrize('target, name', [
    ('wall_follow', 'wall_follow'), ('scan_pkg.wall_follow', 'wall_follow'),
    ('students/ana/wall_follow.py', 'wall_follow'), ('wf.py:WallFollower', 'wf'),
    ('scan_pkg.wanderbot:Wanderbot', 'wanderbot'),
])
def test_target_names(target, name):
    assert target_name(target) == name


def test_an_override_replaces_the_node_of_the_same_name(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID))
    replaced = scenario.with_node_override('students/bo/wall_follow.py')
    assert replaced.nodes == ('students/bo/wall_follow.py', scenario.nodes[1])
    # The student's node may name itself anything: ROS's own wildcard reaches it.
    assert replaced.params == {'/**': scenario.params['wall_follow']}


def test_an_overridden_nodes_params_go_to_every_node_the_others_keep_theirs(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID.replace(
        'params:', 'params:\n  wf: {gain: 2.0}\n  sim_bridge: {lidar_samples: 360}')))
    replaced = scenario.with_node_override('wall_follow=students/ana/follower.py')
    assert replaced.params == {'wf': {'gain': 2.0}, 'sim_bridge': {'lidar_samples': 360},
                               '/**': {'side': 'left', 'distance': 0.5, 'seed': '$seed'}}
    assert replaced.runs()[0].params['/**']['seed'] == 1
    # A replaced node without parameters leaves none for every node.
    plain = load_scenario(write(tmp_path, 'plain.yaml', VALID))
    assert '/**' not in plain.with_node_override('wf=ana.py').params


def test_robot_remap_and_setpoint_are_read(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID + textwrap.dedent("""\
        robot: turtlebot3_burger
        remap: [/robot/scan:=/scan, 'wf:/husky/cmd_vel:=/cmd_vel']
        setpoint: {wall_distance_m: 0.45}
    """)))
    assert scenario.robot == 'turtlebot3_burger'
    assert scenario.remap == ('/robot/scan:=/scan', 'wf:/husky/cmd_vel:=/cmd_vel')
    assert scenario.setpoint == {'wall_distance_m': 0.45}
    plain = load_scenario(write(tmp_path, 'p.yaml', VALID))
    assert (plain.robot, plain.remap, plain.setpoint) == (None, (), {})


def test_an_override_of_another_name_replaces_the_only_node(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID.replace(
        'nodes: [wall_follow, ../students/wf.py:Follower]', 'nodes: [wall_follow]')))
    assert scenario.with_node_override('ana.py:Follower').nodes == ('ana.py:Follower',)


def test_an_ambiguous_override_must_name_the_node(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID))
    with pytest.raises(ScenarioError, match='say which one to replace with NODE=ana.py'):
        scenario.with_node_override('ana.py')
    assert scenario.with_node_override('wf=ana.py').nodes == ('wall_follow', 'ana.py')
    assert scenario.with_node_override('wanderbot=ana.py') == scenario


def test_the_largest_seed_is_the_largest_int64(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID.replace(
        'seeds: [1, 2, 3]', f'seed: {2 ** 63 - 1}')))
    assert scenario.seeds == (MAX_SEED,) == (2 ** 63 - 1,)


def test_an_override_naming_an_existing_file_is_that_file_whatever_it_holds(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID))
    for folder in ('with=sign', 'col:on', 'both=a:b'):
        student_file = tmp_path / folder / 'wall_follow.py'
        student_file.parent.mkdir()
        student_file.write_text('')
        replaced = scenario.with_node_override(str(student_file))
        assert replaced.nodes == (str(student_file), scenario.nodes[1])
        assert target_name(str(student_file)) == 'wall_follow'


def test_an_override_that_is_neither_a_file_nor_node_equals_target_is_an_error(tmp_path):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID))
    with pytest.raises(ScenarioError, match=r"--node-override '/nowhere/with=sign/wf\.py': no "
                       r'such file, and not NODE=TARGET \(NODE a node name without a path'):
        scenario.with_node_override('/nowhere/with=sign/wf.py')


def test_an_override_read_both_ways_is_an_error(tmp_path, monkeypatch):
    scenario = load_scenario(write(tmp_path, 's.yaml', VALID.replace(
        'nodes: [wall_follow, ../students/wf.py:Follower]', 'nodes: [wall_follow]')))
    monkeypatch.chdir(tmp_path)
    for name in ('wall_follow=ana.py', 'ana.py'):
        (tmp_path / name).write_text('')
    with pytest.raises(ScenarioError, match=r"'wall_follow=ana\.py' is ambiguous: both the "
                       r'file wall_follow=ana\.py and node wall_follow replaced by ana\.py exist; '
                       r'write \./wall_follow=ana\.py for the file'):
        scenario.with_node_override('wall_follow=ana.py')
    assert scenario.with_node_override('./wall_follow=ana.py').nodes == ('./wall_follow=ana.py',)


def test_an_override_of_a_node_no_scenario_runs_is_an_error(tmp_path):
    scenarios = [load_scenario(write(tmp_path, 's.yaml', VALID))]
    assert with_node_overrides(scenarios, ['wf=ana.py'])[0].nodes == ('wall_follow', 'ana.py')
    with pytest.raises(ScenarioError, match="no scenario runs a node 'wal_follow' "
                       r'\(they run wall_follow, wf\)'):
        with_node_overrides(scenarios, ['wal_follow=ana.py'])


PRINTED = textwrap.dedent("""\
    world: obstacles
    nodes: [scan_around]
    duration: 10
    criteria:
      - len(node_errors) == 0
      - printed_regions: {max_error_m: 0.05, min_matched_fraction: 0.9}
      - printed.closest.mae_m <= 0.1
""")


def test_printed_value_criteria_are_mappings_and_name_what_the_run_scores(tmp_path):
    scenario = load_scenario(write(tmp_path, 'around.yaml', PRINTED))
    assert [criterion.text for criterion in scenario.criteria] == [
        'len(node_errors) == 0', 'printed_regions: max_error_m 0.05, min_matched_fraction 0.9',
        'printed.closest.mae_m <= 0.1']
    assert scenario.printed == ('regions', 'closest')
    scored = {'scans': 10, 'lines': 10, 'missed': 0, 'matched_fraction': 1.0, 'mae_m': 0.3,
              'worst_error_m': 2.0, 'unprinted': [],
              'worst': {'t': 4.2, 'node': 'scan_around', 'text': 'front-left: 2.31 m',
                        'what': 'front-left', 'printed': '2.31 m', 'printed_m': 2.31,
                        'truth_m': [0.31, 0.31]}}
    result = scenario.criteria[1].evaluate({'printed': {'regions': scored}})
    assert not result.passed
    assert result.value == result.shown == (
        "scan_around: front-left printed 2.31 m at t=4.2 s, truth 0.31 m: 'front-left: 2.31 m' "
        '(worst of 10 lines; 0 of 10 scans with no line)')
    assert not scenario.criteria[1].evaluate({}).passed  # not scored: fails


@pytest.mark.parametrize('item, message', [
    ('printed_ahead: {max_error_m: 0.05}', "unknown criterion 'printed_ahead'; a mapping "
     'criterion is one of printed_range_ahead, printed_regions, printed_closest'),
    ('printed_regions: 0.05', "'printed_regions' must map settings to numbers"),
    ('printed_regions: {max_error_m: 0.05}', "'printed_regions.min_matched_fraction' is missing"),
    ('printed_regions: {max_error_m: 0.05, min_matched_fraction: 95}',
     "'printed_regions.min_matched_fraction' must be a number from 0 to 1, got int 95"),
    ('printed_regions: {max_error_m: -1, min_matched_fraction: 0.9}',
     "'printed_regions.max_error_m' must be a number at least 0"),
    ('printed_range_ahead: {max_error_m: 0.1, min_matched_fraction: 0.9, '
     'max_bearing_error_deg: 5}', "'printed_range_ahead.max_bearing_error_deg': unknown setting"),
    ('{printed_regions: {max_error_m: 0.1}, printed_closest: {max_error_m: 0.1}}',
     'a printed-value criterion is one key'),
])
def test_a_wrong_printed_value_criterion_is_refused_naming_the_criterion(
        tmp_path, item, message):
    text = PRINTED.replace('printed_regions: {max_error_m: 0.05, min_matched_fraction: 0.9}',
                           item)
    with pytest.raises(ScenarioError, match='criteria\\[1\\]: ' + message.replace(
            '{', '\\{').replace('(', '\\(')):
        load_scenario(write(tmp_path, 'around.yaml', text))
