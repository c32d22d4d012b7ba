"""Node loggers print ROS console lines stamped with sim time and filter on sim time."""

import pytest


def test_lines_have_the_ros_console_format_with_sim_time(rclpy, runtime, logs):
    node = rclpy.create_node('scan_ahead')
    runtime.run_until(12_340_000_000)
    node.get_logger().info('Range ahead: 1.23 m')
    node.get_logger().warn('careful')
    node.get_logger().warning('careful too')
    node.get_logger().error('bad')
    node.get_logger().fatal('worse')
    assert logs[0].line() == '[INFO] [12.340000000] [scan_ahead]: Range ahead: 1.23 m'
    assert [record.level for record in logs] == ['INFO', 'WARN', 'WARN', 'ERROR', 'FATAL']


def test_default_sink_prints_to_stderr_like_rcutils(rclpy, runtime, capsys):
    runtime.set_log_sink(None)
    rclpy.create_node('talker').get_logger().info('hello')
    assert capsys.readouterr().err == '[INFO] [0.000000000] [talker]: hello\n'


def test_debug_is_hidden_until_the_level_allows_it(runtime):
    import rclpy
    from rclpy.logging import LoggingSeverity
    records = []
    runtime.set_log_sink(records.append)
    rclpy.init(args=['--ros-args', '--log-level', 'quiet:=warn'])
    loud, quiet = rclpy.create_node('loud'), rclpy.create_node('quiet')
    loud.get_logger().debug('hidden')
    quiet.get_logger().info('hidden too')
    loud.get_logger().set_level(LoggingSeverity.DEBUG)
    loud.get_logger().debug('shown')
    assert [record.text for record in records] == ['shown']


def test_throttle_counts_sim_time_and_always_logs_the_first_call(rclpy, runtime, logs):
    node = rclpy.create_node('throttled')
    node.create_timer(0.1, lambda: node.get_logger().info('tick', throttle_duration_sec=1.0))
    runtime.run_until(3 * 10 ** 9)
    assert [record.time_ns for record in logs] == [100_000_000, 1_100_000_000, 2_100_000_000]


def test_once_and_skip_first_are_per_call_site(rclpy, runtime, logs):
    node = rclpy.create_node('filters')

    def tick():
        node.get_logger().info('once', once=True)
        node.get_logger().info('not the first', skip_first=True)
    node.create_timer(1.0, tick)
    runtime.run_until(3 * 10 ** 9)
    assert [(record.text, record.time_ns // 10 ** 9) for record in logs] == [
        ('once', 1), ('not the first', 2), ('not the first', 3)]


def test_non_string_messages_are_a_type_error_as_in_rclpy(rclpy):
    with pytest.raises(TypeError):
        rclpy.create_node('n').get_logger().info(42)


def test_unknown_logging_options_are_refused(rclpy):
    with pytest.raises(TypeError, match='not one of the recognized logging options'):
        rclpy.create_node('n').get_logger().info('x', throttle=1)


def test_loggers_are_named_after_namespace_and_node(rclpy, logs):
    from rclpy.logging import get_logger
    node = rclpy.create_node('wall_follow', namespace='/robot1')
    node.get_logger().get_child('pid').info('x')
    get_logger('custom').info('y')
    assert [record.name for record in logs] == ['robot1.wall_follow.pid', 'custom']


def log_from_one_line(logger, severity, text, **filters):
    """Log as a student's helper ``log(text, level)`` does: every call from this one line."""
    return getattr(logger, severity)(text, **filters)


@pytest.mark.parametrize('first, then, error', [
    (('info', {}), ('warning', {}), 'Logger severity cannot be changed between calls.'),
    (('info', {}), ('info', {'once': True}),
     'Requested logging filters cannot be changed between calls.'),
    (('info', {'throttle_duration_sec': 1.0}), ('info', {'throttle_duration_sec': 2.0}),
     'Logging filter parameters cannot be changed between calls.'),
])
def test_a_call_site_keeps_its_first_severity_and_filters_as_in_rclpy(
        rclpy, logs, first, then, error):
    logger = rclpy.create_node('helper').get_logger()
    log_from_one_line(logger, first[0], 'first', **first[1])
    with pytest.raises(ValueError, match=error):
        log_from_one_line(logger, then[0], 'then', **then[1])
    assert [record.text for record in logs] == ['first']


def test_a_call_site_may_repeat_its_severity_and_filters(rclpy, logs):
    logger = rclpy.create_node('helper').get_logger()
    for text in ('one', 'two'):
        log_from_one_line(logger, 'warning', text, skip_first=True)
    assert [record.text for record in logs] == ['two']
