"""ROS arguments are parsed and typed with rcl's rules (rcl_yaml_param_parser get_value)."""

import math

import pytest

from sim_bridge.lockstep import rosargs


@pytest.mark.parametrize('text, value', [
    ('10', 10), ('-5', -5), ('010', 8), ('0x1A', 26), ('10.0', 10.0), ('1e3', 1000.0),
    ('.5', 0.5), ('08', 8.0), ('true', True), ('False', False), ('yes', True), ('off', False),
    ("'10'", '10'), ('"true"', 'true'), ('hello', 'hello'), ('1_000', '1_000'),
    ('1e400', '1e400'), ('.inf', math.inf), ('-.inf', -math.inf), ('[1, 2]', [1, 2]),
    ('[1.0, 2.5]', [1.0, 2.5]), ('[a, b]', ['a', 'b']), ('[true, false]', [True, False]),
    ('99999999999999999999', 1e20),
])
def test_values_are_typed_like_rcl(text, value):
    typed = rosargs.yaml_value(text)
    assert typed == value and type(typed) is type(value)


def test_nan_is_a_double():
    assert math.isnan(rosargs.yaml_value('.nan'))


@pytest.mark.parametrize('text', ['[1, 2.0]', '[]', 'a: b', ''])
def test_values_rcl_cannot_type_are_refused(text):
    with pytest.raises(ValueError):
        rosargs.yaml_value(text)


def test_parse_reads_only_ros_sections_and_every_rule_kind():
    parsed = rosargs.parse(['prog', 'user_arg', '--ros-args', '-p', 'speed:=0.2',
                            '--param', 'node:rate:=5', '-r', '__ns:=/robot1', '--remap',
                            'scan:=base_scan', '--log-level', 'debug', '--', '-p', 'x'])
    assert parsed.parameters == [(None, 'speed', 0.2), ('node', 'rate', 5)]
    assert parsed.remaps == [(None, '__ns', '/robot1'), (None, 'scan', 'base_scan')]
    assert parsed.log_levels == {'': 10}


def test_unknown_ros_arguments_stop_init_like_rclpy():
    with pytest.raises(rosargs.UnknownROSArgsError,
                       match=r"Found unknown ROS arguments: \['--speed', '1'\]"):
        rosargs.parse(['--ros-args', '--speed', '1'])


@pytest.mark.parametrize('args', [['--ros-args', '-p', 'speed'], ['--ros-args', '-p'],
                                  ['--ros-args', '-p', 'speed:=[1, 2.0]']])
def test_malformed_rules_are_refused(args):
    with pytest.raises(rosargs.InvalidROSArgsError):
        rosargs.parse(args)


def test_remove_ros_args_keeps_the_user_arguments():
    assert rosargs.remove_ros_args(['prog', 'a', '--ros-args', '-p', 'x:=1', '--', 'b']) == \
        ['prog', 'a', 'b']


def test_init_with_unknown_ros_arguments_raises(runtime):
    import rclpy
    with pytest.raises(RuntimeError, match='Found unknown ROS arguments'):
        rclpy.init(args=['--ros-args', '--bogus'])


def test_init_without_args_reads_sys_argv_like_rclpy(runtime, monkeypatch):
    import rclpy
    monkeypatch.setattr('sys.argv', ['node', '--ros-args', '-p', 'rate:=7'])
    rclpy.init()
    assert rclpy.create_node('n').declare_parameter('rate', 1).value == 7
