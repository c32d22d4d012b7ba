"""
The sim_bridge node (bridge.py) on real rclpy, seen from a node that uses it.

A probe node subscribes and publishes the way a lab node or ``ros2 topic pub`` would. The bridge
is stepped (``SimBridge(stepped=True)``) and every ready callback runs after each physics step
(``spin_until_idle``), so every check is at an exact sim time; one test runs the bridge live,
on its own steady-clock timer. Log lines are read from /rosout, as rqt_console reads them.
DDS traffic stays in the test process (conftest.py).
"""

import copy
from dataclasses import replace
import math
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time

from geometry_msgs.msg import PointStamped, TransformStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rcl_interfaces.msg import Log
import rclpy
from rclpy.clock import ClockType
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.time import Time
from rclpy.utilities import get_default_context
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from sim_bridge.common.paths import find_world
from sim_bridge.live import live
from sim_bridge.ros import bridge as bridge_module
from sim_bridge.ros.bridge import command_type, NO_TF_WARNING, SimBridge
from sim_bridge.ros.rviz import LATCHED, shape_pose
from sim_bridge.runner.stepping import spin_after_publishing, spin_until_idle, SteppedExecutor
from sim_bridge.simulation.geometry import quaternion_from_euler
from sim_bridge.simulation.robot import DiffDriveConfig, DriveLimits, pose_from
from sim_bridge.simulation.sdf_frames import relative_pose
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World
from std_msgs.msg import String
from urdf_parser_py import urdf
from visualization_msgs.msg import MarkerArray
import yaml

NANOSECONDS_PER_SECOND = 10 ** 9
MS = 10 ** 6
STEP_NS = NANOSECONDS_PER_SECOND // 100     # the default physics_rate, 100 Hz
SCAN_PERIOD_NS = NANOSECONDS_PER_SECOND // 10
ODOM_PERIOD_NS = NANOSECONDS_PER_SECOND // 50
COMMAND_PERIOD_S = 0.1                       # how often the probe repeats a command
PARAMS_FILE = Path(__file__).resolve().parents[1] / 'params' / 'sim.yaml'
MODELS = Path(__file__).resolve().parent / 'fixtures' / 'models'


class Session:
    """rclpy initialised, an executor, and the nodes a test starts in it."""

    def __init__(self):
        self.executor = SteppedExecutor(get_default_context())
        self.nodes = []
        self.bridges = []

    def add(self, node):
        """Put ``node`` in the executor; it is destroyed when the test ends."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def bridge(self, namespace=None, stepped=True, cli_args=None, **params):
        """Start a SimBridge with ``params`` as parameter overrides."""
        node = SimBridge(stepped=stepped, namespace=namespace, cli_args=cli_args,
                         parameter_overrides=[Parameter(name, value=value)
                                              for name, value in params.items()])
        self.bridges.append(node)
        return self.add(node)

    def probe(self, name='probe'):
        """Start a plain node, as ``rclpy.create_node`` gives a user."""
        return self.add(rclpy.create_node(name))

    @property
    def now_ns(self):
        """Return the sim time (ns): every bridge of the test steps together."""
        return self.bridges[0].now_ns if self.bridges else 0

    def listen(self, node, msg_type, topic, qos=10):
        """Subscribe ``node`` to ``topic``; return the list of (sim time ns, msg) it receives."""
        received = []
        node.create_subscription(
            msg_type, topic, lambda msg: received.append((self.now_ns, msg)), qos)
        return received

    def spin(self):
        """Run every ready callback, and those they make ready."""
        return spin_until_idle(self.executor)

    def step(self, clock_due=True):
        """Step every bridge once, then run every callback that became ready."""
        heard = [bridge.step(clock_due) for bridge in self.bridges]
        self.spin()
        return any(heard)

    def run_for(self, seconds):
        """Advance sim time by ``seconds``, running every callback due."""
        self.spin()
        for _ in range(round(seconds * NANOSECONDS_PER_SECOND / self.bridges[0].step_ns)):
            self.step()

    def command_publisher(self, node, msg_type=Twist):
        """Return a new cmd_vel publisher of ``node``, subscribed to by the bridges."""
        publisher = node.create_publisher(msg_type, 'cmd_vel', 10)
        for bridge in self.bridges:  # what they would see on the graph at their next look
            bridge.check_command_publishers()
        return publisher

    def drive(self, publisher, message, seconds):
        """Publish ``message`` now and every COMMAND_PERIOD_S for ``seconds``, like teleop."""
        for bridge in self.bridges:  # as the runner has them look once its nodes are up
            bridge.check_command_publishers()
        for _ in range(round(seconds / COMMAND_PERIOD_S)):
            publisher.publish(message)
            self.run_for(COMMAND_PERIOD_S)


@pytest.fixture
def session():
    """Init rclpy; shut the executor down, destroy the nodes and shut rclpy down after."""
    rclpy.init(args=[])
    started = Session()
    try:
        yield started
    finally:
        started.executor.shutdown()
        for node in started.nodes[::-1]:
            node.destroy_node()     # a bridge closes its pybullet client
        rclpy.try_shutdown()


@pytest.fixture
def logs(session):
    """Collect what the test's nodes log, from /rosout (kept for late joiners, like rosout)."""
    records = []
    listener = session.add(rclpy.create_node('log_listener'))
    listener.create_subscription(
        Log, '/rosout', records.append,
        QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    return records


@pytest.fixture
def no_tf(monkeypatch):
    """Run the bridge as on a machine without tf2_ros (the PyPI wheels)."""
    monkeypatch.setattr(bridge_module, 'TransformBroadcaster', None)
    monkeypatch.setattr(bridge_module, 'StaticTransformBroadcaster', None)


@pytest.fixture
def tf_sent(monkeypatch):
    """
    Stand in for tf2_ros's broadcasters; return what the bridge sends them.

    ``{'tf': [...], 'tf_static': [...]}`` of (bridge sim time ns, transform). Each double
    publishes the transform on /test_tf or /test_tf_static (TFMessage is not on PyPI), so its
    ``pub_tf`` has subscribers as tf2_ros's would.
    """
    sent = {'tf': [], 'tf_static': []}

    def broadcaster(kind):
        class RecordingBroadcaster:

            def __init__(self, node):
                self.node = node
                self.pub_tf = node.create_publisher(TransformStamped, f'/test_{kind}', 10)

            def sendTransform(self, transforms):  # noqa: N802 tf2_ros's name
                # One transform or a list, as tf2_ros takes. The bridge refills its transform
                # in place; tf2_ros copies it by publishing.
                for transform in transforms if isinstance(transforms, list) else [transforms]:
                    sent[kind].append((self.node.now_ns, copy.deepcopy(transform)))
                    self.pub_tf.publish(transform)

        return RecordingBroadcaster

    monkeypatch.setattr(bridge_module, 'TransformBroadcaster', broadcaster('tf'))
    monkeypatch.setattr(bridge_module, 'StaticTransformBroadcaster', broadcaster('tf_static'))
    return sent


def twist(linear, angular=0.0):
    """Return a geometry_msgs/Twist command (m/s, rad/s)."""
    message = Twist()
    message.linear.x = float(linear)
    message.angular.z = float(angular)
    return message


def periodic_times(period_ns, end_ns, start_ns=0):
    """Return the times (ns) of something happening every ``period_ns`` up to ``end_ns``."""
    return list(range(start_ns + period_ns, end_ns + 1, period_ns))


def stamp_ns(stamp):
    """Return a builtin_interfaces/Time as ns."""
    return stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec


def yaw_of(quaternion):
    """Return the yaw (rad) of a rotation about z."""
    return math.atan2(2.0 * (quaternion.w * quaternion.z + quaternion.x * quaternion.y),
                      1.0 - 2.0 * (quaternion.y ** 2 + quaternion.z ** 2))


def warnings_of(logs, node_name='sim_bridge'):
    """
    Return the texts of the WARN records of ``node_name``, but the one about missing tf2_ros.

    That one depends on the machine (a ROS install has tf2_ros, the PyPI wheels do not).
    """
    return [record.msg for record in logs
            if record.level == Log.WARN and record.name == node_name
            and record.msg != NO_TF_WARNING]


def ramp_loss(speed, accel):
    """Return the distance (m) lost accelerating from rest to ``speed`` (m/s) at ``accel``."""
    return speed ** 2 / (2.0 * accel)


def robot_world(monkeypatch, *, drive=None, lidar=None, **world_attributes):
    """
    Make every bridge load the obstacles world with its robot's drive and lidar replaced.

    As the model reader gives a model whose SDF has a diff-drive plugin; ``world_attributes``
    are set on the world as its reader would set them (``physics_step_s``, ``ignored``).
    """
    world = World.load('obstacles')
    world = replace(world, robot=replace(world.robot, drive=drive,
                                         lidar=lidar or world.robot.lidar))
    for name, value in world_attributes.items():
        object.__setattr__(world, name, value)   # frozen: as the reader's constructor would
    monkeypatch.setattr(bridge_module.World, 'load', lambda *args, **kwargs: world)
    return world


#: A TurtleBot3-like plugin: its own topics and frames, slow odometry, no acceleration limit.
PLUGIN = DiffDriveConfig(
    wheel_separation=0.16, wheel_radius=0.033,
    limits=DriveLimits(max_linear_speed=0.22, max_angular_speed=2.0,
                       max_linear_accel=math.inf, max_angular_accel=math.inf),
    command_topic='/robot/cmd_vel', odometry_topic='robot/odom', odometry_frame='robot_odom',
    base_frame='base_footprint', odometry_rate=20.0, publish_tf=True)


# --- what the bridge publishes ---------------------------------------------------------------

def test_clock_is_published_every_physics_step_with_the_sim_time(session):
    session.bridge()
    clocks = session.listen(session.probe(), Clock, '/clock')
    session.run_for(0.5)
    assert [t for t, _ in clocks] == periodic_times(STEP_NS, NANOSECONDS_PER_SECOND // 2)
    assert [stamp_ns(msg.clock) for t, msg in clocks] == [t for t, _ in clocks]


def test_scan_is_published_at_the_lidar_rate_in_the_laser_frame(session):
    session.bridge()
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(1.0)
    assert [t for t, _ in scans] == periodic_times(SCAN_PERIOD_NS, NANOSECONDS_PER_SECOND)
    for t, scan in scans:
        assert stamp_ns(scan.header.stamp) == t
        assert scan.header.frame_id == 'laser'


def test_scan_has_the_labs_geometry(session):
    session.bridge()
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.1)
    (_, scan), = scans
    assert len(scan.ranges) == 36
    assert scan.angle_min == pytest.approx(-1.57, abs=1e-6)
    assert scan.angle_max == pytest.approx(1.57, abs=1e-6)
    assert scan.angle_increment == pytest.approx(
        (scan.angle_max - scan.angle_min) / (len(scan.ranges) - 1), rel=1e-6)
    assert (scan.range_min, scan.range_max) == pytest.approx((0.12, 10.0))
    assert (scan.scan_time, scan.time_increment) == pytest.approx((0.1, 0.0))
    # One intensity per beam, 0.0 as Gazebo's gpu_lidar gives (through ros_gz_bridge) for
    # surfaces without <laser_retro>, the SDF default.
    assert list(scan.intensities) == [0.0] * 36


def test_scan_is_reliable_depth_10_and_reaches_best_effort_and_reliable_subscribers(session):
    bridge = session.bridge()
    assert bridge.scan_pub.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    assert bridge.scan_pub.qos_profile.depth == 10
    probe = session.probe()
    # What `ros2 topic info -v /scan` shows: the middleware's view of the publisher.
    (info,) = probe.get_publishers_info_by_topic('/scan')
    assert (info.node_name, info.topic_type) == ('sim_bridge', 'sensor_msgs/msg/LaserScan')
    assert info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    best_effort = session.listen(probe, LaserScan, 'scan', qos_profile_sensor_data)
    reliable = session.listen(probe, LaserScan, 'scan', QoSProfile(depth=10))
    session.run_for(1.0)
    assert len(best_effort) == len(reliable) == 10


def test_scan_ranges_are_the_simulators(session):
    session.bridge(seed=5)
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.2)
    assert len(scans) == 2
    with Simulator('obstacles', seed=5) as simulator:
        for _, scan in scans:
            for _ in range(SCAN_PERIOD_NS // STEP_NS):
                simulator.step(STEP_NS / NANOSECONDS_PER_SECOND)
            expected = np.asarray(simulator.scan().ranges, dtype=np.float32)
            assert np.array_equal(np.asarray(scan.ranges, dtype=np.float32), expected)


def test_odometry_follows_the_simulated_robot_from_zero_at_its_spawn_pose(session):
    bridge = session.bridge(robot_pose=[-0.5, 0.4, 1.0])
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'odom')
    session.drive(probe.create_publisher(Twist, 'cmd_vel', 10), twist(0.2, 0.5), 1.0)
    assert [t for t, _ in odometry] == periodic_times(ODOM_PERIOD_NS, NANOSECONDS_PER_SECOND)
    t, odom = odometry[-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    assert stamp_ns(odom.header.stamp) == t
    # Gazebo's DiffDrive: odometry from (0, 0, 0) in odom, the spawn pose's frame.
    x, y, yaw = pose_from(bridge.sim.world.robot_start, bridge.sim.pose)
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (x, y)
    assert yaw_of(odom.pose.pose.orientation) == pytest.approx(yaw, abs=1e-9)
    first = odometry[0][1].pose.pose
    assert math.hypot(first.position.x, first.position.y) < 0.01
    assert (x, y) != pytest.approx(bridge.sim.pose[:2], abs=0.1)
    assert (odom.twist.twist.linear.x, odom.twist.twist.angular.z) == bridge.sim.velocity
    assert bridge.sim.velocity == pytest.approx((0.2, 0.5))
    # The bridge refills one message in place: what was received earlier must not change.
    assert len({odom.pose.pose.position.x for _, odom in odometry}) == len(odometry)


def test_collision_is_logged_and_published(session, logs):
    bridge = session.bridge()
    probe = session.probe()
    collisions = session.listen(probe, PointStamped, 'collisions')
    session.drive(probe.create_publisher(Twist, 'cmd_vel', 10), twist(1.0), 4.0)
    world = World.load('obstacles')
    cube = world.obstacle('cube').footprints[0]
    contact_x = cube.x - cube.half_x - world.robot.radius
    assert bridge.sim.pose[0] == pytest.approx(contact_x, abs=1e-5)
    (t, point), = collisions
    assert stamp_ns(point.header.stamp) == t
    assert point.header.frame_id == 'odom'
    assert (point.point.x, point.point.y) == pytest.approx((contact_x, 0.0), abs=1e-5)
    (warning,) = warnings_of(logs)
    assert warning.startswith('collision with cube at t=')
    assert f'x={contact_x:.2f} m, y=0.00 m' in warning


# --- stepping: step(), now_ns, on_publish, live timer ----------------------------------------

def test_a_stepped_bridge_has_no_timer_and_moves_only_when_stepped(session):
    bridge = session.bridge(physics_rate=250.0)
    assert list(bridge.timers) == []
    assert bridge.now_ns == 0
    session.spin()
    assert bridge.now_ns == 0
    for _ in range(3):
        session.step()
    assert bridge.now_ns == 3 * NANOSECONDS_PER_SECOND // 250
    assert bridge.sim.time_ns == bridge.now_ns


def test_step_without_clock_due_sends_clock_only_with_a_heard_message(session):
    bridge = session.bridge()
    probe = session.probe()
    clocks = session.listen(probe, Clock, '/clock')
    scans = session.listen(probe, LaserScan, 'scan')
    # Odometry goes out every 2 steps but nobody listens: those steps are not heard.
    heard = [session.step(clock_due=False) for _ in range(20)]
    assert [step for step, was_heard in enumerate(heard, 1) if was_heard] == [10, 20]
    assert [t for t, _ in clocks] == [t for t, _ in scans] == periodic_times(
        SCAN_PERIOD_NS, 2 * SCAN_PERIOD_NS)
    assert bridge.now_ns == 20 * STEP_NS
    assert bridge.step(clock_due=True) is True


def test_step_reports_nothing_heard_when_nobody_listens(session):
    session.bridge()
    assert not any(session.step(clock_due=False) for _ in range(20))


def test_on_publish_sees_every_message_the_bridge_publishes(session):
    bridge = session.bridge(namespace='robot')
    published = []
    # With the bytes it published: the message itself, serialised.
    bridge.on_publish = lambda topic, msg, data: published.append(
        (bridge.now_ns, topic, type(msg))
        if deserialize_message(data, type(msg)) == deserialize_message(serialize_message(msg),
                                                                       type(msg))
        else (topic, 'published other bytes'))
    for _ in range(10):
        session.step(clock_due=False)     # nobody listens: no /clock
    assert published == [(20 * MS, '/robot/odom', Odometry), (40 * MS, '/robot/odom', Odometry),
                         (60 * MS, '/robot/odom', Odometry), (80 * MS, '/robot/odom', Odometry),
                         (100 * MS, '/robot/scan', LaserScan),
                         (100 * MS, '/robot/odom', Odometry)]
    published.clear()
    session.step(clock_due=True)
    assert published == [(110 * MS, '/robot/clock', Clock)]


def test_live_bridge_steps_physics_on_a_steady_timer_and_clock_advances(session):
    # The one test on the wall clock: bounded by a deadline, it needs ~0.15 s.
    start = time.monotonic()    # the timer starts with the node
    bridge = session.bridge(stepped=False, real_time_factor=2.0)
    (timer,) = bridge.timers
    assert timer.clock.clock_type == ClockType.STEADY_TIME
    assert timer.timer_period_ns == STEP_NS // 2
    probe = session.probe()
    clocks = session.listen(probe, Clock, '/clock', QoSProfile(depth=1000))
    scans = session.listen(probe, LaserScan, 'scan')
    deadline = start + 5.0
    while len(scans) < 3 and time.monotonic() < deadline:
        session.executor.spin_once(timeout_sec=0.1)
    elapsed_s = time.monotonic() - start
    assert len(scans) >= 3
    assert [stamp_ns(scan.header.stamp) for _, scan in scans[:3]] == periodic_times(
        SCAN_PERIOD_NS, 3 * SCAN_PERIOD_NS)
    sim_times = [stamp_ns(msg.clock) for _, msg in clocks]
    assert sim_times[:30] == periodic_times(STEP_NS, 30 * STEP_NS)
    assert bridge.now_ns >= 30 * STEP_NS
    # Paced: 0.3 s of sim time at real_time_factor 2 cannot take less than ~0.15 s.
    assert elapsed_s >= 29 * timer.timer_period_ns / NANOSECONDS_PER_SECOND


# --- TF --------------------------------------------------------------------------------------

def test_without_tf2_ros_the_bridge_warns_once_and_publishes_the_rest(session, logs, no_tf):
    bridge = session.bridge()
    assert bridge.tf_broadcaster is None
    probe = session.probe()
    scans = session.listen(probe, LaserScan, 'scan')
    odometry = session.listen(probe, Odometry, 'odom')
    clocks = session.listen(probe, Clock, '/clock')
    session.run_for(1.0)
    (warning,) = [record.msg for record in logs if record.level == Log.WARN]
    assert warning == NO_TF_WARNING and 'tf2_ros' in warning
    assert (len(scans), len(odometry), len(clocks)) == (10, 50, 100)
    topics = dict(probe.get_topic_names_and_types())
    assert '/tf' not in topics and '/tf_static' not in topics


def test_static_laser_transform_is_sent_once_at_start_from_the_robot_model(session, tf_sent):
    bridge = session.bridge()
    session.run_for(0.5)
    (t, transform), = tf_sent['tf_static']
    assert t == 0
    assert (transform.header.frame_id, transform.child_frame_id) == ('base_link', 'laser')
    assert stamp_ns(transform.header.stamp) == 0
    laser = bridge.sim.lidar_config.pose
    offset = transform.transform.translation
    assert (offset.x, offset.y, offset.z) == pytest.approx(laser[:3])
    rotation = transform.transform.rotation
    assert yaw_of(rotation) == pytest.approx(laser[5])
    assert (rotation.x, rotation.y, rotation.z, rotation.w) == pytest.approx(
        quaternion_from_euler(*laser[3:]))


def test_a_turtlebot3_has_the_tf_tree_robot_state_publisher_and_the_diff_drive_give(
        session, tf_sent):
    bridge = session.bridge(robot='turtlebot3_burger', robot_pose=[0.5, 0.5, 0.0])
    session.run_for(0.1)
    static = {(t.header.frame_id, t.child_frame_id): t.transform for _, t in tf_sent['tf_static']}
    assert {('base_footprint', 'base_link'), ('base_link', 'base_scan'),
            ('base_link', 'wheel_left_link')} <= set(static)
    assert not any(child == 'base_scan' for parent, child in static if parent != 'base_link')
    # The scan frame where the lidar sensor is, seen from base_link.
    lidar = bridge.sim.lidar_config.pose
    offset = static[('base_link', 'base_scan')].translation
    assert (offset.x, offset.y, offset.z) == pytest.approx(lidar[:3])
    (_, odom), *_ = tf_sent['tf']
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_footprint')


def test_odom_transform_goes_with_each_odometry_message(session, tf_sent):
    bridge = session.bridge()
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'odom')
    session.drive(probe.create_publisher(Twist, 'cmd_vel', 10), twist(0.2, 0.5), 1.0)
    assert bridge.sim.velocity == pytest.approx((0.2, 0.5))
    assert [t for t, _ in tf_sent['tf']] == [t for t, _ in odometry]
    for (_, odom), (_, transform) in zip(odometry, tf_sent['tf'], strict=True):
        assert (transform.header.frame_id, transform.child_frame_id) == ('odom', 'base_link')
        assert transform.header.stamp == odom.header.stamp
        offset = transform.transform.translation
        assert (offset.x, offset.y, offset.z) == \
            (odom.pose.pose.position.x, odom.pose.pose.position.y, 0.0)
        assert transform.transform.rotation == odom.pose.pose.orientation


def test_a_tf_subscriber_makes_odometry_steps_heard(session, tf_sent):
    session.bridge()
    transforms = session.listen(session.probe(), TransformStamped, '/test_tf')
    heard = [session.step(clock_due=False) for _ in range(6)]
    assert heard == [False, True] * 3
    assert [t for t, _ in transforms] == periodic_times(ODOM_PERIOD_NS, 6 * STEP_NS)


def test_clock_goes_with_a_transform_only_a_tf_subscriber_hears(session, tf_sent):
    session.bridge()
    probe = session.probe()
    transforms = session.listen(probe, TransformStamped, '/test_tf')
    clocks = session.listen(probe, Clock, '/clock')
    for _ in range(4):
        session.step(clock_due=False)
    assert [t for t, _ in clocks] == [t for t, _ in transforms] == [20 * MS, 40 * MS]


def test_frame_parameters_rename_the_frames(session, tf_sent):
    session.bridge(odom_frame='world', base_link_frame='base_footprint', laser_frame='base_scan')
    probe = session.probe()
    scans = session.listen(probe, LaserScan, 'scan')
    odometry = session.listen(probe, Odometry, 'odom')
    session.run_for(0.1)
    assert scans[0][1].header.frame_id == 'base_scan'
    assert (odometry[0][1].header.frame_id, odometry[0][1].child_frame_id) == \
        ('world', 'base_footprint')
    ((_, static),) = tf_sent['tf_static']
    assert (static.header.frame_id, static.child_frame_id) == ('base_footprint', 'base_scan')
    assert {(transform.header.frame_id, transform.child_frame_id)
            for _, transform in tf_sent['tf']} == {('world', 'base_footprint')}


def test_tf_with_the_real_tf2_ros(session, monkeypatch):
    tf2_ros = pytest.importorskip('tf2_ros')
    from tf2_msgs.msg import TFMessage
    monkeypatch.setattr(bridge_module, 'TransformBroadcaster', tf2_ros.TransformBroadcaster)
    monkeypatch.setattr(bridge_module, 'StaticTransformBroadcaster',
                        tf2_ros.StaticTransformBroadcaster)
    bridge = session.bridge()
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'odom')
    messages = session.listen(probe, TFMessage, '/tf')
    session.drive(probe.create_publisher(Twist, 'cmd_vel', 10), twist(0.2, 0.5), 0.5)
    # A listener that starts late still gets the static transform (transient local).
    late = session.probe('late_listener')
    buffer = tf2_ros.Buffer()
    listener = tf2_ros.TransformListener(buffer, late)
    session.run_for(0.1)
    assert [t for t, _ in messages] == [t for t, _ in odometry]
    for (_, odom), (_, message) in zip(odometry, messages, strict=True):
        (transform,) = message.transforms
        assert (transform.header.frame_id, transform.child_frame_id) == ('odom', 'base_link')
        assert transform.header.stamp == odom.header.stamp
        assert (transform.transform.translation.x, transform.transform.translation.y) == \
            (odom.pose.pose.position.x, odom.pose.pose.position.y)
        assert transform.transform.rotation == odom.pose.pose.orientation
    _, odom = odometry[-1]
    laser = buffer.lookup_transform('odom', 'laser', Time.from_msg(odom.header.stamp))
    x, y, yaw = bridge.sim.pose
    offset = laser.transform.translation
    assert (offset.x, offset.y, offset.z) == pytest.approx(
        (x, y, bridge.sim.lidar_config.pose[2]), abs=1e-9)
    assert yaw_of(laser.transform.rotation) == pytest.approx(yaw, abs=1e-9)
    listener.unregister()


# --- cmd_vel ---------------------------------------------------------------------------------

def test_twist_drives_the_robot_forward(session):
    bridge = session.bridge()
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(0.2), 1.0)
    x, y, yaw = bridge.sim.pose
    assert x == pytest.approx(0.2 * 1.0 - ramp_loss(0.2, DriveLimits().max_linear_accel),
                              abs=1e-9)
    assert (y, yaw) == (0.0, 0.0)


def test_twist_stamped_drives_a_bridge_with_cmd_vel_stamped(session):
    bridge = session.bridge(cmd_vel_stamped=True)
    probe = session.probe()
    (info,) = probe.get_subscriptions_info_by_topic('/cmd_vel')
    assert info.topic_type == 'geometry_msgs/msg/TwistStamped'
    publisher = probe.create_publisher(TwistStamped, 'cmd_vel', 10)
    command = TwistStamped(twist=twist(0.2))
    command.header.stamp = probe.get_clock().now().to_msg()
    session.drive(publisher, command, 1.0)
    assert bridge.sim.pose[0] == pytest.approx(
        0.2 - ramp_loss(0.2, DriveLimits().max_linear_accel), abs=1e-9)


@pytest.mark.parametrize('msg_type', [Twist, TwistStamped])
def test_cmd_vel_takes_the_type_its_publisher_uses(msg_type, session):
    bridge = session.bridge()
    probe = session.probe()
    assert probe.get_subscriptions_info_by_topic('/cmd_vel') == []  # none until one publishes
    # A node of either type can start in the bridge's process (one DDS participant).
    publisher = session.command_publisher(probe, msg_type)
    (info,) = probe.get_subscriptions_info_by_topic('/cmd_vel')
    assert info.topic_type == f'geometry_msgs/msg/{msg_type.__name__}'
    command = msg_type()
    getattr(command, 'twist', command).linear.x = 0.2
    session.drive(publisher, command, 1.0)
    assert bridge.sim.pose[0] == pytest.approx(
        0.2 - ramp_loss(0.2, DriveLimits().max_linear_accel), abs=1e-9)


def test_publishers_of_both_command_types_are_one_error_naming_them():
    assert command_type('/cmd_vel', {}) == (None, '')
    assert command_type('/cmd_vel', {'geometry_msgs/msg/TwistStamped': ['driver']}) == \
        (TwistStamped, '')
    assert command_type('/cmd_vel', {'geometry_msgs/msg/Twist': ['teleop', 'ns/helper'],
                                     'geometry_msgs/msg/TwistStamped': ['driver']}) == \
        (None, '/cmd_vel has publishers of both command types (teleop, ns/helper publish Twist;'
         ' driver publish TwistStamped): the simulator takes one; publish Twist or '
         'TwistStamped from every node')


def test_twist_publisher_on_a_stamped_bridge_is_refused_in_the_same_process(session):
    from rclpy.impl.implementation_singleton import rclpy_implementation
    if rclpy.utilities.get_rmw_implementation_identifier() != 'rmw_fastrtps_cpp':
        pytest.skip('how a topic type clash shows depends on the middleware')
    bridge = session.bridge(cmd_vel_stamped=True)
    # Across processes DDS would just never connect the two; within one participant Fast DDS
    # refuses the second type on the topic.
    with pytest.raises(rclpy_implementation.RCLError, match=r'rt/cmd_vel with incompatible '
                       r'type geometry_msgs::msg::dds_::Twist_'):
        session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.run_for(0.1)
    assert bridge.sim.pose == (0.0, 0.0, 0.0)


# --- the drive as the robot model's diff-drive plugin says -----------------------------------

def test_the_drive_follows_the_models_diff_drive_plugin(session, monkeypatch, tf_sent):
    world = robot_world(monkeypatch, drive=PLUGIN,
                        lidar=replace(World.load('obstacles').robot.lidar, frame_id='base_scan'))
    bridge = session.bridge()
    probe = session.probe()
    # The plugin's topics, as relative names (in the node's namespace, remappable).
    odometry = session.listen(probe, Odometry, 'robot/odom')
    scans = session.listen(probe, LaserScan, 'scan')
    session.drive(probe.create_publisher(Twist, 'robot/cmd_vel', 10), twist(1.0, 3.0), 1.0)
    assert bridge.sim.command == (0.22, 2.0)                      # the plugin's limits
    assert bridge.sim.velocity == (0.22, 2.0)                     # no acceleration limit
    times = [t for t, _ in odometry]
    assert times == periodic_times(NANOSECONDS_PER_SECOND // 20, NANOSECONDS_PER_SECOND)
    assert {(odom.header.frame_id, odom.child_frame_id) for _, odom in odometry} == \
        {('robot_odom', 'base_footprint')}
    assert {scan.header.frame_id for _, scan in scans} == {'base_scan'}
    ((_, static),) = tf_sent['tf_static']
    assert (static.header.frame_id, static.child_frame_id) == ('base_footprint', 'base_scan')
    assert static.transform.translation.z == pytest.approx(world.robot.lidar.pose[2])
    assert {(transform.header.frame_id, transform.child_frame_id)
            for _, transform in tf_sent['tf']} == {('robot_odom', 'base_footprint')}
    assert [t for t, _ in tf_sent['tf']] == times
    assert bridge.get_parameter('max_linear_speed').value == 0.22
    assert bridge.get_parameter('cmd_vel_timeout').value == 0.0


def test_a_parameter_given_to_the_node_wins_over_the_plugin(session, monkeypatch, tf_sent):
    robot_world(monkeypatch, drive=PLUGIN)
    bridge = session.bridge(cli_args=['--ros-args', '-p', 'max_linear_speed:=0.1',
                                      '-p', 'odom_frame:=odom', '-p', 'odom_rate:=10.0'])
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'robot/odom')
    session.drive(probe.create_publisher(Twist, 'robot/cmd_vel', 10), twist(1.0, 3.0), 0.5)
    assert bridge.sim.command == (0.1, 2.0)       # the parameter's speed, the plugin's turn
    assert [t for t, _ in odometry] == periodic_times(NANOSECONDS_PER_SECOND // 10,
                                                      NANOSECONDS_PER_SECOND // 2)
    assert (odometry[0][1].header.frame_id, odometry[0][1].child_frame_id) == \
        ('odom', 'base_footprint')


def test_a_plugin_without_tf_sends_only_the_static_lidar_transform(session, monkeypatch,
                                                                   tf_sent):
    robot_world(monkeypatch, drive=replace(PLUGIN, publish_tf=False))
    session.bridge()
    session.run_for(0.5)
    assert len(tf_sent['tf_static']) == 1
    assert tf_sent['tf'] == []
    session.bridge(namespace='with_tf', publish_tf=True)
    session.run_for(0.1)
    assert len(tf_sent['tf']) == 2


def test_a_robot_without_a_plugin_keeps_the_kits_drive(session):
    bridge = session.bridge()
    assert World.load('obstacles').robot.drive is None
    assert {name: bridge.get_parameter(name).value for name in vars(DriveLimits())} == \
        vars(DriveLimits())
    assert bridge.frames == {'odom': 'odom', 'base_link': 'base_link', 'laser': 'laser'}
    assert bridge.get_parameter('odom_rate').value == 50.0


def test_without_a_new_command_the_robot_keeps_the_last_one_as_in_gazebo(session):
    bridge = session.bridge()
    probe = session.probe()
    session.command_publisher(probe).publish(twist(0.2, 0.1))
    session.run_for(5.0)
    assert bridge.sim.command == (0.2, 0.1)
    assert bridge.sim.velocity == pytest.approx((0.2, 0.1))


@pytest.mark.parametrize('value', [-1.0, math.nan, math.inf])
def test_cmd_vel_timeout_must_be_zero_or_positive(value, session):
    with pytest.raises(ValueError, match="'cmd_vel_timeout' must be 0"):
        session.bridge(cmd_vel_timeout=value)


@pytest.mark.parametrize('timeout_s', [0.5, 1.0])
def test_robot_stops_when_commands_stop_for_cmd_vel_timeout(timeout_s, session):
    bridge = session.bridge(cmd_vel_timeout=timeout_s)
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'odom')
    session.command_publisher(probe).publish(twist(0.2))
    session.run_for(timeout_s + 1.0)
    moving = [t for t, odom in odometry if odom.twist.twist.linear.x > 0.0]
    stop_time_s = 0.2 / DriveLimits().max_linear_accel
    # The timeout is checked at each physics step, then the robot brakes.
    assert moving[-1] / NANOSECONDS_PER_SECOND == pytest.approx(
        timeout_s + stop_time_s, abs=2 * ODOM_PERIOD_NS / NANOSECONDS_PER_SECOND)
    assert bridge.sim.velocity == (0.0, 0.0)
    assert odometry[-1][1].pose.pose.position == odometry[-10][1].pose.pose.position


@pytest.mark.parametrize('linear, angular', [
    (math.nan, 0.0), (0.2, math.nan), (math.inf, 0.0), (0.2, -math.inf)])
def test_non_finite_command_is_rejected_with_a_warning_and_stops_the_robot(
        linear, angular, session, logs):
    bridge = session.bridge()
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(0.2), 1.0)
    assert bridge.sim.velocity[0] == pytest.approx(0.2)
    session.drive(publisher, twist(linear, angular), 0.5)
    assert bridge.sim.command == (0.0, 0.0)
    assert bridge.sim.velocity == (0.0, 0.0)
    # Five bad commands in well under a second of wall time: the warning is throttled to one
    # a second (rclpy throttles on the system clock).
    (warning,) = warnings_of(logs)
    assert warning.startswith('cmd_vel: rejected command') and 'not a finite number' in warning


@pytest.mark.parametrize('linear, angular, limit', [
    (1e9, 0.0, (DriveLimits().max_linear_speed, 0.0)),
    (-1e9, 0.0, (-DriveLimits().max_linear_speed, 0.0)),
    (0.0, 1e9, (0.0, DriveLimits().max_angular_speed)),
])
def test_huge_command_is_clamped_with_a_warning(linear, angular, limit, session, logs):
    bridge = session.bridge()
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(linear, angular), 1.0)
    assert bridge.sim.command == limit
    assert bridge.sim.velocity == pytest.approx(limit)
    (warning,) = warnings_of(logs)
    assert warning.startswith('cmd_vel: clamped command')


# --- parameters ------------------------------------------------------------------------------

def first_pose(session, **params):
    """Start a bridge with ``params``; return (bridge, its robot's world pose at first odom)."""
    bridge = session.bridge(**params)
    odometry = session.listen(session.probe(), Odometry, 'odom')
    session.run_for(ODOM_PERIOD_NS / NANOSECONDS_PER_SECOND)
    pose = odometry[0][1].pose.pose
    assert (pose.position.x, pose.position.y, yaw_of(pose.orientation)) == \
        pytest.approx((0.0, 0.0, 0.0))  # odometry from the spawn pose, as Gazebo's DiffDrive
    return bridge, bridge.sim.pose


def test_world_parameter_takes_a_name(session):
    bridge, pose = first_pose(session, world='wall_follow_box')
    assert bridge.sim.world.name == 'wall_follow_box'
    assert pose == pytest.approx(World.load('wall_follow_box').robot_start)


def test_world_parameter_takes_a_path_anywhere(session, tmp_path):
    path = tmp_path / 'my_world.yaml'
    shutil.copy(find_world('wall_follow_box'), path)
    bridge, pose = first_pose(session, world=str(path))
    assert bridge.sim.world.path.resolve() == path.resolve()
    assert pose == pytest.approx(World.load(path).robot_start)


def test_unknown_world_raises_naming_the_shipped_worlds(session):
    with pytest.raises(FileNotFoundError, match='no_such_world.*wall_follow_box'):
        session.bridge(world='no_such_world')


@pytest.mark.parametrize('parameter, said', [
    ('world:=5', "parameter 'world' to '5' of type 'INTEGER', expecting type 'STRING'"),
    ('world:=no_such_world', "unknown world 'no_such_world': shipped worlds are obstacles"),
    ('robot_pose:=[1.0]', "parameter 'robot_pose' must be [x, y, yaw]"),
    ('world:={broken}', 'broken.world: invalid XML: mismatched tag'),
])
def test_the_simulator_node_refuses_a_bad_start_in_one_line(tmp_path, parameter, said):
    # ros2 run sim_bridge sim_bridge --ros-args -p ...: its own process, its main().
    broken = tmp_path / 'broken.world'
    broken.write_text('<sdf version="1.6"><world name="w"><model name="m"><link name="l">'
                      '</model></world></sdf>')
    done = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.ros.bridge', '--ros-args', '-p',
         parameter.format(broken=broken)], capture_output=True, text=True, timeout=120,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='OFF'))
    assert done.returncode == 1
    [line] = [line for line in done.stderr.splitlines() if not line.startswith('[INFO]')]
    assert line.startswith('sim_bridge: cannot start: ') and said in line, done.stderr


def test_robot_pose_parameter_places_the_robot(session):
    _, pose = first_pose(session, robot_pose=[1.0, -1.0, 0.5])
    assert pose == pytest.approx((1.0, -1.0, 0.5))


@pytest.fixture
def spawned_robot(monkeypatch):
    """
    Put the test's model folders on GZ_SIM_RESOURCE_PATH, as a Gazebo user does.

    ``little_bot``: a 0.2 m box with a 0..2 pi lidar of 360 beams at 5 Hz in frame base_scan.
    """
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(MODELS))


def test_robot_parameter_spawns_a_model_at_robot_pose(session, spawned_robot):
    bridge = session.bridge(world='obstacles', robot='little_bot', robot_pose=[1.0, -1.0, 0.5])
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.3)
    assert bridge.sim.world.robot.name == 'little_bot'
    assert bridge.sim.world.robot.radius == pytest.approx(math.hypot(0.1, 0.1))
    assert bridge.sim.pose == pytest.approx((1.0, -1.0, 0.5))
    (t, scan), = scans                                    # its lidar: 5 Hz, 360 beams
    assert t == 200 * MS
    assert (scan.header.frame_id, len(scan.ranges)) == ('base_scan', 360)


def test_robot_and_robot_pose_as_live_gives_them_on_the_command_line(session, spawned_robot):
    spec = live.bridge_spec('obstacles', robot='little_bot', robot_pose=(0.5, -1.0, 1.5))
    bridge = session.bridge(cli_args=list(spec.cmd[spec.cmd.index('--ros-args'):]))
    assert bridge.sim.world.robot.name == 'little_bot'
    assert bridge.sim.pose == pytest.approx((0.5, -1.0, 1.5))


def test_robot_parameter_alone_spawns_at_the_worlds_start(session, spawned_robot):
    bridge = session.bridge(world='wall_follow_box', robot='little_bot')
    assert bridge.sim.pose == pytest.approx(World.load('wall_follow_box').robot_start)


@pytest.mark.parametrize('params, error, match', [
    ({'robot': 'no_such_bot'}, ValueError, "model 'no_such_bot' not found"),
    ({'robot': 'little_bot', 'robot_pose': [2.5, 0.0, 0.0]}, ValueError,
     "overlaps obstacle 'cube'"),
    ({'robot_pose': [1.0, 2.0]}, ValueError, r"'robot_pose' must be \[x, y, yaw\]"),
])
def test_a_robot_that_cannot_be_spawned_is_one_clear_error(params, error, match, session,
                                                           spawned_robot):
    with pytest.raises(error, match=match):
        session.bridge(world='obstacles', **params)


def test_what_the_world_cannot_simulate_is_logged_once_at_start(session, monkeypatch, logs):
    robot_world(monkeypatch, ignored='ignored: 1 light, plugin gz-sim-imu-system')
    session.bridge()
    session.run_for(0.5)
    said = [record.msg for record in logs
            if record.name == 'sim_bridge' and record.msg.startswith('ignored: ')]
    assert said == ['ignored: 1 light, plugin gz-sim-imu-system']


def test_the_worlds_physics_step_sets_the_physics_rate_unless_the_parameter_does(
        session, monkeypatch):
    robot_world(monkeypatch, physics_step_s=0.004)
    assert session.bridge().step_ns == 4 * MS
    assert session.bridge(namespace='given', physics_rate=50.0).step_ns == 20 * MS


def test_parameters_on_the_command_line_as_ros2_run_gives_them(session):
    bridge = session.bridge(cli_args=['--ros-args', '-p', 'world:=wall_follow_box',
                                      '-p', 'robot_pose:=[1.0, -1.0, 0.5]',
                                      '-p', 'max_linear_speed:=0.5'])
    assert bridge.sim.world.name == 'wall_follow_box'
    assert bridge.sim.pose == pytest.approx((1.0, -1.0, 0.5))
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(1.0), 0.5)
    assert bridge.sim.command == (0.5, 0.0)


def test_same_seed_gives_identical_scans_and_another_seed_does_not(session):
    probe = session.probe()
    scans = {}
    for namespace, seed in (('a', 7), ('b', 7), ('c', 8)):
        session.bridge(namespace=namespace, seed=seed)
        scans[namespace] = session.listen(probe, LaserScan, f'/{namespace}/scan')
    session.run_for(1.0)
    ranges = {namespace: [list(scan.ranges) for _, scan in received]
              for namespace, received in scans.items()}
    assert len(ranges['a']) == 10
    assert ranges['a'] == ranges['b']
    assert all(first != other for first, other in zip(ranges['a'], ranges['c']))


def test_lidar_parameters_override_the_robot_model(session):
    session.bridge(lidar_samples=360, lidar_noise_stddev=0.0)
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.3)
    (_, first), *_, (_, last) = scans
    assert len(first.ranges) == 360
    assert first.angle_increment == pytest.approx(
        (first.angle_max - first.angle_min) / 359, rel=1e-6)
    # Without noise a standing robot sees the same scan every time.
    assert list(first.ranges) == list(last.ranges)


def test_lidar_noise_is_on_by_default(session):
    session.bridge()
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.2)
    (_, first), (_, second) = scans
    assert list(first.ranges) != list(second.ranges)


@pytest.mark.parametrize('name, value', [
    ('seed', 1.5), ('physics_rate', 100), ('cmd_vel_timeout', 1), ('cmd_vel_stamped', 'true'),
    ('world', 3), ('robot_pose', [0, 0, 0]), ('max_linear_speed', 1)])
def test_parameter_of_the_wrong_type_raises_as_rclpy_does(name, value, session):
    with pytest.raises(InvalidParameterTypeException, match=f"parameter '{name}'"):
        session.bridge(**{name: value})


def test_an_int_rate_on_the_command_line_is_the_wrong_type(session):
    # `-p physics_rate:=100` is an integer to rclpy; the parameter is a double.
    with pytest.raises(InvalidParameterTypeException, match="parameter 'physics_rate'"):
        session.bridge(cli_args=['--ros-args', '-p', 'physics_rate:=100'])


@pytest.mark.parametrize('value', [0.0, -10.0, math.inf, math.nan])
@pytest.mark.parametrize('name', ['physics_rate', 'odom_rate', 'real_time_factor'])
def test_rate_parameters_must_be_positive_and_finite(name, value, session):
    with pytest.raises(ValueError, match=f"'{name}' must be positive and finite"):
        session.bridge(**{name: value})


def test_drive_limits_must_be_positive(session):
    with pytest.raises(ValueError, match='max_linear_speed must be a positive finite number'):
        session.bridge(max_linear_speed=-1.0)


def published_times(session, msg_type, topic, seconds):
    """Run the bridges for ``seconds``; return the sim times (ns) and messages on ``topic``."""
    received = session.listen(session.probe(), msg_type, topic)
    session.run_for(seconds)
    return [t for t, _ in received], [msg for _, msg in received]


def test_a_30_hz_lidar_on_100_hz_physics_sends_30_scans_a_second_each_saying_when(
        session, monkeypatch, logs):
    world = World.load('obstacles')
    robot_world(monkeypatch, lidar=replace(world.robot.lidar, update_rate=30.0))
    session.bridge()
    times, scans = published_times(session, LaserScan, 'scan', 3.0)
    assert len(times) == 90
    # Each scan at the first physics step at or after n / 30 s, stamped with that step's time.
    assert times == [math.ceil(n * NANOSECONDS_PER_SECOND / 30 / STEP_NS) * STEP_NS
                     for n in range(1, 91)]
    assert [stamp_ns(scan.header.stamp) for scan in scans] == times
    assert [scan.scan_time for scan in scans] == pytest.approx(
        [(t - previous) / NANOSECONDS_PER_SECOND for previous, t in zip([0] + times, times)])
    assert {scan.time_increment for scan in scans} == {0.0}
    assert warnings_of(logs) == []


def test_a_rate_above_the_physics_rate_is_warned_of_and_sent_every_step(session, logs):
    session.bridge(odom_rate=30.0, physics_rate=25.0)
    times, _ = published_times(session, Odometry, 'odom', 2.0)
    assert len(times) == 50                      # 25 Hz physics: one odometry per step
    session.spin()
    assert warnings_of(logs) == [
        'odom_rate 30 Hz is above physics_rate 25 Hz: publishing every physics step, at 25 Hz']


@pytest.mark.parametrize('rate, seconds, count', [(30.0, 2.0, 60), (7.0, 3.0, 21),
                                                  (50.0, 1.0, 50)])
def test_odometry_comes_at_its_rate_on_average(rate, seconds, count, session):
    session.bridge(odom_rate=rate)
    times, _ = published_times(session, Odometry, 'odom', seconds)
    assert len(times) == count
    assert times[-1] == round(seconds * NANOSECONDS_PER_SECOND)


def test_the_installed_params_file_holds_the_nodes_own_defaults(session):
    shipped = yaml.safe_load(PARAMS_FILE.read_text())['sim_bridge']['ros__parameters']
    bridge = session.bridge()
    for name, value in shipped.items():
        default = bridge.get_parameter(name).value
        assert (type(value), value) == (type(default), default), name


def test_the_installed_params_file_starts_the_bridge(session):
    # As `ros2 run sim_bridge sim_bridge --ros-args --params-file sim.yaml` does.
    bridge = session.bridge(cli_args=['--ros-args', '--params-file', str(PARAMS_FILE)])
    assert bridge.get_parameter('world').value == 'obstacles'
    session.run_for(0.1)
    assert bridge.now_ns == SCAN_PERIOD_NS


def test_ctrl_c_while_the_world_loads_ends_the_bridge_cleanly(monkeypatch):
    # As `ros2 run` or `ros2 launch` stopping it before its first step: no traceback, and rclpy
    # shut down, as when Ctrl-C comes while it spins.
    def interrupted_while_loading():
        assert rclpy.ok()
        raise KeyboardInterrupt

    monkeypatch.setattr(bridge_module, 'SimBridge', interrupted_while_loading)
    bridge_module.main(args=[])
    assert not rclpy.ok()


def test_after_a_publish_sinks_take_it_without_a_wait_and_any_other_callback_spins(session):
    # A relay (not a sink) republishes /a on /b: only the wait after its callback finds the
    # sink's /b subscription ready. Sinks alone leave nothing ready.
    relay, sink = session.add(rclpy.create_node('relay')), session.add(rclpy.create_node('sink'))
    session.executor.own_nodes |= {relay, sink}
    session.executor.sink_nodes.add(sink)
    relayed = relay.create_publisher(String, 'b', 10)
    relay.create_subscription(String, 'a', relayed.publish, 10)
    heard_a, heard_b = [], []
    sink.create_subscription(String, 'a', lambda msg: heard_a.append(msg.data), 10)
    sink.create_subscription(String, 'b', lambda msg: heard_b.append(msg.data), 10)
    source = session.probe('source')
    to_a, to_b = (source.create_publisher(String, topic, 10) for topic in ('a', 'b'))
    session.spin()
    to_a.publish(String(data='first'))
    assert spin_after_publishing(session.executor, {'/a'}) == 3  # relay, sink, then sink
    assert (heard_a, heard_b) == (['first'], ['first'])
    to_b.publish(String(data='second'))
    assert spin_after_publishing(session.executor, {'/b'}) == 1
    assert heard_b == ['first', 'second'] and session.spin() == 0


def test_a_live_bridge_latches_the_robot_and_the_worlds_obstacles_for_rviz(session):
    """What params/lab.rviz displays: /robot_description and /world_markers, in odom."""
    bridge = session.bridge(stepped=False, world='obstacles', robot_pose=[0.5, -0.2, 0.7])
    probe = session.probe()  # joins later: the messages are kept for it
    descriptions = session.listen(probe, String, 'robot_description', LATCHED)
    markers = session.listen(probe, MarkerArray, 'world_markers', LATCHED)
    deadline = time.monotonic() + 10.0
    while not (descriptions and markers) and time.monotonic() < deadline:
        session.executor.spin_once(timeout_sec=0.1)
    robot = urdf.URDF.from_xml_string(descriptions[0][1].data)
    laser = next(joint for joint in robot.joints if joint.child == bridge.frames['laser'])
    (static,) = [transform for transform in bridge.static_transforms()
                 if transform.child_frame_id == bridge.frames['laser']]
    assert laser.parent == bridge.frames['base_link'] == static.header.frame_id
    offset = static.transform.translation
    assert laser.origin.xyz == pytest.approx([offset.x, offset.y, offset.z], abs=1e-6)
    assert len(robot.link_map[laser.parent].visuals) == len(bridge.sim.world.robot.shapes)
    shapes = bridge.sim.world.shapes()
    (array,) = [msg for _, msg in markers]
    rviz = yaml.safe_load((Path(__file__).parents[1] / 'params' / 'lab.rviz').read_text())
    topics = {(display.get('Topic') or display.get('Description Topic'))['Value']
              for display in rviz['Visualization Manager']['Displays']
              if 'Topic' in display or 'Description Topic' in display}
    assert topics == {'/robot_description', '/world_markers', '/scan', '/odom'}
    assert all(bridge.get_publishers_info_by_topic(topic) for topic in topics)
    assert len(array.markers) == len(shapes) > 0
    for marker, shape in zip(array.markers, shapes):
        assert marker.header.frame_id == bridge.frames['odom']
        x, y, z, *_ = relative_pose((0.5, -0.2, 0.0, 0.0, 0.0, 0.7), shape_pose(shape))
        position = marker.pose.position
        assert (position.x, position.y, position.z) == pytest.approx((x, y, z))


def test_a_stepped_bridge_publishes_nothing_for_rviz(session):
    bridge = session.bridge()
    assert not bridge.get_publishers_info_by_topic('/robot_description')
    assert not bridge.get_publishers_info_by_topic('/world_markers')
