"""Message classes generated from the rosbags type store behave like rosidl_generator_py's."""

from array import array

import numpy as np
import pytest
from rosbags.typesys import get_typestore, Stores

from sim_bridge.lockstep import message_class
from sim_bridge.lockstep.messages import package_modules, packages

LaserScan = message_class('sensor_msgs/msg/LaserScan')
Odometry = message_class('nav_msgs/msg/Odometry')
Twist = message_class('geometry_msgs/msg/Twist')
Vector3 = message_class('geometry_msgs/msg/Vector3')
TFMessage = message_class('tf2_msgs/msg/TFMessage')
TransformStamped = message_class('geometry_msgs/msg/TransformStamped')

ALL_TYPES = sorted(name for name in get_typestore(Stores.ROS2_JAZZY).fielddefs if '/msg/' in name)


def test_defaults_are_zero_empty_and_fresh_per_instance():
    scan = LaserScan()
    assert scan.angle_min == 0.0 and isinstance(scan.angle_min, float)
    assert scan.header.frame_id == '' and scan.header.stamp.sec == 0
    assert scan.ranges == array('f') and scan.intensities == array('f')
    other = LaserScan()
    assert other.header is not scan.header and other.ranges is not scan.ranges


def test_quaternion_default_is_the_identity_rotation_as_in_jazzy():
    assert Odometry().pose.pose.orientation.w == 1.0


def test_fixed_numeric_arrays_are_numpy_arrays_of_the_field_dtype():
    covariance = Odometry().pose.covariance
    assert isinstance(covariance, np.ndarray)
    assert covariance.dtype == np.float64 and covariance.shape == (36,)
    assert not covariance.any()


def test_slots_reject_unknown_attributes():
    twist = Twist()
    with pytest.raises(AttributeError):
        twist.linaer = Vector3()
    assert '_linear' in Twist.__slots__ and '_check_fields' in Twist.__slots__


@pytest.mark.parametrize('value', [[1.0, 2.5], (1.0, 2.5), np.array([1.0, 2.5]),
                                   np.array([1.0, 2.5], dtype=np.float32), array('d', [1, 2.5])])
def test_float32_sequences_convert_any_sequence_to_array_f(value):
    scan = LaserScan()
    scan.ranges = value
    assert isinstance(scan.ranges, array) and scan.ranges.typecode == 'f'
    assert list(scan.ranges) == [1.0, 2.5]


def test_float32_sequence_rounds_to_float32_like_array_array():
    scan = LaserScan(ranges=np.array([0.1]))
    assert scan.ranges[0] == array('f', [0.1])[0] != 0.1


def test_fixed_array_assignment_converts_lists_to_numpy():
    odom = Odometry()
    odom.pose.covariance = [1] * 36
    assert odom.pose.covariance.dtype == np.float64 and odom.pose.covariance[0] == 1.0


def test_constructor_keywords_set_fields_and_convert():
    scan = LaserScan(angle_min=-1.57, ranges=[1.0, 2.0])
    assert scan.angle_min == -1.57 and scan.ranges == array('f', [1.0, 2.0])


def test_constructor_rejects_a_wrongly_sized_fixed_array_as_rosidl_asserts():
    with pytest.raises(AssertionError):
        message_class('geometry_msgs/msg/PoseWithCovariance')(covariance=[0.0] * 35)


def test_unknown_constructor_keyword_is_ignored_without_field_checks_as_in_jazzy():
    twist = Twist(lineaar=Vector3(x=1.0))
    assert twist.linear.x == 0.0


def test_field_checks_reject_unknown_keywords_and_wrong_types_when_enabled():
    with pytest.raises(AssertionError, match='Invalid arguments passed to constructor: lineaar'):
        Twist(check_fields=True, lineaar=Vector3())
    vector = Vector3(check_fields=True)
    with pytest.raises(AssertionError, match="The 'x' field must be of type 'float'"):
        vector.x = 0
    vector.x = 1.0
    assert vector.x == 1.0


def test_field_checks_accept_only_what_rosidl_asserts_for_sequences():
    scan = LaserScan(check_fields=True)
    scan.ranges = [1.0, 2.0]
    own = array('f', [3.0])
    scan.ranges = own
    assert scan.ranges is own
    for wrong in (np.array([1.0]), [1, 2], array('d', [1.0])):
        with pytest.raises(AssertionError):
            scan.ranges = wrong


def test_assignment_of_a_wrong_type_is_accepted_until_publish_without_field_checks():
    twist = Twist()
    twist.angular.z = 0
    assert twist.angular.z == 0 and isinstance(twist.angular.z, int)


def test_equality_compares_every_field_including_arrays():
    assert Odometry() == Odometry()
    odom = Odometry()
    odom.pose.covariance[3] = 1.0
    assert odom != Odometry()
    assert LaserScan(ranges=[1.0]) == LaserScan(ranges=[1.0]) != LaserScan(ranges=[2.0])
    assert Twist() != Vector3()


def test_repr_reads_like_rosidl():
    text = repr(LaserScan(ranges=[1.0]))
    assert text.startswith('sensor_msgs.msg.LaserScan(header=std_msgs.msg.Header(stamp='
                           'builtin_interfaces.msg.Time(sec=0, nanosec=0), frame_id=')
    assert text.endswith('ranges=[1.0], intensities=[])')


def test_fields_and_field_types_use_idl_names():
    assert LaserScan.get_fields_and_field_types()['ranges'] == 'sequence<float>'
    assert LaserScan.get_fields_and_field_types()['header'] == 'std_msgs/Header'
    assert message_class('geometry_msgs/msg/PoseWithCovariance') \
        .get_fields_and_field_types()['covariance'] == 'double[36]'
    assert TFMessage.get_fields_and_field_types() == {
        'transforms': 'sequence<geometry_msgs/TransformStamped>'}


def test_constants_are_class_attributes_with_their_values():
    status = message_class('sensor_msgs/msg/NavSatStatus')
    assert status.STATUS_FIX == 0 and status.SERVICE_GALILEO == 8
    assert message_class('diagnostic_msgs/msg/DiagnosticStatus').WARN == b'\x01'


def test_empty_message_has_no_fields_like_rosidl():
    empty = message_class('std_msgs/msg/Empty')()
    assert empty.get_fields_and_field_types() == {}
    assert repr(empty) == 'std_msgs.msg.Empty()'


def test_module_names_follow_rosidl_so_repr_and_pickling_paths_match():
    assert TFMessage.__module__ == 'tf2_msgs.msg._tf_message'
    assert LaserScan.__module__ == 'sensor_msgs.msg._laser_scan'


def test_package_modules_list_every_message_of_the_package():
    _, msg = package_modules('std_msgs')
    assert 'Int32' in msg.__all__ and msg.Int32 is message_class('std_msgs/msg/Int32')
    with pytest.raises(AttributeError):
        msg.NoSuchMessage
    assert {'sensor_msgs', 'geometry_msgs', 'nav_msgs', 'tf2_msgs', 'rosgraph_msgs',
            'builtin_interfaces', 'std_msgs', 'rcl_interfaces'} <= set(packages())


@pytest.mark.parametrize('msgtype', ALL_TYPES)
def test_every_jazzy_message_builds_validates_and_copies(msgtype):
    cls = message_class(msgtype)
    msg = cls()
    assert cls._lockstep_check(msg) is None
    copy = cls._lockstep_copy(msg)
    assert copy == msg and copy is not msg


def test_copy_is_deep_and_rounds_float32_fields_like_the_c_converter():
    scan = LaserScan(angle_min=-1.57, ranges=[1.0])
    copy = LaserScan._lockstep_copy(scan)
    assert copy.angle_min == float(np.float32(-1.57)) != -1.57
    copy.ranges[0] = 5.0
    copy.header.frame_id = 'changed'
    assert scan.ranges[0] == 1.0 and scan.header.frame_id == ''


def test_copy_turns_numpy_float64_and_bool_subclasses_into_plain_python_values():
    vector = Vector3(x=np.float64(0.5))
    assert type(Vector3._lockstep_copy(vector).x) is float
    stamp = message_class('builtin_interfaces/msg/Time')(sec=True)
    assert type(message_class('builtin_interfaces/msg/Time')._lockstep_copy(stamp).sec) is int


def test_copy_of_float32_beyond_range_is_infinite_like_a_c_cast():
    scan = LaserScan(angle_max=1e39)
    assert LaserScan._lockstep_copy(scan).angle_max == float('inf')


def test_sub_message_sequences_are_copied_element_by_element():
    tf = TFMessage(transforms=[TransformStamped(child_frame_id='laser')])
    copy = TFMessage._lockstep_copy(tf)
    assert copy.transforms[0] == tf.transforms[0] and copy.transforms[0] is not tf.transforms[0]
