"""
Recording: rclpy's CDR bytes go into a rosbag2 MCAP bag, padding zeroed, and read back intact.

Messages are real rclpy messages serialised by ``rclpy.serialization.serialize_message``, which
needs no rclpy context: nothing here starts DDS except the one test of a raw subscription,
which starts it in a context of its own with discovery off. Bags are read back with rosbags'
reader and deserialised with its ROS2_JAZZY type store, independently of the recorder. The
bytes stored are the ones given with their alignment padding zeroed (sim_bridge.runner.cdr_padding,
tested in test_cdr_padding.py): the same bytes for the same message, whatever Fast CDR left.
"""

import importlib
import json
import math
import os
from pathlib import Path
import random

from geometry_msgs.msg import Twist
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import serialize_message
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from sim_bridge.runner.cdr_padding import PaddingZeroer
from sim_bridge.runner.record import BAG_VERSION, BagRecorder, DEFAULT_TOPICS, message_type_name
from sim_bridge.runner.run import run_simulation
from std_msgs.msg import String
from std_srvs.srv import SetBool
import yaml

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
ZERO_PADDING = PaddingZeroer(TYPESTORE)
RUN_TOPICS = {'/tf_static': 1, '/clock': 100, '/odom': 50, '/tf': 50, '/scan': 10,
              '/cmd_vel': 10}
RUN_TYPES = {'/tf_static': 'tf2_msgs/msg/TFMessage', '/clock': 'rosgraph_msgs/msg/Clock',
             '/odom': 'nav_msgs/msg/Odometry', '/tf': 'tf2_msgs/msg/TFMessage',
             '/scan': 'sensor_msgs/msg/LaserScan', '/cmd_vel': 'geometry_msgs/msg/Twist'}
# A scan's last beams: no return, too close, invalid (REP-117).
SPECIAL_RANGES = [math.inf, -math.inf, math.nan]


def stamp_of(msg, t_ns):
    msg.sec, msg.nanosec = divmod(t_ns, 10 ** 9)


def tf_bytes(t_ns, parent, child, x):
    """
    Return the CDR bytes of a tf2_msgs/msg/TFMessage of one transform, x in m.

    tf2_msgs has no PyPI wheel, so rosbags serialises it here; on a ROS machine the bridge
    records rclpy's bytes of it like any other message.
    """
    types = TYPESTORE.types
    sec, nanosec = divmod(t_ns, 10 ** 9)
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec), frame_id=parent)
    transform = types['geometry_msgs/msg/Transform'](
        translation=types['geometry_msgs/msg/Vector3'](x=x, y=0.0, z=0.0),
        rotation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0))
    msg = types['tf2_msgs/msg/TFMessage'](transforms=[types['geometry_msgs/msg/TransformStamped'](
        header=header, child_frame_id=child, transform=transform)])
    return bytes(TYPESTORE.serialize_cdr(msg, 'tf2_msgs/msg/TFMessage'))


def scan_at(step, t_ns, beams=36):
    scan = LaserScan(angle_min=-1.57, angle_max=1.57, angle_increment=3.14 / (beams - 1),
                     time_increment=0.0, scan_time=0.1, range_min=0.12, range_max=10.0)
    stamp_of(scan.header.stamp, t_ns)
    scan.header.frame_id = 'laser'
    ranges = [0.3 + 0.01 * ((step + beam) % 900) for beam in range(beams)]
    scan.ranges = ranges[:-len(SPECIAL_RANGES)] + SPECIAL_RANGES
    scan.intensities = [float(beam % 7) for beam in range(beams)]
    return scan


def run_messages(seconds=1.0):
    """
    Return [(topic, rclpy message or None, type name, CDR bytes, t_ns)] as a run publishes them.

    Per simulated second: 100 /clock, 50 /odom and /tf, 10 /scan and /cmd_vel, one /rosout
    (not recorded by default); one /tf_static first. Each message is serialised once: rclpy's
    bytes are not deterministic in their padding, so the bytes kept are the ones to compare.
    """
    messages = [('/tf_static', None, 'tf2_msgs/msg/TFMessage',
                 tf_bytes(0, 'base_link', 'laser', 0.1), 0)]

    def add(topic, msg, t_ns):
        messages.append((topic, msg, message_type_name(msg), serialize_message(msg), t_ns))

    for step in range(1, round(seconds * 100) + 1):
        t_ns = step * 10_000_000
        clock = Clock()
        stamp_of(clock.clock, t_ns)
        add('clock' if step % 3 else '/clock', clock, t_ns)  # either spelling is /clock
        if step % 2 == 0:
            odom = Odometry(child_frame_id='base_link')
            stamp_of(odom.header.stamp, t_ns)
            odom.header.frame_id = 'odom'
            odom.pose.pose.position.x = 0.003 * step
            odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = 0.01 * step, 1.0
            odom.pose.covariance = np.arange(36, dtype=float) * 1e-3 * step
            odom.twist.twist.linear.x, odom.twist.twist.angular.z = 0.3, -0.02 * step
            add('/odom', odom, t_ns)
            messages.append(('/tf', None, 'tf2_msgs/msg/TFMessage',
                             tf_bytes(t_ns, 'odom', 'base_link', 0.003 * step), t_ns))
        if step % 10 == 0:
            add('/scan', scan_at(step, t_ns), t_ns)
            twist = Twist()
            twist.linear.x, twist.angular.z = 0.3, -0.1 * step
            add('/cmd_vel', twist, t_ns)
        if step % 50 == 0:
            add('/rosout_like', Twist(), t_ns)
    return messages


def record(path, messages, **options):
    with BagRecorder(path, **options) as recorder:
        for topic, _, type_name, data, t_ns in messages:
            recorder.write(topic, type_name, data, t_ns)
    return recorder


def read_bag(path):
    """Return [(topic, type name, t_ns, CDR bytes)] of a bag in storage order, and its info."""
    with Reader(path) as reader:
        read = [(connection.topic, connection.msgtype, t_ns, bytes(data))
                for connection, t_ns, data in reader.messages()]
        return read, {connection.topic: connection for connection in reader.connections}


def base_type(field_type):
    """Return the element type of an rclpy field type: 'float' of 'sequence<float>', say."""
    return field_type.removeprefix('sequence<').split('>')[0].split('[')[0]


def assert_same_message(read, sent, where='msg'):
    """
    Assert a rosbags message read back holds the field values of the rclpy message ``sent``.

    float32 fields are compared after rounding the sent values to float32, as CDR carries
    them; NaN equals NaN.
    """
    for name, field_type in sent.get_fields_and_field_types().items():
        expected, actual, path = getattr(sent, name), getattr(read, name), f'{where}.{name}'
        if hasattr(expected, 'get_fields_and_field_types'):
            assert_same_message(actual, expected, path)
        elif base_type(field_type) == 'string':
            assert actual == expected, path
        else:
            dtype = np.float32 if base_type(field_type) == 'float' else None
            np.testing.assert_array_equal(np.asarray(actual, dtype=dtype),
                                          np.asarray(expected, dtype=dtype), err_msg=path)


def assert_only_zeroed(stored, given):
    """Assert the bytes ``stored`` are the bytes ``given``, some of them set to zero."""
    assert len(stored) == len(given)
    changed = [index for index, (byte, original) in enumerate(zip(stored, given))
               if byte != original]
    assert all(stored[index] == 0 for index in changed), changed


def test_the_message_comparison_sees_a_changed_field_or_beam():
    scan = scan_at(3, 5)
    read = TYPESTORE.deserialize_cdr(serialize_message(scan), 'sensor_msgs/msg/LaserScan')
    assert_same_message(read, scan)
    for change in ('ranges', 'header'):
        other = scan_at(3, 5)
        if change == 'ranges':
            other.ranges[-1] = 1.0  # NaN no more
        else:
            other.header.frame_id = 'base_link'
        with pytest.raises(AssertionError, match=change):
            assert_same_message(read, other)


def test_a_run_reads_back_with_counts_types_times_bytes_and_contents(tmp_path):
    messages = run_messages()
    recorder = record(tmp_path / 'run', messages)
    assert recorder.counts == RUN_TOPICS
    assert recorder.mcap_path == tmp_path / 'run' / 'run.mcap' and recorder.mcap_path.is_file()
    read, connections = read_bag(tmp_path / 'run')
    recorded = [message for message in messages if message[0] != '/rosout_like']
    # The bag holds the bytes rclpy (or rosbags, for TF) gave, in order, at their times, with
    # only their padding zeroed: each byte stored is the one given or a zero.
    assert read == [('/' + topic.lstrip('/'), type_name, t_ns, ZERO_PADDING(type_name, data))
                    for topic, _, type_name, data, t_ns in recorded]
    for (_, _, _, data, _), (_, _, _, stored) in zip(recorded, read):
        assert_only_zeroed(stored, data)
    assert {topic: connection.msgtype for topic, connection in connections.items()} == RUN_TYPES
    for (topic, msg, type_name, _, _), (_, _, t_ns, data) in zip(recorded, read):
        if msg is not None:
            assert_same_message(TYPESTORE.deserialize_cdr(data, type_name), msg, topic)
    clock_times = [t_ns for topic, _, t_ns, _ in read if topic == '/clock']
    assert clock_times == [step * 10_000_000 for step in range(1, 101)]
    scans = [TYPESTORE.deserialize_cdr(data, 'sensor_msgs/msg/LaserScan')
             for topic, _, _, data in read if topic == '/scan']
    assert scans[-1].header.stamp.sec == 1 and scans[-1].header.stamp.nanosec == 0
    assert scans[-1].ranges[-3] == math.inf and scans[-1].ranges[-2] == -math.inf
    assert math.isnan(scans[-1].ranges[-1])
    assert scans[-1].ranges[0] == np.float32(0.3 + 0.01 * 100)
    transforms = [TYPESTORE.deserialize_cdr(data, 'tf2_msgs/msg/TFMessage').transforms[0]
                  for topic, _, _, data in read if topic == '/tf']
    assert transforms[-1].child_frame_id == 'base_link'
    assert transforms[-1].transform.translation.x == pytest.approx(0.3)


def test_the_same_run_recorded_twice_gives_the_same_bag_byte_for_byte(tmp_path):
    """
    Even when Fast CDR leaves other garbage in the padding of the bytes it gives the second time.

    Serialising a string of random letters, about as long as the message, before each message
    leaves those letters where Fast CDR allocates next.
    """
    first = run_messages()
    rng = random.Random(3)
    second = []
    for topic, msg, type_name, data, t_ns in first:
        if msg is not None:
            serialize_message(String(data=''.join(
                rng.choice('abcdefghijklmnopqrstuvwxyz') for _ in range(len(data)))))
            data = serialize_message(msg)
        second.append((topic, msg, type_name, data, t_ns))
    assert any(message[3] != again[3] for message, again in zip(first, second))
    bags = []
    for messages in (first, second):
        record(tmp_path / 'run', messages, overwrite=True)
        bags.append([(tmp_path / 'run' / name).read_bytes()
                     for name in ('run.mcap', 'metadata.yaml')])
    assert bags[0] == bags[1]


def type_hash_of(type_name):
    """Return the RIHS01 type hash rosidl generated for an installed message type, or None."""
    package = type_name.split('/')[0]
    # <prefix>/lib/pythonX.Y/site-packages/<package>/msg/__init__.py
    prefixes = [Path(importlib.import_module(f'{package}.msg').__file__).parents[5]]
    prefixes += [Path(entry) for entry in os.environ.get('AMENT_PREFIX_PATH', '').split(':')
                 if entry]
    for prefix in prefixes:
        description = prefix / 'share' / f'{type_name}.json'
        if description.is_file():
            hashes = json.loads(description.read_text())['type_hashes']
            return next(entry['hash_string'] for entry in hashes
                        if entry['type_name'] == type_name)
    return None


def test_connections_carry_the_type_hashes_of_the_installed_message_packages(tmp_path):
    """``ros2 bag play`` on Jazzy checks them against the types it publishes."""
    record(tmp_path / 'run', run_messages(0.1))
    info = yaml.safe_load((tmp_path / 'run' / 'metadata.yaml').read_text())
    hashes = {entry['topic_metadata']['type']: entry['topic_metadata']['type_description_hash']
              for entry in info['rosbag2_bagfile_information']['topics_with_message_count']}
    installed = {type_name: type_hash_of(type_name) for type_name in hashes
                 if not type_name.startswith('tf2_msgs/')}
    if None in installed.values():
        pytest.skip('no rosidl type descriptions (share/<package>/msg/*.json) found')
    assert len(installed) == 4
    assert installed == {type_name: hashes[type_name] for type_name in installed}
    assert all(value.startswith('RIHS01_') for value in hashes.values())


def test_the_independent_mcap_readers_decode_every_message_of_a_bag_as_jazzy_writes_it(
        tmp_path):
    """
    Foxglove's ``mcap`` and ``mcap-ros2-support``: every message decodes from the bag's schemas.

    As Jazzy's rosbag2_storage_mcap writes them, each channel's metadata holds the type hash
    (``topic_type_hash``, read back by ``ros2 bag info`` as the topic's type_description_hash)
    beside the offered QoS, and both copies of the rosbag2 metadata (``metadata.yaml`` and the
    MCAP's ``rosbag2`` record) name the distribution, ``jazzy``.
    """
    messages = run_messages(0.2)
    record(tmp_path / 'run', messages)
    info = yaml.safe_load((tmp_path / 'run' / 'metadata.yaml').read_text())
    info = info['rosbag2_bagfile_information']
    assert info['ros_distro'] == 'jazzy'
    hashes = {entry['topic_metadata']['name']: entry['topic_metadata']['type_description_hash']
              for entry in info['topics_with_message_count']}
    with (tmp_path / 'run' / 'run.mcap').open('rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        decoded = [(channel.topic, message.log_time, ros_msg)
                   for _, channel, message, ros_msg in reader.iter_decoded_messages()]
        summary = reader.get_summary()
        (rosbag2,) = [entry for entry in reader.iter_metadata() if entry.name == 'rosbag2']
    recorded = [message for message in messages if message[0] != '/rosout_like']
    assert [(topic, t_ns) for topic, t_ns, _ in decoded] == \
        [('/' + topic.lstrip('/'), t_ns) for topic, _, _, _, t_ns in recorded]
    for (topic, _, ros_msg), (_, msg, _, _, _) in zip(decoded, recorded):
        if topic in ('/scan', '/odom', '/cmd_vel'):
            assert_same_message(ros_msg, msg, topic)
    for channel in summary.channels.values():
        assert set(channel.metadata) == {'offered_qos_profiles', 'topic_type_hash'}
        assert channel.metadata['topic_type_hash'] == hashes[channel.topic]
        assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
    assert yaml.safe_load(rosbag2.metadata['serialized_metadata'])['ros_distro'] == 'jazzy'
    with Reader(tmp_path / 'run') as reader:
        assert reader.ros_distro == 'jazzy'


def test_the_sim_clock_has_one_message_at_each_recorded_time_before_the_messages(tmp_path):
    """Times with no /clock given get one; a /clock given at a time that has one is dropped."""
    twist, odom = serialize_message(Twist()), serialize_message(Odometry())

    def clock_at(t_ns):
        clock = Clock()
        stamp_of(clock.clock, t_ns)
        return serialize_message(clock)

    with BagRecorder(tmp_path / 'run', sim_clock=True) as recorder:
        recorder.write('/odom', 'nav_msgs/msg/Odometry', odom, 0)
        recorder.write('/clock', 'rosgraph_msgs/msg/Clock', clock_at(0), 0)
        recorder.write('/odom', 'nav_msgs/msg/Odometry', odom, 20)
        recorder.write('/cmd_vel', 'geometry_msgs/msg/Twist', twist, 20)
        recorder.write('clock', 'rosgraph_msgs/msg/Clock', clock_at(35), 35)
        recorder.write('/cmd_vel', 'geometry_msgs/msg/Twist', twist, 35)
        recorder.write('/parameter_events', 'geometry_msgs/msg/Twist', twist, 50)  # not kept
    read, _ = read_bag(tmp_path / 'run')
    assert [(topic, t_ns) for topic, _, t_ns, _ in read] == [
        ('/clock', 0), ('/odom', 0), ('/clock', 20), ('/odom', 20), ('/cmd_vel', 20),
        ('/clock', 35), ('/cmd_vel', 35)]
    for topic, type_name, t_ns, data in read:
        if topic == '/clock':
            clock = TYPESTORE.deserialize_cdr(data, type_name).clock
            assert clock.sec * 10 ** 9 + clock.nanosec == t_ns


def test_a_stepped_runs_bag_has_its_clock_at_every_message_so_a_replay_never_lags(tmp_path):
    """
    The run sends /clock only with what a node hears; the bag has it at every message's time.

    wall_follow hears /scan only, so the run sends /clock with the 10 Hz scans and not with
    the 50 Hz odometry.
    """
    run_simulation('wall_follow_box', ['wall_follow'], duration_s=1.0, seed=1,
                   out_dir=tmp_path, quiet=True, plot=False)
    read, _ = read_bag(tmp_path / 'run')
    clock_ns, lagging = -1, []
    for topic, type_name, t_ns, data in read:
        if topic == '/clock':
            clock = TYPESTORE.deserialize_cdr(data, type_name).clock
            assert clock.sec * 10 ** 9 + clock.nanosec == t_ns > clock_ns
            clock_ns = t_ns
        elif t_ns != clock_ns:
            lagging.append((topic, t_ns, clock_ns))
    assert not lagging
    odom_times = [t_ns for topic, _, t_ns, _ in read if topic == '/odom']
    assert len(odom_times) == 50


def test_metadata_has_the_counts_times_and_qos_that_ros2_bag_play_uses(tmp_path):
    record(tmp_path / 'run', run_messages(0.5))
    info = yaml.safe_load((tmp_path / 'run' / 'metadata.yaml').read_text())
    info = info['rosbag2_bagfile_information']
    assert info['version'] == BAG_VERSION == 9 and info['storage_identifier'] == 'mcap'
    assert info['relative_file_paths'] == ['run.mcap']
    assert info['starting_time']['nanoseconds_since_epoch'] == 0
    assert info['duration']['nanoseconds'] == 500_000_000
    assert info['message_count'] == 1 + 50 + 25 + 25 + 5 + 5
    topics = {entry['topic_metadata']['name']: entry
              for entry in info['topics_with_message_count']}
    assert {name: entry['message_count'] for name, entry in topics.items()} == {
        '/tf_static': 1, '/clock': 50, '/odom': 25, '/tf': 25, '/scan': 5, '/cmd_vel': 5}
    profiles = {name: entry['topic_metadata']['offered_qos_profiles']
                for name, entry in topics.items()}
    assert profiles['/tf_static'][0]['durability'] == 'transient_local'
    assert {profile[0]['durability'] for name, profile in profiles.items()
            if name != '/tf_static'} == {'volatile'}
    assert {profile[0]['reliability'] for profile in profiles.values()} == {'reliable'}
    _, connections = read_bag(tmp_path / 'run')
    static_qos = connections['/tf_static'].ext.offered_qos_profiles[0]
    assert static_qos.durability == QosDurability.TRANSIENT_LOCAL
    assert static_qos.reliability == QosReliability.RELIABLE
    assert connections['/scan'].ext.offered_qos_profiles[0].durability == \
        QosDurability.VOLATILE


def test_only_the_topics_asked_for_are_recorded(tmp_path):
    assert '/rosout_like' not in DEFAULT_TOPICS
    recorder = record(tmp_path / 'run', run_messages(0.5), topics=['scan', '/cmd_vel'])
    assert recorder.topics == {'/scan', '/cmd_vel'}
    assert recorder.counts == {'/scan': 5, '/cmd_vel': 5}
    read, connections = read_bag(tmp_path / 'run')
    assert sorted(connections) == ['/cmd_vel', '/scan']
    assert [topic for topic, _, _, _ in read] == ['/scan', '/cmd_vel'] * 5


def test_a_topic_not_recorded_is_ignored_whatever_its_type(tmp_path):
    with BagRecorder(tmp_path / 'run') as recorder:
        recorder.write('/parameter_events', 'no_such_pkg/msg/Nothing', b'not cdr', 5)
        with pytest.raises(ValueError, match=r"'no_such_pkg/msg/Nothing' on /odom"):
            recorder.write('/odom', 'no_such_pkg/msg/Nothing', b'not cdr', 5)
        recorder.write('/clock', 'rosgraph_msgs/msg/Clock', serialize_message(Clock()), 6)
    assert recorder.counts == {'/clock': 1}
    assert [topic for topic, _, _, _ in read_bag(tmp_path / 'run')[0]] == ['/clock']


def test_one_topic_with_two_types_gets_a_connection_per_type(tmp_path):
    """As rosbag2 records a topic whose publishers disagree."""
    twist = serialize_message(Twist())
    clock = serialize_message(Clock())
    with BagRecorder(tmp_path / 'run') as recorder:
        for t_ns, (type_name, data) in enumerate([('geometry_msgs/msg/Twist', twist),
                                                  ('rosgraph_msgs/msg/Clock', clock),
                                                  ('geometry_msgs/msg/Twist', twist)]):
            recorder.write('cmd_vel', type_name, data, t_ns)
    assert recorder.counts == {'/cmd_vel': 3}
    read, _ = read_bag(tmp_path / 'run')
    assert [(type_name, t_ns) for _, type_name, t_ns, _ in read] == [
        ('geometry_msgs/msg/Twist', 0), ('rosgraph_msgs/msg/Clock', 1),
        ('geometry_msgs/msg/Twist', 2)]


@pytest.mark.parametrize('t_ns', [-1, 1.5, np.int64(3), True, None])
def test_a_message_time_that_is_not_a_non_negative_int_is_refused_and_the_bag_kept(
        tmp_path, t_ns):
    clock = serialize_message(Clock())
    with BagRecorder(tmp_path / 'bag') as recorder:
        recorder.write('/clock', 'rosgraph_msgs/msg/Clock', clock, 5)
        with pytest.raises(ValueError, match=r'bag .*bag: .*non-negative int.* on /clock'):
            recorder.write('/clock', 'rosgraph_msgs/msg/Clock', clock, t_ns)
        recorder.write('/clock', 'rosgraph_msgs/msg/Clock', clock, 6)
    read, _ = read_bag(tmp_path / 'bag')
    assert [t_ns for _, _, t_ns, _ in read] == [5, 6]


def test_a_closed_bag_refuses_messages_and_closes_twice(tmp_path):
    recorder = BagRecorder(tmp_path / 'run')
    assert not recorder.closed
    recorder.write('/clock', 'rosgraph_msgs/msg/Clock', serialize_message(Clock()), 1)
    recorder.close()
    assert recorder.closed
    for topic in ('/clock', '/not_recorded'):
        with pytest.raises(RuntimeError, match='closed'):
            recorder.write(topic, 'rosgraph_msgs/msg/Clock', serialize_message(Clock()), 2)
    recorder.close()
    assert recorder.counts == {'/clock': 1}
    assert [t_ns for _, _, t_ns, _ in read_bag(tmp_path / 'run')[0]] == [1]


def test_a_run_failing_half_way_leaves_a_readable_bag(tmp_path):
    messages = run_messages(0.5)
    with pytest.raises(RuntimeError, match='node failed'):
        with BagRecorder(tmp_path / 'run') as recorder:
            for topic, _, type_name, data, t_ns in messages:
                recorder.write(topic, type_name, data, t_ns)
                if t_ns == 300_000_000 and topic == '/cmd_vel':
                    raise RuntimeError('node failed')
    assert recorder.closed
    read, _ = read_bag(tmp_path / 'run')
    assert sum(topic == '/clock' for topic, _, _, _ in read) == 30
    assert read[-1][:3] == ('/cmd_vel', 'geometry_msgs/msg/Twist', 300_000_000)


def test_a_bag_closed_while_the_run_goes_on_is_readable_and_complete(tmp_path):
    """The grader's timeout, say: the run is stopped from outside and the bag closed."""
    messages = run_messages(0.5)
    recorder = BagRecorder(tmp_path / 'run')
    refused = 0
    for index, (topic, _, type_name, data, t_ns) in enumerate(messages):
        if index == 40:
            recorder.close()
        try:
            recorder.write(topic, type_name, data, t_ns)
        except RuntimeError:
            refused += 1
    assert refused == len(messages) - 40
    read, _ = read_bag(tmp_path / 'run')
    assert [data for _, _, _, data in read] == [ZERO_PADDING(type_name, data)
                                                for _, _, type_name, data, _ in messages[:40]]
    for (topic, msg, type_name, _, _), (_, _, _, data) in zip(messages, read):
        if msg is not None:
            assert_same_message(TYPESTORE.deserialize_cdr(data, type_name), msg, topic)


def test_large_scans_spanning_several_mcap_chunks_read_back_in_order(tmp_path):
    messages = []
    for step in range(400):  # about 4.4 kB a scan: rosbags closes a chunk past 1 MiB
        t_ns = step * 100_000_000
        scan = scan_at(step, t_ns, beams=1081)
        messages.append(('/scan', scan, 'sensor_msgs/msg/LaserScan', serialize_message(scan),
                         t_ns))
    recorder = record(tmp_path / 'run', messages)
    assert recorder.counts == {'/scan': 400}
    assert recorder.mcap_path.stat().st_size > 1.5 * 2 ** 20
    read, _ = read_bag(tmp_path / 'run')
    assert [(t_ns, data) for _, _, t_ns, data in read] == \
        [(t_ns, ZERO_PADDING(type_name, data)) for _, _, type_name, data, t_ns in messages]
    assert_same_message(TYPESTORE.deserialize_cdr(read[-1][3], 'sensor_msgs/msg/LaserScan'),
                        messages[-1][1])


def test_an_old_bag_is_replaced_only_when_asked(tmp_path):
    clock = serialize_message(Clock())
    for t_ns in (5, 7):
        with BagRecorder(tmp_path / 'run', overwrite=True) as recorder:
            recorder.write('/clock', 'rosgraph_msgs/msg/Clock', clock, t_ns)
    assert [t_ns for _, _, t_ns, _ in read_bag(tmp_path / 'run')[0]] == [7]
    with pytest.raises(Exception, match='exists'):
        BagRecorder(tmp_path / 'run')
    assert [t_ns for _, _, t_ns, _ in read_bag(tmp_path / 'run')[0]] == [7]
    (tmp_path / 'notes').mkdir()
    (tmp_path / 'notes' / 'thesis.tex').write_text('precious')
    (tmp_path / 'notes.mcap').write_text('not a folder')
    (tmp_path / 'like_a_bag' / 'like_a_bag.mcap').mkdir(parents=True)  # a folder in it
    (tmp_path / 'like_a_bag' / 'metadata.yaml').write_text('{}')
    (tmp_path / 'like_a_bag' / 'like_a_bag.mcap' / 'thesis.tex').write_text('precious')
    for path in (tmp_path / 'notes', tmp_path / 'notes.mcap', tmp_path / 'like_a_bag'):
        with pytest.raises(FileExistsError, match='not a rosbag2 bag'):
            BagRecorder(path, overwrite=True)
    assert (tmp_path / 'notes' / 'thesis.tex').read_text() == 'precious'
    assert (tmp_path / 'notes.mcap').read_text() == 'not a folder'
    assert (tmp_path / 'like_a_bag' / 'like_a_bag.mcap' / 'thesis.tex').is_file()
    with BagRecorder(tmp_path / 'new' / 'run', overwrite=True) as recorder:
        pass
    assert recorder.counts == {} and read_bag(tmp_path / 'new' / 'run')[0] == []


def test_type_names_come_from_rclpy_message_classes_and_instances():
    assert message_type_name(LaserScan) == message_type_name(LaserScan()) == \
        'sensor_msgs/msg/LaserScan'
    assert message_type_name(Odometry()) == 'nav_msgs/msg/Odometry'
    assert message_type_name(Clock) == 'rosgraph_msgs/msg/Clock'
    assert message_type_name(SetBool.Request()) == 'std_srvs/srv/SetBool_Request'

    class Imitation:  # a look-alike without rosidl's metaclass
        pass

    Imitation.__module__ = 'sensor_msgs.msg._laser_scan'
    for not_a_message in (3.0, Imitation, Imitation(), TYPESTORE.types['std_msgs/msg/String']):
        with pytest.raises(TypeError, match='not a generated ROS 2 message class'):
            message_type_name(not_a_message)


def test_the_bytes_a_raw_subscription_delivers_are_recorded(tmp_path, monkeypatch):
    """Real DDS in a context of its own, discovery off: what a raw recorder node would get."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'OFF')
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('raw_recorder_test', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        received = []
        node.create_subscription(LaserScan, 'scan', received.append, 10, raw=True)
        publisher = node.create_publisher(LaserScan, 'scan', 10)
        sent = [scan_at(step, step * 100_000_000) for step in range(3)]
        for scan in sent:
            publisher.publish(scan)
            for _ in range(200):
                if len(received) == sent.index(scan) + 1:
                    break
                executor.spin_once(timeout_sec=0.01)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    assert len(received) == 3 and all(isinstance(data, bytes) for data in received)
    with BagRecorder(tmp_path / 'run') as recorder:
        for step, data in enumerate(received):
            recorder.write('/scan', message_type_name(LaserScan), data, step * 100_000_000)
    read, _ = read_bag(tmp_path / 'run')
    assert [data for _, _, _, data in read] == \
        [ZERO_PADDING('sensor_msgs/msg/LaserScan', data) for data in received]
    for (_, _, _, data), scan in zip(read, sent):
        assert_same_message(TYPESTORE.deserialize_cdr(data, 'sensor_msgs/msg/LaserScan'), scan)
