"""
Padding zeroer: rclpy's CDR bytes with their unwritten padding zeroed, and nothing else changed.

Fast CDR (under ``rclpy.serialization.serialize_message`` and DDS) skips the alignment padding
and may leave bytes after the message unwritten, holding whatever the heap held. The zeroed
bytes are checked against two references independent of the zeroer: rclpy's deserialisation
(the message is intact) and rosbags' serialisation of the same message, which writes every
padding byte as zero (the bytes are canonical). Padding positions are found without the
zeroer's walk of the layout either: a byte is padding when no reader sees it changed.
"""

import array
import importlib
import math
import random
import struct

from geometry_msgs.msg import Point32, PointStamped, PolygonStamped, TwistStamped
from hypothesis import given, settings, strategies as st
from nav_msgs.msg import OccupancyGrid, Odometry
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.serde import SerdeError
from rosbags.typesys import get_typestore, Stores
from rosgraph_msgs.msg import Clock
from rosidl_parser import definition
from sensor_msgs.msg import JointState, LaserScan, PointCloud2, PointField
from sim_bridge.common.message_types import message_type_name
from sim_bridge.runner.cdr_padding import PaddingZeroer
from std_msgs.msg import Bool, ByteMultiArray, Empty, MultiArrayDimension, String

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
ZERO_PADDING = PaddingZeroer()
#: Little-endian plain CDR, no options: what rclpy and rosbags write.
HEADER = b'\x00\x01\x00\x00'
GARBAGE = 0xAA
PROPERTIES = settings(derandomize=True, database=None, deadline=None, max_examples=100)


def stamped(msg, frame_id, sec=12, nanosec=345_000_000):
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return msg


def odometry():
    odom = stamped(Odometry(child_frame_id='base_link'), 'odom')
    odom.pose.pose.position.x, odom.pose.pose.orientation.w = 1.5, 1.0
    odom.pose.covariance = np.arange(36, dtype=float) * 0.25
    odom.twist.twist.linear.x, odom.twist.twist.angular.z = 0.3, -0.125
    odom.twist.covariance = -np.arange(36, dtype=float)
    return odom


def twist_stamped():
    msg = stamped(TwistStamped(), 'b')
    msg.twist.linear.x, msg.twist.angular.z = 0.25, -1.0
    return msg


def point_stamped():
    msg = stamped(PointStamped(), 'map_12')
    msg.point.x, msg.point.y, msg.point.z = 1.0, -2.5, math.pi
    return msg


def point_cloud():
    fields = [PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32, count=1)
              for index, name in enumerate('xyz')]
    return stamped(PointCloud2(height=1, width=2, fields=fields, is_bigendian=False,
                               point_step=12, row_step=24, data=bytes(range(24)),
                               is_dense=True), 'lidar')


def occupancy_grid():
    grid = stamped(OccupancyGrid(data=[-1, 0, 100, 50, 0, -1]), 'map')
    grid.info.map_load_time.sec = 3
    grid.info.resolution, grid.info.width, grid.info.height = 0.0625, 3, 2
    grid.info.origin.position.x, grid.info.origin.orientation.w = -1.5, 1.0
    return grid


def byte_multi_array():
    msg = ByteMultiArray(data=[b'\x01', b'\xff', b'\x00'])
    msg.layout.dim = [MultiArrayDimension(label='x', size=3, stride=3)]
    msg.layout.data_offset = 1
    return msg


def polygon():
    msg = stamped(PolygonStamped(), 'odom')
    msg.polygon.points = [Point32(x=1.0, y=2.0, z=0.5), Point32(x=-1.25), Point32(z=4.0)]
    return msg


def clock():
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = 7, 10_000_000
    return msg


#: Messages of the types a run records and of layouts with padding of every kind: after
#: strings of every length modulo 4 before 4- and 8-byte fields, after a bool, around empty
#: sequences, in sequences of strings and of messages, and fixed-size arrays. float32 values
#: are exact in float32, so a message read back equals the one sent.
MESSAGES = [
    pytest.param(stamped(LaserScan(angle_min=-1.5, angle_max=1.5, angle_increment=0.75,
                                   time_increment=0.0, scan_time=0.0625, range_min=0.125,
                                   range_max=10.0, ranges=[0.5, math.inf, -math.inf, math.nan,
                                                           2.25],
                                   intensities=[1.0, 2.0, 0.0, 7.0, 3.0]), 'laser'),
                 id='LaserScan'),
    pytest.param(stamped(LaserScan(range_max=10.0), 'base_scan'), id='LaserScan-empty-ranges'),
    pytest.param(LaserScan(), id='LaserScan-default'),
    pytest.param(odometry(), id='Odometry-covariance-arrays'),
    pytest.param(twist_stamped(), id='TwistStamped'),
    pytest.param(point_stamped(), id='PointStamped'),
    pytest.param(stamped(JointState(name=['left_wheel', 'r', 'arm'], position=[1.0, -2.0, 0.5],
                                    velocity=[], effort=[0.0, math.nan, 3.0]), 'base_link'),
                 id='JointState'),
    pytest.param(stamped(JointState(name=['a', 'bc']), 'x'), id='JointState-empty-floats'),
    pytest.param(JointState(), id='JointState-default'),
    pytest.param(stamped(PolygonStamped(), 'map'), id='PolygonStamped-empty'),
    pytest.param(polygon(), id='PolygonStamped'),
    pytest.param(String(data=''), id='String-empty'),
    pytest.param(String(data='abc'), id='String'),
    pytest.param(String(data='h\u00e9llo w\u00f6rld \u2192'), id='String-utf8'),
    pytest.param(Bool(data=True), id='Bool'),
    pytest.param(Empty(), id='Empty'),
    pytest.param(byte_multi_array(), id='ByteMultiArray'),
    pytest.param(point_cloud(), id='PointCloud2'),
    pytest.param(occupancy_grid(), id='OccupancyGrid'),
    pytest.param(clock(), id='Clock'),
]


def differences(actual, expected, path='msg'):
    """Return the paths of the fields of two rclpy messages that differ, NaN equal to NaN."""
    if hasattr(expected, 'get_fields_and_field_types'):
        if type(actual) is not type(expected):
            return [path]
        return [difference for name in expected.get_fields_and_field_types()
                for difference in differences(getattr(actual, name), getattr(expected, name),
                                              f'{path}.{name}')]
    if isinstance(expected, list):
        if not isinstance(actual, list) or len(actual) != len(expected):
            return [path]
        return [difference for index, (item, expected_item) in enumerate(zip(actual, expected))
                for difference in differences(item, expected_item, f'{path}[{index}]')]
    if isinstance(expected, (array.array, np.ndarray)):
        actual, expected = np.asarray(actual), np.asarray(expected)
        same = actual.dtype == expected.dtype and np.array_equal(
            actual, expected, equal_nan=expected.dtype.kind == 'f')
    elif isinstance(expected, float):
        same = isinstance(actual, float) and (
            actual == expected or math.isnan(actual) and math.isnan(expected))
    else:
        same = type(actual) is type(expected) and actual == expected
    return [] if same else [path]


def rosbags_bytes(type_name, data):
    """
    Return rosbags' serialisation of the message in the CDR bytes ``data``: zero padding.

    The message is read up to its end: Typestore.deserialize_cdr refuses more than 3 bytes
    after it, and Fast CDR leaves more after some messages (JointState, empty sequences).
    """
    assert data[:4] == HEADER
    msgdef = TYPESTORE.get_msgdef(type_name)
    msg, _ = msgdef.deserialize_cdr_le(memoryview(data)[4:], 0, msgdef.cls, TYPESTORE)
    return bytes(TYPESTORE.serialize_cdr(msg, type_name, little_endian=True))


def canonical(type_name, data):
    """Return rosbags' bytes of the message in ``data``, zero-filled to the length of ``data``."""
    reference = rosbags_bytes(type_name, data)
    assert len(reference) <= len(data)
    return reference + bytes(len(data) - len(reference))


def padding_positions(type_name, data, msg_class):
    """
    Return the positions of the bytes of ``data`` that neither rosbags nor rclpy reads.

    ``data`` are canonical CDR bytes (padding zero). Each zero byte in turn is set to garbage:
    it is padding if rosbags reads the same message (its serialisation unchanged) and so does
    rclpy (which sees string terminators, that rosbags skips). No layout is assumed.
    """
    reference = rosbags_bytes(type_name, data)
    expected = deserialize_message(data, msg_class)
    positions = []
    for position in range(len(HEADER), len(data)):
        if data[position]:
            continue
        garbled = bytearray(data)
        garbled[position] = GARBAGE
        garbled = bytes(garbled)
        try:
            if rosbags_bytes(type_name, garbled) != reference:
                continue
        except (SerdeError, struct.error, UnicodeDecodeError, ValueError, IndexError):
            continue
        if not differences(deserialize_message(garbled, msg_class), expected):
            positions.append(position)
    return positions


def with_garbage(data, positions, garbage=None):
    """Return ``data`` with the bytes at ``positions`` set to ``garbage`` (GARBAGE each)."""
    garbled = bytearray(data)
    for index, position in enumerate(positions):
        garbled[position] = GARBAGE if garbage is None else garbage[index]
    return bytes(garbled)


@pytest.mark.parametrize('msg', MESSAGES)
def test_zeroed_bytes_read_back_as_the_message_with_only_padding_changed(msg):
    type_name = message_type_name(msg)
    data = serialize_message(msg)
    zeroed = ZERO_PADDING(type_name, data)
    assert isinstance(zeroed, bytes) and len(zeroed) == len(data)
    assert zeroed[:4] == data[:4] == HEADER
    assert all(byte == original or byte == 0 for byte, original in zip(zeroed, data))
    assert not differences(deserialize_message(zeroed, type(msg)), msg)


@pytest.mark.parametrize('msg', MESSAGES)
def test_zeroed_bytes_are_rosbags_bytes_then_zeros(msg):
    type_name = message_type_name(msg)
    data = serialize_message(msg)
    zeroed = ZERO_PADDING(type_name, data)
    reference = rosbags_bytes(type_name, data)
    assert zeroed[:len(reference)] == reference
    assert zeroed[len(reference):] == bytes(len(data) - len(reference))


@pytest.mark.parametrize('msg, positions', [
    (Bool(data=True), [5, 6, 7]),  # Fast CDR pads the length to a multiple of 4
    (String(data='abc'), []),
    # Stamp 4..11, frame_id length 12..15 and 'laser\0' 16..21; float32s from 24.
    (stamped(LaserScan(ranges=[1.0]), 'laser'), [22, 23]),
    # 'b\0' 16..17; float64s from 20, at a multiple of 8 after the header.
    (twist_stamped(), [18, 19]),
    # '\0' 16; four empty sequences 20..35, not aligned to 8; 8 bytes Fast CDR left unwritten.
    (JointState(), [17, 18, 19] + list(range(36, 44))),
    (Empty(), [5, 6, 7]),
])
def test_padding_found_by_trying_bytes_is_where_the_layout_puts_it(msg, positions):
    """Both the way the tests find padding and the zeroer agree with layouts worked by hand."""
    type_name = message_type_name(msg)
    data = serialize_message(msg)
    expected = canonical(type_name, data)
    assert padding_positions(type_name, expected, type(msg)) == positions
    assert ZERO_PADDING(type_name, with_garbage(expected, positions)) == expected
    assert ZERO_PADDING(type_name, data) == expected


@pytest.mark.parametrize('msg', MESSAGES)
def test_garbage_in_every_padding_byte_is_zeroed(msg):
    type_name = message_type_name(msg)
    data = serialize_message(msg)
    expected = canonical(type_name, data)
    positions = padding_positions(type_name, expected, type(msg))
    # Whatever Fast CDR left in the bytes is in padding.
    assert {index for index, byte in enumerate(data) if byte != expected[index]} <= \
        set(positions)
    garbled = with_garbage(expected, positions)
    assert ZERO_PADDING(type_name, garbled) == expected
    assert not differences(deserialize_message(garbled, type(msg)), msg)


@pytest.mark.parametrize('length', range(10))
def test_garbage_is_zeroed_after_strings_of_every_length(length):
    """A string of each length modulo 4 (and 8) before 4-byte, 8-byte and sequence fields."""
    text = 'abcdefghij'[:length]
    for msg in (stamped(LaserScan(ranges=[1.0, 2.0], intensities=[3.0]), text),
                stamped(JointState(name=[text, 'ab'], position=[1.0], effort=[2.0]), text),
                stamped(twist_stamped(), text), String(data=text)):
        type_name = message_type_name(msg)
        expected = canonical(type_name, serialize_message(msg))
        positions = padding_positions(type_name, expected, type(msg))
        assert ZERO_PADDING(type_name, with_garbage(expected, positions)) == expected, type_name


def test_a_message_of_the_same_type_and_size_laid_out_otherwise_is_walked_anew():
    """The zeroer keeps where a type's padding was: for messages with the same lengths only."""
    zeroer = PaddingZeroer()
    # 68 bytes each; the frame_id's padding is bytes 18..19 in one, 22..23 in the other.
    one = stamped(LaserScan(ranges=[1.0, 2.0], intensities=[3.0]), 'a')
    other = stamped(LaserScan(ranges=[1.0], intensities=[3.0]), 'abcde')
    assert len(serialize_message(one)) == len(serialize_message(other))
    for msg in (one, one, other, one, other):
        type_name = message_type_name(msg)
        expected = canonical(type_name, serialize_message(msg))
        positions = padding_positions(type_name, expected, type(msg))
        assert zeroer(type_name, with_garbage(expected, positions)) == expected


frame_ids = st.text('abcdefghijklmnopqrstuvwxyz_/0123456789', max_size=9)
texts = st.text(st.characters(codec='utf-8', exclude_characters='\x00'), max_size=9)
float32s = st.floats(width=32)
stamps = st.tuples(st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, 2 ** 32 - 1))


@st.composite
def scans(draw):
    scan = LaserScan(**{name: draw(float32s) for name in (
        'angle_min', 'angle_max', 'angle_increment', 'time_increment', 'scan_time',
        'range_min', 'range_max')})
    scan.ranges = draw(st.lists(float32s, max_size=6))
    scan.intensities = draw(st.lists(float32s, max_size=6))
    return stamped(scan, draw(frame_ids), *draw(stamps))


@st.composite
def joint_states(draw):
    names = draw(st.lists(texts, max_size=3))
    msg = JointState(name=names, **{name: draw(st.lists(st.floats(), max_size=3))
                                    for name in ('position', 'velocity', 'effort')})
    return stamped(msg, draw(frame_ids), *draw(stamps))


@PROPERTIES
@given(st.one_of(scans(), joint_states(), texts.map(lambda text: String(data=text))),
       st.data())
def test_any_garbage_in_the_padding_of_any_scan_joint_state_or_string_is_zeroed(msg, data):
    type_name = message_type_name(msg)
    clean = serialize_message(msg)
    expected = canonical(type_name, clean)
    positions = padding_positions(type_name, expected, type(msg))
    garbage = data.draw(st.lists(st.integers(1, 255), min_size=len(positions),
                                 max_size=len(positions)))
    garbled = with_garbage(expected, positions, garbage)
    assert ZERO_PADDING(type_name, garbled) == ZERO_PADDING(type_name, clean) == expected
    assert not differences(deserialize_message(expected, type(msg)), msg)


def test_the_same_message_serialised_again_and_again_gives_the_same_zeroed_bytes():
    """Serialising other messages in between leaves their bytes where Fast CDR allocates."""
    rng = random.Random(5)
    messages = [stamped(LaserScan(ranges=[1.0] * 5, intensities=[2.0]), 'laser'),
                stamped(JointState(name=['a', 'bcd'], position=[1.0, 2.0]), 'j'),
                twist_stamped(), odometry(), Bool()]
    raw_versions = {}
    for msg in messages:
        type_name = message_type_name(msg)
        raw, zeroed = set(), set()
        for _ in range(200):
            for _ in range(rng.randrange(3)):
                serialize_message(String(data=''.join(
                    rng.choice('abcdefghijklmnopqrstuvwxyz') for _ in range(rng.randrange(200)))))
            data = serialize_message(msg)
            raw.add(data)
            zeroed.add(ZERO_PADDING(type_name, data))
        assert zeroed == {canonical(type_name, data)}, type_name
        raw_versions[type_name] = len(raw)
    # Else the churn left the padding as it found it and the test above proved nothing.
    assert max(raw_versions.values()) > 1, raw_versions


def installed_message_class(type_name):
    """Return the rclpy class of ``type_name`` (``pkg/msg/Name``), None if not installed."""
    package, _, name = type_name.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError):
        return None


#: Every message type of rosbags' Jazzy type store whose rclpy class is installed.
INSTALLED = {type_name: cls for type_name in sorted(TYPESTORE.fielddefs)
             if (cls := installed_message_class(type_name)) is not None}
_INTEGER_BITS = {'int8': 8, 'uint8': 8, 'char': 8, 'int16': 16, 'uint16': 16, 'int32': 32,
                 'uint32': 32, 'int64': 64, 'uint64': 64}


def random_value(slot_type, rng):
    """Return a random value of a rosidl field type (``SLOT_TYPES``), short if a string."""
    if isinstance(slot_type, definition.BasicType):
        name = slot_type.typename
        if name == 'boolean':
            return rng.random() < 0.5
        if name == 'octet':
            return bytes([rng.randrange(256)])
        if name == 'float':
            return float(np.float32(rng.uniform(-1e3, 1e3)))
        if name == 'double':
            return rng.uniform(-1e6, 1e6)
        bits = _INTEGER_BITS[name]
        low = -2 ** (bits - 1) if name.startswith('int') else 0
        return rng.randrange(low, low + 2 ** bits)
    if isinstance(slot_type, definition.AbstractString):
        size = rng.randint(0, min(getattr(slot_type, 'maximum_size', 9), 9))
        return ''.join(rng.choice('abcxyz_/') for _ in range(size))
    if isinstance(slot_type, definition.NamespacedType):
        cls = getattr(importlib.import_module('.'.join(slot_type.namespaces)), slot_type.name)
        return random_message(cls, rng)
    if isinstance(slot_type, definition.Array):
        return [random_value(slot_type.value_type, rng) for _ in range(slot_type.size)]
    # Up to 4 numbers or strings, up to 2 messages (nested messages nest sequences too).
    longest = 2 if isinstance(slot_type.value_type, definition.NamespacedType) else 4
    size = rng.randint(0, min(getattr(slot_type, 'maximum_size', longest), longest))
    return [random_value(slot_type.value_type, rng) for _ in range(size)]


def random_message(cls, rng):
    msg = cls()
    for name, slot_type in zip(msg.get_fields_and_field_types(), cls.SLOT_TYPES):
        setattr(msg, name, random_value(slot_type, rng))
    return msg


def test_the_installed_message_types_are_many():
    assert len(INSTALLED) > 100
    assert {'sensor_msgs/msg/LaserScan', 'nav_msgs/msg/Odometry', 'rosgraph_msgs/msg/Clock',
            'geometry_msgs/msg/Twist', 'sensor_msgs/msg/JointState'} <= set(INSTALLED)


@pytest.mark.parametrize('type_name', sorted(INSTALLED))
def test_every_installed_message_type_with_random_contents(type_name):
    cls = INSTALLED[type_name]
    rng = random.Random(type_name)
    for msg in [cls()] + [random_message(cls, rng) for _ in range(3)]:
        data = serialize_message(msg)
        expected = canonical(type_name, data)
        assert ZERO_PADDING(type_name, data) == expected
        assert not differences(deserialize_message(expected, cls), msg)
        garbled = with_garbage(expected, padding_positions(type_name, expected, cls))
        assert ZERO_PADDING(type_name, garbled) == expected


def test_bytes_that_do_not_hold_the_type_raise_at_once():
    zeroer = PaddingZeroer()
    with pytest.raises(ValueError, match='do not hold this type'):
        zeroer('geometry_msgs/msg/Polygon', b'\x00\x01\x00\x00\x00\x00\x00\x01')
    with pytest.raises(ValueError, match='too few'):
        zeroer('geometry_msgs/msg/Twist', b'\x00\x01\x00\x00' + bytes(8))
