"""
A run's bag holds what Jazzy's own ``ros2 bag record`` would: the installed packages' types.

Each MCAP schema and hash is compared with what the installed message packages hold, found
independently of the recorder: the ``.msg`` files in each package's share folder, the
dependencies from rclpy's classes (rosidl's ``SLOT_TYPES``), the hash that rmw computes for a
publisher of the type (the ROS graph's ``topic_type_hash``). A recording cut by ``kill -9``
keeps what reached its file and is closed by ``python -m sim_bridge.commands.record
recover``.
"""

import os
from pathlib import Path
import subprocess
import sys
import textwrap

from mcap.reader import make_reader
import pytest
from rosbags.rosbag2 import Reader
from rosidl_parser import definition
from sim_bridge.common.message_types import message_class
from sim_bridge.runner.run import run_simulation
import yaml

SEPARATOR = '\n' + '=' * 80 + '\n'
INFINITE = {'sec': 9223372036, 'nsec': 854775807}


def installed_msg_file(type_name):
    """Return the text of the installed ``.msg`` file of ``pkg/msg/Name`` (or ``pkg/Name``)."""
    package, *_, name = type_name.split('/')
    prefixes = [entry for entry in os.environ.get('AMENT_PREFIX_PATH', '').split(':') if entry]
    for prefix in prefixes + [sys.prefix]:
        path = Path(prefix) / 'share' / package / 'msg' / f'{name}.msg'
        if path.is_file():
            return path.read_text()
    raise AssertionError(f'no installed {package}/msg/{name}.msg')


def dependencies(type_name):
    """Return every message type ``type_name`` uses, from rclpy's classes (pkg/msg/Name)."""
    found, todo = set(), [message_class(type_name)]
    while todo:
        for slot_type in todo.pop().SLOT_TYPES:
            element = getattr(slot_type, 'value_type', slot_type)
            if isinstance(element, definition.NamespacedType):
                name = '/'.join([*element.namespaces, element.name])
                if name not in found:
                    found.add(name)
                    todo.append(message_class(name))
    return found


def graph_hashes(type_names):
    """Return the RIHS01 hash rmw gives a publisher of each type (ROS graph, discovery off)."""
    import rclpy
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('hash_test', context=context)
        hashes = {}
        for index, type_name in enumerate(sorted(type_names)):
            node.create_publisher(message_class(type_name), f'/hash_{index}', 1)
            (info,) = node.get_publishers_info_by_topic(f'/hash_{index}')
            hashes[type_name] = str(info.topic_type_hash)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    return hashes


@pytest.fixture(scope='module')
def run_bag(tmp_path_factory):
    """Return the bag folder of a 1 s stepped run of wall_follow (it logs)."""
    out_dir = tmp_path_factory.mktemp('run')
    result = run_simulation('wall_follow_box', ['wall_follow'], duration_s=1.0, seed=1,
                            out_dir=out_dir, quiet=True, plot=False)
    assert result.ok
    return out_dir / 'run'


def test_schemas_and_hashes_are_the_installed_packages_own(run_bag):
    info = yaml.safe_load((run_bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    topics = {entry['topic_metadata']['name']: entry['topic_metadata']
              for entry in info['topics_with_message_count']}
    with (run_bag / info['relative_file_paths'][0]).open('rb') as stream:
        summary = make_reader(stream).get_summary()
    channels = {channel.topic: channel for channel in summary.channels.values()}
    assert set(channels) == set(topics) >= {'/scan', '/odom', '/clock', '/cmd_vel', '/rosout'}
    expected_hashes = graph_hashes({topic['type'] for topic in topics.values()})
    for name, topic in topics.items():
        channel, schema = channels[name], summary.schemas[channels[name].schema_id]
        assert (schema.name, schema.encoding) == (topic['type'], 'ros2msg')
        own, *sections = schema.data.decode().split(SEPARATOR)
        assert own == installed_msg_file(topic['type']), name
        included = {}
        for section in sections:
            header, _, text = section.partition('\n')
            assert header.startswith('MSG: ')
            included[header[5:]] = text
            assert text == installed_msg_file(header[5:]), header
        assert {type_name.replace('/msg/', '/') for type_name in dependencies(topic['type'])} \
            == set(included), name
        assert topic['type_description_hash'] == channel.metadata['topic_type_hash'] == \
            expected_hashes[topic['type']], name


def test_the_qos_is_what_the_publishers_offered_with_jazzy_s_infinite(run_bag):
    info = yaml.safe_load((run_bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    profiles = {entry['topic_metadata']['name']: entry['topic_metadata']['offered_qos_profiles']
                for entry in info['topics_with_message_count']}
    assert profiles['/scan'] == [{
        'history': 'unknown', 'depth': 0, 'reliability': 'reliable', 'durability': 'volatile',
        'deadline': INFINITE, 'lifespan': INFINITE, 'liveliness': 'automatic',
        'liveliness_lease_duration': INFINITE, 'avoid_ros_namespace_conventions': False}]
    # rcl's /rosout publishers (one per node of the run): latched, messages live 10 s.
    assert profiles['/rosout'] and all(
        (profile['durability'], profile['lifespan']) == ('transient_local',
                                                         {'sec': 10, 'nsec': 0})
        for profile in profiles['/rosout'])
    with Reader(run_bag) as reader:
        assert reader.ros_distro == 'jazzy'
        assert {connection.topic for connection in reader.connections} == set(profiles)


KILLED_RECORDING = textwrap.dedent("""
    import os, signal, sys
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import LaserScan
    from sim_bridge.runner.record import BagRecorder
    bag = BagRecorder(sys.argv[1])
    for step in range(2000):
        scan = LaserScan(ranges=[float(step)] * 360)
        bag.write('/scan', 'sensor_msgs/msg/LaserScan', serialize_message(scan), step)
    os.kill(os.getpid(), signal.SIGKILL)
""")


def test_a_recording_killed_keeps_what_reached_its_file_and_recover_closes_it(tmp_path):
    bag = tmp_path / 'cut'
    killed = subprocess.run([sys.executable, '-c', KILLED_RECORDING, str(bag)])
    assert killed.returncode == -9
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['cut_0.mcap'] and (bag / 'cut_0.mcap').is_file()
    recovered = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.commands.record', 'recover', str(bag)],
        capture_output=True, text=True)
    assert recovered.returncode == 0, recovered.stderr
    with Reader(bag) as reader:
        times = [t_ns for _, t_ns, _ in reader.messages()]
        assert reader.message_count == len(times)
    # Every chunk that reached the file is kept: most of the 2000 scans, in order, from 0.
    assert 1500 < len(times) < 2000 and times == list(range(len(times)))
    assert recovered.stdout.strip() == f'{bag}: /scan {len(times)}'
