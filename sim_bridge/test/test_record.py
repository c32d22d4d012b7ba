"""Recording: CDR bytes equal rosbags' own, and bags read back with rosbags' reader intact."""

import math
import random
import struct

import numpy as np
import pytest
from rosbags.interfaces import Nodetype, QosDurability, QosReliability
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapReader
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
import yaml

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.messages.rosbags_conversion import msg_to_rosbags
from sim_bridge.record import (BAG_VERSION, BagRecorder, CdrSerializer, offered_qos,
                               ros_type_name)

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
MESSAGE_TYPES = sorted(name for name in TYPESTORE.fielddefs if '/msg/' in name)
SCALAR_VALUES = {
    'bool': lambda rng: rng.random() < 0.5,
    # rosbags packs a byte as a signed int8, so only 0..127 convert to it unchanged.
    'byte': lambda rng: bytes([rng.randrange(128)]),
    'char': lambda rng: rng.randrange(256),
    'float32': lambda rng: float(np.float32(rng.uniform(-1e3, 1e3))),
    'float64': lambda rng: rng.uniform(-1e6, 1e6),
    'string': lambda rng: ''.join(rng.choice('abcé/_ ') for _ in range(rng.randrange(6))),
}
INTEGER_BITS = {'int8': 8, 'int16': 16, 'int32': 32, 'int64': 64}


def random_scalar(type_name, rng):
    if type_name in SCALAR_VALUES:
        return SCALAR_VALUES[type_name](rng)
    bits = int(type_name.lstrip('uint'))
    if type_name.startswith('u'):
        return rng.randrange(2 ** bits)
    return rng.randrange(-2 ** (bits - 1), 2 ** (bits - 1))


def random_value(desc, rng):
    kind, detail = desc
    if kind == Nodetype.BASE:
        return random_scalar(detail[0], rng)
    if kind == Nodetype.NAME:
        return random_message(detail, rng)
    element, length = detail
    count = length if kind == Nodetype.ARRAY else rng.randrange(4)
    if length and kind == Nodetype.SEQUENCE:
        count = min(count, length)
    return [random_value(element, rng) for _ in range(count)]


def random_message(msgtype, rng):
    """Return a runtime message of ``msgtype`` with every field set to a random value."""
    msg = message_class(msgtype)()
    for name, desc in TYPESTORE.fielddefs[msgtype][1]:
        if hasattr(msg, name):
            setattr(msg, name, random_value(desc, rng))
    return msg


def every_message_with_rosbags_bytes(seed):
    """Yield (type name, random runtime message, rosbags' CDR bytes of it) for every type."""
    rng = random.Random(seed)
    for msgtype in MESSAGE_TYPES:
        msg = random_message(msgtype, rng)
        yield msgtype, msg, TYPESTORE.serialize_cdr(msg_to_rosbags(msg, TYPESTORE), msgtype)


@pytest.mark.parametrize('seed', range(3))
def test_serialised_bytes_equal_rosbags_for_every_jazzy_message(seed):
    serializer = CdrSerializer(TYPESTORE)
    for msgtype, msg, expected in every_message_with_rosbags_bytes(seed):
        assert serializer.serialize(msg) == expected, msgtype  # read through the slots
        assert serializer.function(msgtype)(msg) == expected, msgtype  # by the field names


def mcap_record(channel, t_ns, data):
    """Return the MCAP message record of ``data`` as rosbags' McapWriter writes it."""
    return struct.pack('<BQHIQQ', 0x05, 22 + len(data), channel, 0, t_ns, t_ns) + data


@pytest.mark.parametrize('seed', range(2))
def test_mcap_records_hold_rosbags_bytes_wherever_they_start_in_the_chunk(seed):
    """CDR alignment counts from the record's own payload, not from the shared buffer."""
    serializer = CdrSerializer(TYPESTORE)
    for msgtype, msg, expected in every_message_with_rosbags_bytes(seed):
        for slots in (True, False):
            write = serializer.function(msgtype, slots=slots, mcap_channel=7)
            for before in range(8):
                out = bytearray(b'\xaa' * before)
                write(msg, out, 10 ** 9 + before)
                assert out == b'\xaa' * before + mcap_record(7, 10 ** 9 + before, expected), \
                    (msgtype, slots, before)


def test_mcap_records_fall_back_to_field_names_and_a_failure_leaves_the_buffer_as_it_was():
    rng = random.Random(5)
    tf = random_message('tf2_msgs/msg/TFMessage', rng)
    tf.transforms = [random_message('geometry_msgs/msg/TransformStamped', rng) for _ in range(3)]
    expected = TYPESTORE.serialize_cdr(msg_to_rosbags(tf, TYPESTORE), 'tf2_msgs/msg/TFMessage')
    tf.transforms[2] = msg_to_rosbags(tf.transforms[2], TYPESTORE)  # read by field names
    serializer = CdrSerializer(TYPESTORE)
    out = bytearray(b'\xaa' * 3)
    serializer.function('tf2_msgs/msg/TFMessage', slots=True, mcap_channel=2)(tf, out, 5)
    assert out == b'\xaa' * 3 + mcap_record(2, 5, expected)
    bad = message_class('geometry_msgs/msg/PoseWithCovarianceStamped')()
    bad.header.frame_id = 'map'
    bad.pose.covariance = np.zeros(35)
    with pytest.raises(ValueError, match='covariance'):
        serializer.function('geometry_msgs/msg/PoseWithCovarianceStamped', slots=True,
                            mcap_channel=2)(bad, out, 6)
    assert out == b'\xaa' * 3 + mcap_record(2, 5, expected)


def test_runtime_messages_are_read_through_their_slots(monkeypatch):
    twist = message_class('geometry_msgs/msg/Twist')()
    twist.linear.x = 0.5
    monkeypatch.setattr(message_class('geometry_msgs/msg/Vector3'), 'x',
                        property(lambda vector: 1 / 0))
    assert CdrSerializer(TYPESTORE).serialize(twist) == TYPESTORE.serialize_cdr(
        TYPESTORE.types['geometry_msgs/msg/Twist'](
            linear=TYPESTORE.types['geometry_msgs/msg/Vector3'](x=0.5, y=0.0, z=0.0),
            angular=TYPESTORE.types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)),
        'geometry_msgs/msg/Twist')


def test_runtime_messages_holding_rosbags_sub_messages_serialise_by_field_names():
    rng = random.Random(4)
    odom = random_message('nav_msgs/msg/Odometry', rng)
    expected = TYPESTORE.serialize_cdr(msg_to_rosbags(odom, TYPESTORE), 'nav_msgs/msg/Odometry')
    odom.header = msg_to_rosbags(odom.header, TYPESTORE)
    tf = random_message('tf2_msgs/msg/TFMessage', rng)
    tf.transforms = [random_message('geometry_msgs/msg/TransformStamped', rng) for _ in range(3)]
    tf_expected = TYPESTORE.serialize_cdr(msg_to_rosbags(tf, TYPESTORE), 'tf2_msgs/msg/TFMessage')
    tf.transforms[1] = msg_to_rosbags(tf.transforms[1], TYPESTORE)
    serializer = CdrSerializer(TYPESTORE)
    assert serializer.serialize(odom) == expected
    assert serializer.serialize(tf) == tf_expected


def test_messages_starting_with_an_array_of_strings_or_messages_serialise_as_rosbags():
    """No Jazzy message starts so: the output then starts with the header alone, not a run."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg('string[2] names\nint32 count', 'test_msgs/msg/Names'))
    store.register(get_types_from_msg('geometry_msgs/Point[2] corners\nstring label',
                                      'test_msgs/msg/Corners'))
    point = store.types['geometry_msgs/msg/Point']
    for msg in (store.types['test_msgs/msg/Names'](names=['ab', 'cdé'], count=-7),
                store.types['test_msgs/msg/Corners'](
                    corners=[point(x=1.5, y=2.0, z=3.0), point(x=4.0, y=5.0, z=-6.0)],
                    label='x')):
        assert CdrSerializer(store).serialize(msg) == store.serialize_cdr(msg, msg.__msgtype__)


def test_rosbags_messages_serialise_as_they_are():
    msg = msg_to_rosbags(random_message('nav_msgs/msg/Odometry', random.Random(0)), TYPESTORE)
    assert CdrSerializer(TYPESTORE).serialize(msg) == TYPESTORE.serialize_cdr(
        msg, 'nav_msgs/msg/Odometry')


def test_bytes_above_127_serialise_as_the_same_octet_from_rosidl_or_rosbags():
    serializer = CdrSerializer(TYPESTORE)
    data = serializer.serialize(message_class('std_msgs/msg/Byte')(data=b'\x92'))
    assert data[4:] == b'\x92'
    as_rosbags = TYPESTORE.deserialize_cdr(bytes(data), 'std_msgs/msg/Byte')
    assert as_rosbags.data == -110
    assert serializer.serialize(as_rosbags) == data


def test_a_fixed_array_of_the_wrong_length_is_refused():
    msg = message_class('geometry_msgs/msg/PoseWithCovariance')()
    msg.covariance = np.zeros(35)
    with pytest.raises(ValueError, match='covariance: expected 36 items, got 35'):
        CdrSerializer(TYPESTORE).serialize(msg)


def test_type_names_come_from_the_message_class():
    assert ros_type_name(message_class('sensor_msgs/msg/LaserScan')()) == \
        'sensor_msgs/msg/LaserScan'
    assert ros_type_name(TYPESTORE.types['rosgraph_msgs/msg/Clock'](
        clock=TYPESTORE.types['builtin_interfaces/msg/Time'](sec=1, nanosec=2))) == \
        'rosgraph_msgs/msg/Clock'
    with pytest.raises(TypeError, match='not a ROS message class'):
        ros_type_name(3.0)


def stamp(t_ns):
    time = message_class('builtin_interfaces/msg/Time')()
    time.sec, time.nanosec = divmod(t_ns, 10 ** 9)
    return time


def run_messages(seconds=1.0):
    """Yield (topic, message, t_ns) as the bridge publishes them: 100 Hz clock, 10 Hz scan..."""
    transform = message_class('geometry_msgs/msg/TransformStamped')()
    transform.header.frame_id, transform.child_frame_id = 'base_link', 'laser'
    static = message_class('tf2_msgs/msg/TFMessage')(transforms=[transform])
    yield '/tf_static', static, 0
    for step in range(1, round(seconds * 100) + 1):
        t_ns = step * 10_000_000
        yield 'clock', message_class('rosgraph_msgs/msg/Clock')(clock=stamp(t_ns)), t_ns
        if step % 2 == 0:
            odom = message_class('nav_msgs/msg/Odometry')(child_frame_id='base_link')
            odom.header.stamp, odom.header.frame_id = stamp(t_ns), 'odom'
            odom.pose.pose.position.x = 0.003 * step
            yield '/odom', odom, t_ns
            moved = message_class('geometry_msgs/msg/TransformStamped')(child_frame_id='base_link')
            moved.header.stamp, moved.header.frame_id = stamp(t_ns), 'odom'
            moved.transform.translation.x = 0.003 * step
            yield '/tf', message_class('tf2_msgs/msg/TFMessage')(transforms=[moved]), t_ns
        if step % 10 == 0:
            scan = message_class('sensor_msgs/msg/LaserScan')(
                angle_min=-1.57, angle_max=1.57, angle_increment=3.14 / 35, range_min=0.12,
                range_max=10.0, ranges=[1.0 + 0.01 * step] * 35 + [math.inf])
            scan.header.stamp, scan.header.frame_id = stamp(t_ns), 'laser'
            yield '/scan', scan, t_ns
            twist = message_class('geometry_msgs/msg/Twist')()
            twist.linear.x, twist.angular.z = 0.3, -0.1 * step
            yield '/cmd_vel', twist, t_ns
            yield '/rosout', message_class('rcl_interfaces/msg/Log')(msg='not recorded'), t_ns


def read_bag(path):
    """Return {topic: [(t_ns, rosbags message)]} and the connections of a bag."""
    messages = {}
    with Reader(path) as reader:
        for connection, t_ns, data in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (t_ns, TYPESTORE.deserialize_cdr(data, connection.msgtype)))
        return messages, {connection.topic: connection for connection in reader.connections}


def test_recorded_bag_reads_back_with_counts_types_times_and_contents(tmp_path):
    with BagRecorder(tmp_path / 'run') as recorder:
        for topic, msg, t_ns in run_messages():
            recorder.write(topic, msg, t_ns)
        assert recorder.counts == {
            '/tf_static': 1, '/clock': 100, '/odom': 50, '/tf': 50, '/scan': 10, '/cmd_vel': 10}
    assert (tmp_path / 'run' / 'run.mcap').is_file()
    messages, connections = read_bag(tmp_path / 'run')
    assert {topic: len(entries) for topic, entries in messages.items()} == {
        '/tf_static': 1, '/clock': 100, '/odom': 50, '/tf': 50, '/scan': 10, '/cmd_vel': 10}
    assert recorder.counts == {topic: len(entries) for topic, entries in messages.items()}
    assert {topic: connection.msgtype for topic, connection in connections.items()} == {
        '/tf_static': 'tf2_msgs/msg/TFMessage', '/clock': 'rosgraph_msgs/msg/Clock',
        '/odom': 'nav_msgs/msg/Odometry', '/tf': 'tf2_msgs/msg/TFMessage',
        '/scan': 'sensor_msgs/msg/LaserScan', '/cmd_vel': 'geometry_msgs/msg/Twist'}
    clock_times = [t_ns for t_ns, _ in messages['/clock']]
    assert clock_times == [step * 10_000_000 for step in range(1, 101)]
    assert [msg.clock.sec * 10 ** 9 + msg.clock.nanosec
            for _, msg in messages['/clock']] == clock_times
    t_ns, scan = messages['/scan'][-1]
    assert t_ns == 10 ** 9 and scan.header.frame_id == 'laser'
    assert scan.ranges[:35] == pytest.approx(np.full(35, 2.0))
    assert scan.ranges[35] == math.inf
    assert scan.angle_increment == pytest.approx(3.14 / 35)
    assert messages['/odom'][-1][1].pose.pose.position.x == pytest.approx(0.3)
    assert messages['/tf'][0][1].transforms[0].child_frame_id == 'base_link'
    assert messages['/cmd_vel'][-1][1].angular.z == pytest.approx(-10.0)


def test_metadata_offers_qos_that_ros2_bag_play_can_use(tmp_path):
    with BagRecorder(tmp_path / 'run') as recorder:
        for topic, msg, t_ns in run_messages(0.1):
            recorder.write(topic, msg, t_ns)
    info = yaml.safe_load((tmp_path / 'run' / 'metadata.yaml').read_text())
    info = info['rosbag2_bagfile_information']
    assert info['version'] == BAG_VERSION and info['storage_identifier'] == 'mcap'
    profiles = {entry['topic_metadata']['name']: entry['topic_metadata']['offered_qos_profiles']
                for entry in info['topics_with_message_count']}
    assert profiles['/tf_static'][0]['durability'] == 'transient_local'
    assert profiles['/scan'][0]['durability'] == 'volatile'
    assert {profile[0]['reliability'] for profile in profiles.values()} == {'reliable'}
    _, connections = read_bag(tmp_path / 'run')
    static_qos = connections['/tf_static'].ext.offered_qos_profiles[0]
    assert static_qos.durability == QosDurability.TRANSIENT_LOCAL
    assert static_qos.reliability == QosReliability.RELIABLE


def test_a_run_failing_half_way_leaves_a_readable_bag(tmp_path):
    with pytest.raises(RuntimeError, match='node failed'):
        with BagRecorder(tmp_path / 'run') as recorder:
            for topic, msg, t_ns in run_messages(0.5):
                recorder.write(topic, msg, t_ns)
            raise RuntimeError('node failed')
    messages, _ = read_bag(tmp_path / 'run')
    assert len(messages['/clock']) == 50
    with pytest.raises(RuntimeError, match='closed'):
        recorder.write('/clock', message_class('rosgraph_msgs/msg/Clock')(), 0)
    recorder.close()


@pytest.mark.parametrize('t_ns', [-1, 1.5, np.int64(3), True])
def test_a_message_time_that_is_not_a_non_negative_int_is_refused_and_the_bag_kept(
        tmp_path, t_ns):
    clock = message_class('rosgraph_msgs/msg/Clock')()
    with BagRecorder(tmp_path / 'bag') as recorder:
        recorder.write('/clock', clock, 5)
        with pytest.raises(ValueError, match='non-negative int'):
            recorder.write('/clock', clock, t_ns)
    messages, _ = read_bag(tmp_path / 'bag')
    assert [t for t, _ in messages['/clock']] == [5]


def test_only_the_topics_asked_for_are_recorded(tmp_path):
    with BagRecorder(tmp_path / 'run', topics=['scan', '/cmd_vel']) as recorder:
        for topic, msg, t_ns in run_messages(0.5):
            recorder.write(topic, msg, t_ns)
    messages, _ = read_bag(tmp_path / 'run')
    assert {topic: len(entries) for topic, entries in messages.items()} == {
        '/scan': 5, '/cmd_vel': 5}


def write_with_rosbags(path, recorded, qos):
    """Write ``recorded`` as BagRecorder does but with rosbags' own Writer, the reference."""
    serializer = CdrSerializer(TYPESTORE)
    with Writer(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {}
        for topic, msg, t_ns in recorded:
            topic = '/' + topic.lstrip('/')
            if topic == '/rosout':
                continue
            if topic not in connections:
                connections[topic] = writer.add_connection(
                    topic, ros_type_name(msg), typestore=TYPESTORE,
                    offered_qos_profiles=[qos.get(topic, offered_qos())])
            writer.write(connections[topic], t_ns, serializer.serialize(msg))


def assert_same_bag(ours, reference):
    for name in ('run.mcap', 'metadata.yaml'):
        assert (ours / name).read_bytes() == (reference / name).read_bytes(), name


def test_lean_writer_writes_the_same_bytes_as_rosbags_writer(tmp_path):
    recorded = list(run_messages(0.3))
    with BagRecorder(tmp_path / 'ours' / 'run') as recorder:
        for topic, msg, t_ns in recorded:
            recorder.write(topic, msg, t_ns)
    write_with_rosbags(tmp_path / 'rosbags' / 'run', recorded, recorder.qos)
    assert_same_bag(tmp_path / 'ours' / 'run', tmp_path / 'rosbags' / 'run')


def test_bags_of_several_chunks_are_rosbags_bytes_and_read_back(tmp_path):
    """Chunks of 1 MiB close on the same message as rosbags'; a late topic joins a later one."""
    recorded = []
    for step in range(700):
        t_ns = step * 10_000_000
        recorded.append(('/clock', message_class('rosgraph_msgs/msg/Clock')(clock=stamp(t_ns)),
                         t_ns))
        scan = message_class('sensor_msgs/msg/LaserScan')(
            ranges=[0.01 * ((step + beam) % 997) for beam in range(1081)])
        scan.header.stamp, scan.header.frame_id = stamp(t_ns), 'laser'
        recorded.append(('/scan', scan, t_ns))
        if step >= 450 and step % 3 == 0:
            twist = message_class('geometry_msgs/msg/Twist')()
            twist.linear.x = 0.001 * step
            recorded.append(('/cmd_vel', twist, t_ns))
    with BagRecorder(tmp_path / 'ours' / 'run') as recorder:
        for topic, msg, t_ns in recorded:
            recorder.write(topic, msg, t_ns)
    write_with_rosbags(tmp_path / 'rosbags' / 'run', recorded, recorder.qos)
    assert_same_bag(tmp_path / 'ours' / 'run', tmp_path / 'rosbags' / 'run')
    mcap = McapReader(tmp_path / 'ours' / 'run' / 'run.mcap')
    mcap.open()
    assert len(mcap.chunks) >= 3
    mcap.close()
    with Reader(tmp_path / 'ours' / 'run') as reader:
        read = [(connection.topic, t_ns, data) for connection, t_ns, data in reader.messages()]
    assert read == [(topic, t_ns, CdrSerializer(TYPESTORE).serialize(msg))
                    for topic, msg, t_ns in recorded]


def test_a_message_failing_to_serialise_leaves_a_bag_as_rosbags_would(tmp_path):
    """Its new connection is written but not the message: here to a chunk without messages."""
    scan = message_class('sensor_msgs/msg/LaserScan')(ranges=np.ones(300_000))  # over 1 MiB
    bad = message_class('geometry_msgs/msg/PoseWithCovarianceStamped')()
    bad.pose.covariance = np.zeros(35)
    with pytest.raises(ValueError, match='covariance'):
        with BagRecorder(tmp_path / 'ours' / 'run', topics=['/scan', '/pose']) as recorder:
            recorder.write('/scan', scan, 7)
            recorder.write('/pose', bad, 8)
    with Writer(tmp_path / 'rosbags' / 'run', version=BAG_VERSION,
                storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(
            '/scan', 'sensor_msgs/msg/LaserScan', typestore=TYPESTORE,
            offered_qos_profiles=[offered_qos()])
        writer.write(connection, 7, CdrSerializer(TYPESTORE).serialize(scan))
        writer.add_connection('/pose', 'geometry_msgs/msg/PoseWithCovarianceStamped',
                              typestore=TYPESTORE, offered_qos_profiles=[offered_qos()])
    assert_same_bag(tmp_path / 'ours' / 'run', tmp_path / 'rosbags' / 'run')
    assert recorder.counts == {'/scan': 1, '/pose': 0}
    messages, _ = read_bag(tmp_path / 'ours' / 'run')
    assert [t_ns for t_ns, _ in messages['/scan']] == [7]


def test_a_topic_however_spelled_and_whatever_the_message_class_is_one_connection(tmp_path):
    clock = message_class('rosgraph_msgs/msg/Clock')(clock=stamp(5))
    with BagRecorder(tmp_path / 'run') as recorder:
        recorder.write('clock', clock, 1)
        recorder.write('/clock', clock, 2)
        recorder.write('/clock', msg_to_rosbags(clock, TYPESTORE), 3)
    messages, connections = read_bag(tmp_path / 'run')
    assert list(connections) == ['/clock']
    assert [(t_ns, msg.clock.nanosec) for t_ns, msg in messages['/clock']] == \
        [(1, 5), (2, 5), (3, 5)]
    assert recorder.counts == {'/clock': 3}


def test_an_old_bag_is_replaced_only_when_asked(tmp_path):
    for _ in range(2):
        with BagRecorder(tmp_path / 'run', overwrite=True) as recorder:
            recorder.write('/clock', message_class('rosgraph_msgs/msg/Clock')(), 5)
    assert len(read_bag(tmp_path / 'run')[0]['/clock']) == 1
    with pytest.raises(Exception, match='exists'):
        BagRecorder(tmp_path / 'run')
    (tmp_path / 'notes').mkdir()
    (tmp_path / 'notes' / 'thesis.tex').write_text('precious')
    with pytest.raises(FileExistsError, match='not a rosbag2 bag'):
        BagRecorder(tmp_path / 'notes', overwrite=True)
    assert (tmp_path / 'notes' / 'thesis.tex').read_text() == 'precious'
