"""Parameters are typed by their default and overrides follow Jazzy rclpy's typing rules."""

import pytest


def test_declare_parameter_returns_the_default_typed_by_it(rclpy):
    from rclpy.parameter import Parameter
    node = rclpy.create_node('wall_follow')
    parameter = node.declare_parameter('distance', 0.5)
    assert parameter.value == 0.5 and parameter.type_ == Parameter.Type.DOUBLE
    assert node.get_parameter('distance').value == 0.5


def test_use_sim_time_is_declared_by_every_node(rclpy):
    assert rclpy.create_node('any').get_parameter('use_sim_time').value is False


def test_ros_args_override_a_parameter_of_the_same_type(runtime):
    import rclpy
    rclpy.init(args=['--ros-args', '-p', 'distance:=0.8', '-p', 'use_sim_time:=true'])
    node = rclpy.create_node('wall_follow')
    assert node.declare_parameter('distance', 0.5).value == 0.8
    assert node.get_parameter('use_sim_time').value is True


def test_an_int_override_for_a_double_parameter_is_rejected_as_in_jazzy(runtime):
    import rclpy
    from rclpy.exceptions import InvalidParameterTypeException
    rclpy.init(args=['--ros-args', '-p', 'distance:=1'])
    node = rclpy.create_node('wall_follow')
    with pytest.raises(InvalidParameterTypeException) as raised:
        node.declare_parameter('distance', 0.5)
    assert str(raised.value) == ("Trying to set parameter 'distance' to '1' of type 'INTEGER', "
                                 "expecting type 'DOUBLE': distance")


@pytest.mark.parametrize('override, default', [('"10"', 10), ('10.0', 10), ('true', 'yes'),
                                               ('[1, 2]', [1.0, 2.0]), ('1.5', True)])
def test_overrides_of_another_type_are_rejected(runtime, override, default):
    import rclpy
    from rclpy.exceptions import InvalidParameterTypeException
    rclpy.init(args=['--ros-args', '-p', f'value:={override}'])
    with pytest.raises(InvalidParameterTypeException):
        rclpy.create_node('node').declare_parameter('value', default)


def test_node_specific_overrides_apply_to_that_node_only(runtime):
    import rclpy
    rclpy.init(args=['--ros-args', '-p', 'fast:speed:=2.0', '-p', 'speed:=1.0'])
    fast, slow = rclpy.create_node('fast'), rclpy.create_node('slow')
    assert fast.declare_parameter('speed', 0.1).value == 2.0
    assert slow.declare_parameter('speed', 0.1).value == 1.0


def test_node_cli_args_and_parameter_overrides_take_precedence(runtime):
    import rclpy
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    rclpy.init(args=['--ros-args', '-p', 'a:=1', '-p', 'b:=1', '-p', 'c:=1'])
    node = Node('n', cli_args=['--ros-args', '-p', 'b:=2', '-p', 'c:=2'],
                parameter_overrides=[Parameter('c', value=3)])
    assert [node.declare_parameter(name, 0).value for name in 'abc'] == [1, 2, 3]


def test_global_arguments_can_be_ignored(runtime):
    import rclpy
    from rclpy.node import Node
    rclpy.init(args=['--ros-args', '-p', 'a:=1'])
    assert Node('n', use_global_arguments=False).declare_parameter('a', 0).value == 0


def test_params_file_overrides_match_the_node(runtime, tmp_path):
    import rclpy
    params = tmp_path / 'params.yaml'
    params.write_text('wall_follow:\n  ros__parameters:\n    distance: 0.7\n'
                      '    gains:\n      kp: 2.0\n/**:\n  ros__parameters:\n    rate: 5\n')
    rclpy.init(args=['--ros-args', '--params-file', str(params)])
    node = rclpy.create_node('wall_follow')
    assert node.declare_parameter('distance', 0.0).value == 0.7
    assert node.declare_parameter('gains.kp', 0.0).value == 2.0
    assert node.declare_parameter('rate', 1).value == 5
    assert rclpy.create_node('other').declare_parameter('distance', 0.0).value == 0.0


def test_undeclared_parameters_cannot_be_read(rclpy):
    from rclpy.exceptions import ParameterNotDeclaredException
    with pytest.raises(ParameterNotDeclaredException,
                       match='Invalid access to undeclared parameter'):
        rclpy.create_node('n').get_parameter('missing')


def test_declaring_twice_is_refused(rclpy):
    from rclpy.exceptions import ParameterAlreadyDeclaredException
    node = rclpy.create_node('n')
    node.declare_parameter('x', 1)
    with pytest.raises(ParameterAlreadyDeclaredException):
        node.declare_parameter('x', 2)


def test_a_parameter_declared_by_type_only_is_uninitialised_until_overridden(runtime):
    import rclpy
    from rclpy.exceptions import ParameterUninitializedException
    from rclpy.parameter import Parameter
    rclpy.init(args=['--ros-args', '-p', 'given:=3.5'])
    node = rclpy.create_node('n')
    node.declare_parameter('missing', Parameter.Type.DOUBLE)
    with pytest.raises(ParameterUninitializedException):
        node.get_parameter('missing')
    assert node.declare_parameter('given', Parameter.Type.DOUBLE).value == 3.5


def test_set_parameters_reports_a_wrong_type_in_its_result(rclpy):
    from rclpy.parameter import Parameter
    node = rclpy.create_node('n')
    node.declare_parameter('distance', 0.5)
    results = node.set_parameters([Parameter('distance', value=1),
                                   Parameter('distance', value=0.9)])
    assert [result.successful for result in results] == [False, True]
    assert results[0].reason == "Wrong parameter type, expected 'Type.DOUBLE' got 'Type.INTEGER'"
    assert node.get_parameter('distance').value == 0.9


def test_on_set_callbacks_can_reject_values(rclpy):
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.parameter import Parameter
    node = rclpy.create_node('n')
    node.declare_parameter('speed', 0.1)
    node.add_on_set_parameters_callback(
        lambda parameters: SetParametersResult(
            successful=all(p.value <= 1.0 for p in parameters), reason='too fast'))
    result, = node.set_parameters([Parameter('speed', value=2.0)])
    assert (result.successful, result.reason) == (False, 'too fast')
    assert node.get_parameter('speed').value == 0.1


def test_descriptor_ranges_and_read_only_are_enforced(rclpy):
    from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
    from rclpy.exceptions import InvalidParameterValueException
    from rclpy.parameter import Parameter
    node = rclpy.create_node('n')
    limited = ParameterDescriptor(floating_point_range=[FloatingPointRange(
        from_value=0.0, to_value=1.0, step=0.0)])
    node.declare_parameter('ratio', 0.5, limited)
    assert not node.set_parameters([Parameter('ratio', value=1.5)])[0].successful
    with pytest.raises(InvalidParameterValueException):
        node.declare_parameter('other', 2.0, ParameterDescriptor(
            floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1.0)]))
    node.declare_parameter('fixed', 1, ParameterDescriptor(read_only=True))
    assert node.set_parameters([Parameter('fixed', value=2)])[0].reason == \
        'Trying to set a read-only parameter: fixed.'


def test_declare_parameters_prefixes_the_namespace_and_reads_by_prefix(rclpy):
    node = rclpy.create_node('n')
    node.declare_parameters('gains', [('kp', 1.0), ('kd', 0.1)])
    assert node.get_parameter('gains.kp').value == 1.0
    assert {name: p.value for name, p in node.get_parameters_by_prefix('gains').items()} == \
        {'kp': 1.0, 'kd': 0.1}


def test_parameter_types_are_inferred_like_rclpy():
    from sim_bridge.lockstep.rclpy.parameter import Parameter
    infer = Parameter.Type.from_parameter_value
    assert infer(True) == Parameter.Type.BOOL and infer(1) == Parameter.Type.INTEGER
    assert infer([]) == Parameter.Type.BYTE_ARRAY
    assert infer([1.0, 2.0]) == Parameter.Type.DOUBLE_ARRAY
    with pytest.raises(TypeError):
        infer([1, 'a'])
    with pytest.raises(ValueError, match='do not agree'):
        Parameter('x', Parameter.Type.DOUBLE, 1)


def test_automatically_declared_overrides(runtime):
    import rclpy
    from rclpy.node import Node
    rclpy.init(args=['--ros-args', '-p', 'anything:=4'])
    node = Node('n', automatically_declare_parameters_from_overrides=True)
    assert node.get_parameter('anything').value == 4
