"""Runtime messages convert to rosbags messages that serialise and read back equal."""

import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores

from sim_bridge.lockstep import message_class, msg_to_rosbags

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def round_trip(msg):
    converted = msg_to_rosbags(msg, TYPESTORE)
    msgtype = converted.__msgtype__
    return TYPESTORE.deserialize_cdr(TYPESTORE.serialize_cdr(converted, msgtype), msgtype)


def test_laser_scan_survives_cdr_serialisation():
    scan = message_class('sensor_msgs/msg/LaserScan')(
        angle_min=-1.5, angle_max=1.5, ranges=[0.5, float('inf'), 2.0])
    scan.header.frame_id = 'laser'
    scan.header.stamp.sec = 12
    back = round_trip(scan)
    assert back.header.frame_id == 'laser' and back.header.stamp.sec == 12
    assert back.angle_min == -1.5
    np.testing.assert_array_equal(back.ranges, np.array([0.5, np.inf, 2.0], dtype=np.float32))


def test_odometry_keeps_its_fixed_covariance_and_nested_pose():
    odom = message_class('nav_msgs/msg/Odometry')(child_frame_id='base_link')
    odom.pose.pose.position.x = 1.25
    odom.pose.covariance[0] = 0.5
    back = round_trip(odom)
    assert back.child_frame_id == 'base_link' and back.pose.pose.position.x == 1.25
    assert back.pose.pose.orientation.w == 1.0 and back.pose.covariance[0] == 0.5


def test_tf_message_keeps_every_transform():
    transform = message_class('geometry_msgs/msg/TransformStamped')(child_frame_id='laser')
    tf = message_class('tf2_msgs/msg/TFMessage')(transforms=[transform, transform])
    assert [t.child_frame_id for t in round_trip(tf).transforms] == ['laser', 'laser']


def test_empty_message_gets_the_placeholder_field_rosbags_needs():
    assert round_trip(message_class('std_msgs/msg/Empty')()).structure_needs_at_least_one_member \
        == 0


@pytest.mark.parametrize('msgtype, fields', [
    ('rcl_interfaces/msg/ParameterValue', {'bool_array_value': [True, False],
                                           'byte_array_value': [b'\x01', b'\x02'],
                                           'string_array_value': ['a']}),
    ('std_msgs/msg/Byte', {'data': b'\x07'}),
])
def test_bool_byte_and_string_containers_convert(msgtype, fields):
    back = round_trip(message_class(msgtype)(**fields))
    if msgtype == 'std_msgs/msg/Byte':
        assert back.data == 7
    else:
        assert list(back.bool_array_value) == [True, False]
        assert list(back.byte_array_value) == [1, 2] and back.string_array_value == ['a']
