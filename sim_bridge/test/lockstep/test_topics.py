"""Delivery follows QoS matching, history depth and durability as in ROS 2 Jazzy."""

import pytest

from sim_bridge.lockstep import TopicTypeError


@pytest.fixture
def nodes(rclpy):
    return rclpy.create_node('talker'), rclpy.create_node('listener')


def int32(value: int):
    from std_msgs.msg import Int32
    return Int32(data=value)


def received_on(listener, topic: str, qos, msg_type=None) -> list:
    from std_msgs.msg import Int32
    received = []
    listener.create_subscription(msg_type or Int32, topic, received.append, qos)
    return received


def test_reliable_subscription_gets_nothing_from_a_best_effort_publisher_and_both_warn(
        nodes, runtime, logs):
    from rclpy.qos import qos_profile_sensor_data
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'scan', qos_profile_sensor_data)
    received = received_on(listener, 'scan', 10)
    publisher.publish(int32(1))
    publisher.publish(int32(2))
    runtime.run_until(0)
    assert received == []
    assert [(record.name, record.level, record.text) for record in logs] == [
        ('listener', 'WARN', "New publisher discovered on topic '/scan', offering incompatible "
                             'QoS. No messages will be received from it. Last incompatible '
                             'policy: RELIABILITY'),
        ('talker', 'WARN', "New subscription discovered on topic '/scan', requesting "
                           'incompatible QoS. No messages will be sent to it. Last incompatible '
                           'policy: RELIABILITY')]


def test_sensor_data_subscription_receives_from_a_reliable_publisher(nodes, runtime):
    from rclpy.qos import qos_profile_sensor_data
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'scan', 10)
    received = received_on(listener, 'scan', qos_profile_sensor_data)
    publisher.publish(int32(7))
    runtime.run_until(0)
    assert [msg.data for msg in received] == [7]


def test_transient_local_publisher_hands_its_last_depth_messages_to_late_joiners(nodes, runtime):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import Int32
    talker, listener = nodes
    latched = QoSProfile(depth=2, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    publisher = talker.create_publisher(Int32, 'map', latched)
    for value in (1, 2, 3):
        publisher.publish(int32(value))
    late = received_on(listener, 'map', latched)
    volatile = received_on(listener, 'map', 10)
    runtime.run_until(0)
    assert [msg.data for msg in late] == [2, 3]
    assert volatile == []


def test_transient_local_subscription_does_not_match_a_volatile_publisher(nodes, runtime, logs):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'map', 10)
    received = received_on(listener, 'map',
                           QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    publisher.publish(int32(1))
    runtime.run_until(0)
    assert received == [] and logs[0].text.endswith('Last incompatible policy: DURABILITY')


def test_keep_last_queue_drops_the_oldest_undelivered_messages(nodes, runtime):
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'burst', 10)
    shallow = received_on(listener, 'burst', 2)
    deep = received_on(listener, 'burst', 10)

    def burst():
        for value in range(5):
            publisher.publish(int32(value))
    talker.create_timer(1.0, burst)
    runtime.run_until(10 ** 9)
    assert [msg.data for msg in shallow] == [3, 4]
    assert [msg.data for msg in deep] == [0, 1, 2, 3, 4]


def test_keep_all_queue_keeps_everything(nodes, runtime):
    from rclpy.qos import HistoryPolicy, QoSProfile
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'burst', 10)
    received = received_on(listener, 'burst', QoSProfile(history=HistoryPolicy.KEEP_ALL))
    for value in range(50):
        publisher.publish(int32(value))
    runtime.run_until(0)
    assert len(received) == 50


def test_messages_published_in_a_callback_arrive_after_it_returns_in_publish_order(
        nodes, runtime):
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'numbers', 10)
    events = []
    listener.create_subscription(Int32, 'numbers',
                                 lambda msg: events.append(('received', msg.data,
                                                            runtime.now_ns)), 10)

    def publish_two():
        publisher.publish(int32(1))
        publisher.publish(int32(2))
        events.append(('callback done', None, runtime.now_ns))
    talker.create_timer(0.25, publish_two)
    runtime.run_until(250_000_000)
    assert events == [('callback done', None, 250_000_000), ('received', 1, 250_000_000),
                      ('received', 2, 250_000_000)]


def test_each_subscription_gets_its_own_copy(nodes, runtime):
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'numbers', 10)
    first = received_on(listener, 'numbers', 10)
    second = received_on(talker, 'numbers', 10)
    sent = int32(5)
    publisher.publish(sent)
    sent.data = 6
    runtime.run_until(0)
    assert first[0] is not second[0] and first[0].data == second[0].data == 5


def test_taps_see_every_successful_publish_with_its_sim_time(nodes, runtime):
    from std_msgs.msg import Int32
    talker, _ = nodes
    publisher = talker.create_publisher(Int32, 'numbers', 10)
    seen = []
    runtime.add_tap(lambda topic, msg, t_ns: seen.append((topic, msg.data, t_ns)))
    talker.create_timer(0.5, lambda: publisher.publish(int32(int(runtime.now_ns // 10 ** 8))))
    runtime.run_until(10 ** 9)
    assert seen == [('/numbers', 5, 500_000_000), ('/numbers', 10, 1_000_000_000)]


def test_a_tap_on_named_topics_sees_only_those(nodes, runtime):
    from std_msgs.msg import Int32
    talker, _ = nodes
    numbers = talker.create_publisher(Int32, 'numbers', 10)
    seen, everything = [], []
    runtime.add_tap(lambda topic, msg, t_ns: seen.append((topic, msg.data)),
                    topics=['/numbers', '/later'])
    runtime.add_tap(lambda topic, msg, t_ns: everything.append(topic))
    others = talker.create_publisher(Int32, 'others', 10)
    later = talker.create_publisher(Int32, 'later', 10)
    for publisher, value in ((numbers, 1), (others, 2), (later, 3)):
        publisher.publish(int32(value))
    assert seen == [('/numbers', 1), ('/later', 3)]
    assert everything == ['/numbers', '/others', '/later']


def test_a_removed_tap_sees_nothing_more(nodes, runtime):
    from std_msgs.msg import Int32
    talker, _ = nodes
    publisher = talker.create_publisher(Int32, 'numbers', 10)
    seen = []

    def tap(topic, msg, t_ns):
        seen.append(msg.data)
    runtime.add_tap(tap, topics=['/numbers'])
    publisher.publish(int32(1))
    runtime.remove_tap(tap)
    publisher.publish(int32(2))
    assert seen == [1]


def test_a_topic_carries_one_message_type(nodes):
    from geometry_msgs.msg import Twist, TwistStamped
    talker, listener = nodes
    listener.create_subscription(TwistStamped, 'cmd_vel', lambda msg: None, 10)
    with pytest.raises(TopicTypeError, match='/cmd_vel already carries '
                                             'geometry_msgs/msg/TwistStamped'):
        talker.create_publisher(Twist, 'cmd_vel', 10)


def test_destroyed_subscription_receives_nothing_more(nodes, runtime):
    from std_msgs.msg import Int32
    talker, listener = nodes
    publisher = talker.create_publisher(Int32, 'numbers', 10)
    received = []
    subscription = listener.create_subscription(Int32, 'numbers', received.append, 10)
    publisher.publish(int32(1))
    assert listener.destroy_subscription(subscription)
    publisher.publish(int32(2))
    runtime.run_until(0)
    assert received == [] and publisher.get_subscription_count() == 0


def test_qos_check_compatible_reports_like_rclpy():
    from sim_bridge.lockstep.rclpy.qos import (
        qos_check_compatible, qos_profile_sensor_data, QoSCompatibility, QoSProfile)
    assert qos_check_compatible(qos_profile_sensor_data, QoSProfile(depth=10)) == (
        QoSCompatibility.ERROR, 'ERROR: Best effort publisher and reliable subscription;')
    assert qos_check_compatible(QoSProfile(depth=10), qos_profile_sensor_data)[0] == \
        QoSCompatibility.OK


def test_a_tap_reads_an_unsubscribed_message_during_the_publish(nodes, runtime):
    from std_msgs.msg import Int32
    talker, _ = nodes
    publisher = talker.create_publisher(Int32, 'unheard', 10)
    seen = []
    runtime.add_tap(lambda topic, msg, t_ns: seen.append(msg.data))
    message = int32(7)
    publisher.publish(message)
    message.data = 8
    publisher.publish(message)
    assert seen == [7, 8]


def test_qos_policies_and_presets_resolve_short_keys_as_rclpy_does():
    from sim_bridge.lockstep.rclpy.qos import (
        qos_profile_sensor_data, QoSPresetProfiles, ReliabilityPolicy)
    assert ReliabilityPolicy.get_from_short_key('Best_Effort') == ReliabilityPolicy.BEST_EFFORT
    assert {'reliable', 'best_effort'} <= set(ReliabilityPolicy.short_keys())
    assert QoSPresetProfiles.get_from_short_key('sensor_data') is qos_profile_sensor_data
    assert 'sensor_data' in QoSPresetProfiles.short_keys()
