"""Publishing fails exactly where Jazzy's C converter aborts, with a message naming the field."""

import numpy as np
import pytest

from sim_bridge.lockstep import MessageTypeError, NodeError


@pytest.fixture
def node(rclpy):
    return rclpy.create_node('wall_follow')


def publisher_of(node, msgtype: str, topic: str):
    from sim_bridge.lockstep import message_class
    cls = message_class(msgtype)
    return cls, node.create_publisher(cls, topic, 10)


def test_int_in_a_float_field_fails_at_publish_naming_node_topic_field_and_type(node):
    from geometry_msgs.msg import Twist
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    twist = Twist()
    twist.angular.z = 0
    with pytest.raises(MessageTypeError) as raised:
        publisher.publish(twist)
    assert str(raised.value) == ("node 'wall_follow' published /cmd_vel: field 'angular.z' "
                                 'must be float (float64), got int 0')
    assert isinstance(raised.value, TypeError)
    assert (raised.value.field, raised.value.topic) == ('angular.z', '/cmd_vel')


def test_numpy_float32_fails_and_numpy_float64_passes(node):
    from geometry_msgs.msg import Twist
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    twist = Twist()
    twist.linear.x = np.float32(0.2)
    with pytest.raises(MessageTypeError, match=r"'linear.x' must be float \(float64\), got "
                                               r'numpy.float32 0.2'):
        publisher.publish(twist)
    twist.linear.x = np.float64(0.2)
    publisher.publish(twist)


@pytest.mark.parametrize('msgtype, field, value, expected', [
    ('std_msgs/msg/Bool', 'data', 1, r'bool \(bool\)'),
    ('std_msgs/msg/Int32', 'data', 1.0, r'int in \[-2147483648, 2147483647\] \(int32\)'),
    ('std_msgs/msg/Int32', 'data', 2 ** 31, r'int in \[-2147483648, 2147483647\] \(int32\)'),
    ('std_msgs/msg/UInt8', 'data', -1, r'int in \[0, 255\] \(uint8\)'),
    ('std_msgs/msg/Int64', 'data', np.int64(3), r'int in .* \(int64\)'),
    ('std_msgs/msg/String', 'data', None, r'str \(string\)'),
    ('std_msgs/msg/Float32', 'data', '1.0', r'float \(float32\)'),
])
def test_scalar_fields_need_the_python_type_the_converter_checks(node, msgtype, field, value,
                                                                 expected):
    cls, publisher = publisher_of(node, msgtype, 'topic')
    msg = cls()
    setattr(msg, field, value)
    with pytest.raises(MessageTypeError, match=f"field '{field}' must be {expected}"):
        publisher.publish(msg)


def test_bool_is_an_int_to_the_converter(node, runtime):
    cls, publisher = publisher_of(node, 'std_msgs/msg/Int32', 'topic')
    received = []
    node.create_subscription(cls, 'topic', received.append, 10)
    publisher.publish(cls(data=True))
    runtime.run_until(0)
    assert [msg.data for msg in received] == [True]


def test_wrong_sub_message_type_is_named(node):
    from geometry_msgs.msg import Point, Twist
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    twist = Twist()
    twist.linear = Point()
    with pytest.raises(MessageTypeError, match="field 'linear' must be geometry_msgs/msg/Vector3,"
                                               ' got geometry_msgs/msg/Point'):
        publisher.publish(twist)


def test_bad_element_of_a_message_sequence_is_named_by_index(node):
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage
    publisher = node.create_publisher(TFMessage, '/tf', 10)
    bad = TransformStamped()
    bad.transform.rotation.w = 1
    with pytest.raises(MessageTypeError, match=r"'transforms\[1\].transform.rotation.w'"):
        publisher.publish(TFMessage(transforms=[TransformStamped(), bad]))


def test_wrongly_sized_fixed_array_is_named(node):
    from nav_msgs.msg import Odometry
    publisher = node.create_publisher(Odometry, 'odom', 10)
    odom = Odometry()
    odom.pose.covariance = [0.0] * 35
    with pytest.raises(MessageTypeError, match=r"'pose.covariance' must be numpy.ndarray of 36 "
                                               r'float64 \(float64\[36\]\)'):
        publisher.publish(odom)


def test_publishing_another_message_class_is_a_type_error(node):
    from geometry_msgs.msg import Twist, TwistStamped
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    with pytest.raises(MessageTypeError, match='expected a geometry_msgs/msg/Twist message, got '
                                               'geometry_msgs/msg/TwistStamped'):
        publisher.publish(TwistStamped())


def test_publish_error_inside_a_callback_leaves_run_until_as_node_error(rclpy, runtime):
    from geometry_msgs.msg import Twist
    node = rclpy.create_node('wall_follow')
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)

    def turn():
        twist = Twist()
        twist.angular.z = 0
        publisher.publish(twist)
    node.create_timer(0.1, turn)
    with pytest.raises(NodeError) as raised:
        runtime.run_until(10 ** 9)
    assert raised.value.node_name == 'wall_follow'
    assert isinstance(raised.value.original, MessageTypeError)
    assert str(raised.value).startswith("node 'wall_follow' published /cmd_vel: field 'angular.z'")
    assert runtime.now_ns == 100_000_000


def test_publisher_reports_its_resolved_topic_and_subscription_count(rclpy):
    from std_msgs.msg import Int32
    node = rclpy.create_node('talker', namespace='robot1')
    publisher = node.create_publisher(Int32, 'chatter', 10)
    assert publisher.topic_name == '/robot1/chatter'
    node.create_subscription(Int32, 'chatter', lambda msg: None, 10)
    assert publisher.get_subscription_count() == 1
