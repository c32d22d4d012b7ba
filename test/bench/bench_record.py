"""
Benchmark recording: microseconds per message written to an MCAP bag, ours against rosbags'.

Rows per message type (and for the mix a 600 s run publishes: per simulated second 100 /clock,
50 /odom, 50 /tf, 10 /scan, 10 /cmd_vel), side by side:
* ``serialise``: our generated CDR serialiser on the runtime message;
* ``rosbags serialise``: the runtime message converted to a rosbags message
  (``lockstep.msg_to_rosbags``) then ``typestore.serialize_cdr``;
* ``record``: ``BagRecorder.write`` (serialise + lean MCAP write) into a real bag of
  ``COUNT`` messages, the bag's open and close included;
* ``rosbags record``: conversion + ``serialize_cdr`` + rosbags' ``Writer.write``, likewise.
Each figure is the best of a few repeats. The last lines give a bag's own cost (open, one
message per topic, close: mostly rosbags' YAML for ``metadata.yaml`` and the QoS profiles,
which the rosbags route does not store, so it has less of it) and extrapolate the mix to a
600 s run: that cost once, plus the mix's cost per message beyond it for each message.

Run: python test/bench/bench_record.py [--quick]
"""

import math
from pathlib import Path
import sys
import tempfile
import time

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.messages.rosbags_conversion import msg_to_rosbags
from sim_bridge.record import BAG_VERSION, BagRecorder, CdrSerializer, ros_type_name

REPEATS = 3
COUNT = 2000 if '--quick' in sys.argv else 10000
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
# Messages per simulated second at the bridge's default rates (physics 100 Hz, odom 50 Hz,
# lidar 10 Hz, one command per scan).
RUN_MIX = {'/clock': 100, '/odom': 50, '/tf': 50, '/scan': 10, '/cmd_vel': 10}
RUN_SECONDS = 600


def stamp(t_ns):
    time_msg = message_class('builtin_interfaces/msg/Time')()
    time_msg.sec, time_msg.nanosec = divmod(t_ns, 10 ** 9)
    return time_msg


def sample_messages(beams):
    """Return {topic: runtime message} shaped as the bridge and a node publish them."""
    t_ns = 12_340_000_000
    odom = message_class('nav_msgs/msg/Odometry')(child_frame_id='base_link')
    odom.header.stamp, odom.header.frame_id = stamp(t_ns), 'odom'
    odom.pose.pose.position.x, odom.pose.pose.orientation.w = 1.25, 1.0
    moved = message_class('geometry_msgs/msg/TransformStamped')(child_frame_id='base_link')
    moved.header.stamp, moved.header.frame_id = stamp(t_ns), 'odom'
    scan = message_class('sensor_msgs/msg/LaserScan')(
        angle_min=-1.57, angle_max=1.57, angle_increment=3.14 / (beams - 1), range_min=0.12,
        range_max=10.0, ranges=[1.0 + 0.001 * index for index in range(beams - 1)] + [math.inf])
    scan.header.stamp, scan.header.frame_id = stamp(t_ns), 'laser'
    twist = message_class('geometry_msgs/msg/Twist')()
    twist.linear.x, twist.angular.z = 0.3, -0.2
    return {'/clock': message_class('rosgraph_msgs/msg/Clock')(clock=stamp(t_ns)),
            '/odom': odom, '/tf': message_class('tf2_msgs/msg/TFMessage')(transforms=[moved]),
            '/scan': scan, '/cmd_vel': twist}


def best_us(action, count):
    """Return the best per-call time (us) of ``action(index)`` over REPEATS rounds."""
    best = math.inf
    for _ in range(REPEATS):
        start = time.perf_counter()
        for index in range(count):
            action(index)
        best = min(best, (time.perf_counter() - start) / count)
    return best * 1e6


def record_seconds(messages, folder, ours):
    """Return the time (s) to open a new bag, write ``messages`` (list of (topic, msg)), close."""
    best = math.inf
    for _ in range(REPEATS):
        path = Path(tempfile.mkdtemp(dir=folder)) / 'bag'
        start = time.perf_counter()
        if ours:
            with BagRecorder(path) as recorder:
                for index, (topic, msg) in enumerate(messages):
                    recorder.write(topic, msg, index)
        else:
            with Writer(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
                connections = {}
                for index, (topic, msg) in enumerate(messages):
                    typename = ros_type_name(msg)
                    if topic not in connections:
                        connections[topic] = writer.add_connection(topic, typename,
                                                                   typestore=TYPESTORE)
                    data = TYPESTORE.serialize_cdr(msg_to_rosbags(msg, TYPESTORE), typename)
                    writer.write(connections[topic], index, data)
        best = min(best, time.perf_counter() - start)
    return best


def main():
    serializer = CdrSerializer(TYPESTORE)
    print(f'{"message":<22}{"serialise":>11}{"rosbags ser.":>14}{"record":>9}'
          f'{"rosbags rec.":>14}   (us per message)')
    with tempfile.TemporaryDirectory() as folder:
        for beams in (36, 1081):
            samples = sample_messages(beams)
            rows = [(topic, [(topic, msg)]) for topic, msg in samples.items()
                    if beams == 36 or topic == '/scan']
            if beams == 36:
                per_second = [(topic, samples[topic]) for topic, rate in RUN_MIX.items()
                              for _ in range(rate)]
                rows.append(('run mix', per_second))
            for label, pattern in rows:
                messages = (pattern * (COUNT // len(pattern) + 1))[:COUNT]
                ours = best_us(lambda index: serializer.serialize(messages[index][1]), COUNT)
                theirs = best_us(lambda index: TYPESTORE.serialize_cdr(
                    msg_to_rosbags(messages[index][1], TYPESTORE),
                    ros_type_name(messages[index][1])), COUNT)
                recorded = record_seconds(messages, folder, ours=True) / COUNT * 1e6
                rosbags_recorded = record_seconds(messages, folder, ours=False) / COUNT * 1e6
                name = f'{label} ({beams} beams)' if label == '/scan' else label
                print(f'{name:<22}{ours:>11.2f}{theirs:>14.2f}{recorded:>9.2f}'
                      f'{rosbags_recorded:>14.2f}')
                if label == 'run mix':
                    mix = (recorded, rosbags_recorded)
        one_each = list(sample_messages(36).items())
        bag = [record_seconds(one_each, folder, ours) for ours in (True, False)]
    print(f"a bag's own cost (open, one message per topic, close): {bag[0] * 1e3:.1f} ms, "
          f'{bag[1] * 1e3:.1f} ms with the rosbags route')
    total = RUN_SECONDS * sum(RUN_MIX.values())
    run = []
    for cost, per_message in zip(bag, mix):
        beyond = (COUNT * per_message * 1e-6 - cost) / (COUNT - len(one_each))  # s per message
        run.append(cost + (total - len(one_each)) * beyond)
    print(f'a {RUN_SECONDS} s run ({total} messages, 36 beams): {run[0]:.2f} s recording, '
          f'{run[1]:.2f} s with the rosbags route')


if __name__ == '__main__':
    main()
