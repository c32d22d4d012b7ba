"""
Benchmark recording: microseconds per message written to a rosbag2 MCAP bag.

Rows per message as the bridge and a node publish them (real rclpy messages), and for the mix
of a run: per simulated second 100 /clock, 50 /odom, 10 /scan (36 beams), 10 /cmd_vel. Columns:
* ``serialise``: ``rclpy.serialization.serialize_message`` (what a raw subscription delivers
  without it: the bytes of the publish);
* ``write``: ``BagRecorder.write`` of those bytes into an open bag;
* ``ser.+write``: both, per message;
* ``naive``: ``serialize_message`` then rosbags' ``Writer.write`` on a connection looked up by
  topic, the plain use of rosbags the recorder wraps (no QoS profiles, no time check).
Writes go to a fresh bag of ``COUNT`` messages per figure, opening and closing it not timed.
The last lines give a bag's own cost (open, one message per topic, close: mostly rosbags' YAML
for ``metadata.yaml``) and extrapolate the mix to a 600 s run.

Run: python test/bench/bench_record.py [--quick]
"""

import math
from pathlib import Path
import sys
import tempfile
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from sim_bridge.runner.record import BAG_VERSION, BagRecorder, message_type_name
from timing import microseconds_per_call

REPEATS = 3
COUNT = 2000 if '--quick' in sys.argv else 10000
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
# Messages per simulated second at the bridge's default rates (physics 100 Hz, odom 50 Hz,
# lidar 10 Hz, one command per scan). No /tf: tf2_msgs is not on PyPI.
RUN_MIX = {'/clock': 100, '/odom': 50, '/scan': 10, '/cmd_vel': 10}
RUN_SECONDS = 600


def stamp(time_msg, t_ns):
    time_msg.sec, time_msg.nanosec = divmod(t_ns, 10 ** 9)


def sample_messages(beams):
    """Return {topic: rclpy message} shaped as the bridge and a node publish them."""
    t_ns = 12_340_000_000
    clock = Clock()
    stamp(clock.clock, t_ns)
    odom = Odometry(child_frame_id='base_link')
    stamp(odom.header.stamp, t_ns)
    odom.header.frame_id = 'odom'
    odom.pose.pose.position.x, odom.pose.pose.orientation.w = 1.25, 1.0
    scan = LaserScan(angle_min=-1.57, angle_max=1.57, angle_increment=3.14 / (beams - 1),
                     range_min=0.12, range_max=10.0,
                     ranges=[1.0 + 0.001 * index for index in range(beams - 1)] + [math.inf])
    stamp(scan.header.stamp, t_ns)
    scan.header.frame_id = 'laser'
    twist = Twist()
    twist.linear.x, twist.angular.z = 0.3, -0.2
    return {'/clock': clock, '/odom': odom, '/scan': scan, '/cmd_vel': twist}


def new_bag(folder):
    return Path(tempfile.mkdtemp(dir=folder)) / 'bag'


def write_us(messages, folder, route):
    """
    Return the best time (us per message) of writing ``messages`` (list of (topic, msg)).

    ``route`` is 'write' (the recorder, bytes serialised beforehand), 'both' (the recorder,
    serialising each message) or 'naive' (serialising, then rosbags' Writer).
    """
    items = [(topic, message_type_name(msg), msg, serialize_message(msg))
             for topic, msg in messages]
    best = math.inf
    for _ in range(REPEATS):
        if route == 'naive':
            bag = Writer(new_bag(folder), version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
            bag.open()
            connections = {}
            start = time.perf_counter()
            for t_ns, (topic, type_name, msg, _) in enumerate(items):
                connection = connections.get(topic)
                if connection is None:
                    connection = connections[topic] = bag.add_connection(
                        topic, type_name, typestore=TYPESTORE)
                bag.write(connection, t_ns, serialize_message(msg))
        else:
            bag = BagRecorder(new_bag(folder))
            write = bag.write
            start = time.perf_counter()
            if route == 'write':
                for t_ns, (topic, type_name, _, data) in enumerate(items):
                    write(topic, type_name, data, t_ns)
            else:
                for t_ns, (topic, type_name, msg, _) in enumerate(items):
                    write(topic, type_name, serialize_message(msg), t_ns)
        best = min(best, time.perf_counter() - start)
        bag.close()
    return best / len(items) * 1e6


def bag_seconds(messages, folder):
    """Return the best time (s) to open a bag, write ``messages`` ((topic, msg)), close it."""
    best = math.inf
    for _ in range(REPEATS):
        path = new_bag(folder)
        start = time.perf_counter()
        with BagRecorder(path) as recorder:
            for t_ns, (topic, msg) in enumerate(messages):
                recorder.write(topic, message_type_name(msg), serialize_message(msg), t_ns)
        best = min(best, time.perf_counter() - start)
    return best


def main():
    print(f'{"message":<22}{"serialise":>11}{"write":>9}{"ser.+write":>12}{"naive":>9}'
          '   (us per message)')
    with tempfile.TemporaryDirectory() as folder:
        for beams in (36, 1081):
            samples = sample_messages(beams)
            rows = [(topic, [(topic, msg)]) for topic, msg in samples.items()
                    if beams == 36 or topic == '/scan']
            if beams == 36:
                rows.append(('run mix', [(topic, samples[topic]) for topic, rate
                                         in RUN_MIX.items() for _ in range(rate)]))
            for label, pattern in rows:
                messages = (pattern * (COUNT // len(pattern) + 1))[:COUNT]
                serialise = microseconds_per_call(
                    serialize_message, lambda: [msg for _, msg in messages[:1000]])
                figures = [write_us(messages, folder, route)
                           for route in ('write', 'both', 'naive')]
                name = f'{label} ({beams} beams)' if label == '/scan' else label
                print(f'{name:<22}{serialise:>11.2f}{figures[0]:>9.2f}{figures[1]:>12.2f}'
                      f'{figures[2]:>9.2f}')
                if label == 'run mix':
                    mix = figures[1]
        bag = bag_seconds(list(sample_messages(36).items()), folder)
    total = RUN_SECONDS * sum(RUN_MIX.values())
    print(f"a bag's own cost (open, one message per topic, close): {bag * 1e3:.1f} ms")
    print(f'a {RUN_SECONDS} s run ({total} messages, 36 beams): '
          f'{bag + total * mix * 1e-6:.2f} s serialising and recording')


if __name__ == '__main__':
    main()
