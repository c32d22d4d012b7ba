"""rclpy's init/shutdown lifecycle and entity-creation signatures follow Jazzy."""

import pytest


def test_init_returns_none_and_ok_tracks_the_lifecycle(runtime):
    import rclpy
    assert not rclpy.ok()
    assert rclpy.init(args=[]) is None
    assert rclpy.ok()
    rclpy.shutdown()
    assert not rclpy.ok()


def test_second_shutdown_raises_and_try_shutdown_never_does(runtime):
    import rclpy
    rclpy.init(args=[])
    rclpy.shutdown()
    with pytest.raises(RuntimeError, match='Context must be initialized before it can be '
                                           'shutdown'):
        rclpy.shutdown()
    rclpy.try_shutdown()
    rclpy.try_shutdown()


def test_init_twice_raises_and_init_after_shutdown_works(runtime):
    import rclpy
    rclpy.init(args=[])
    with pytest.raises(RuntimeError, match='must only be called once'):
        rclpy.init(args=[])
    rclpy.shutdown()
    rclpy.init(args=[])
    assert rclpy.ok()


def test_shutting_a_context_down_twice_raises_rclerror(runtime):
    from rclpy.context import Context
    context = Context()
    context.init([])
    context.shutdown()
    with pytest.raises(RuntimeError, match='rcl_shutdown already called'):
        context.shutdown()


def test_a_node_needs_init(runtime):
    from rclpy.exceptions import NotInitializedException
    from rclpy.node import Node
    with pytest.raises(NotInitializedException, match='rclpy.init\\(\\) has not been called'):
        Node('early')


def test_node_keyword_only_arguments_match_rclpy(rclpy):
    from rclpy.node import Node
    with pytest.raises(TypeError):
        Node('n', None)
    node = Node('n', namespace='ns', enable_rosout=False, start_parameter_services=False)
    assert node.get_fully_qualified_name() == '/ns/n'


def test_create_subscription_requires_a_qos_like_rclpy(rclpy):
    from std_msgs.msg import Int32
    node = rclpy.create_node('n')
    with pytest.raises(TypeError, match='qos_profile'):
        node.create_subscription(Int32, 'topic', lambda msg: None)


def test_an_int_qos_is_a_keep_last_reliable_volatile_profile(rclpy):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
    from std_msgs.msg import Int32
    qos = rclpy.create_node('n').create_publisher(Int32, 'topic', 7).qos_profile
    assert (qos.history, qos.depth, qos.reliability, qos.durability) == (
        HistoryPolicy.KEEP_LAST, 7, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)


def test_qos_presets_and_legacy_aliases_exist(runtime):
    from rclpy.qos import (qos_profile_sensor_data, qos_profile_system_default, QoSPresetProfiles,
                           QoSProfile, QoSReliabilityPolicy, ReliabilityPolicy)
    assert QoSReliabilityPolicy is ReliabilityPolicy
    assert qos_profile_sensor_data.reliability == ReliabilityPolicy.BEST_EFFORT
    assert qos_profile_sensor_data.depth == 5
    assert QoSPresetProfiles.SYSTEM_DEFAULT.value is qos_profile_system_default
    with pytest.raises(Exception, match='History and/or depth settings are required'):
        QoSProfile()


def test_a_non_message_type_is_refused(rclpy):
    with pytest.raises(RuntimeError, match='The message type provided is not valid'):
        rclpy.create_node('n').create_publisher(dict, 'topic', 10)


def test_executors_module_has_the_jazzy_names(runtime):
    from rclpy.executors import (ExternalShutdownException, MultiThreadedExecutor,
                                 SingleThreadedExecutor)
    assert issubclass(ExternalShutdownException, Exception)
    assert SingleThreadedExecutor and MultiThreadedExecutor


def test_spin_once_after_shutdown_raises_external_shutdown(rclpy):
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    executor = SingleThreadedExecutor()
    rclpy.shutdown()
    with pytest.raises(ExternalShutdownException):
        executor.spin_once(timeout_sec=0)


def test_destroy_node_removes_its_entities(rclpy, runtime):
    from std_msgs.msg import Int32
    node = rclpy.create_node('n')
    node.create_publisher(Int32, 'topic', 10)
    fired = []
    node.create_timer(0.1, lambda: fired.append(1))
    node.destroy_node()
    runtime.run_until(10 ** 9)
    assert fired == [] and node.count_publishers('topic') == 0


def test_publishing_after_shutdown_fails_like_rcl(rclpy):
    from std_msgs.msg import Int32
    publisher = rclpy.create_node('n').create_publisher(Int32, 'topic', 10)
    rclpy.shutdown()
    with pytest.raises(RuntimeError, match="publisher's context is invalid"):
        publisher.publish(Int32())
