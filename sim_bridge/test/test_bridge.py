"""
The sim_bridge node (bridge.py) in the lockstep runtime, seen from a node that uses it.

A probe node subscribes and publishes the way a lab node or ``ros2 topic pub`` would; the
runtime is stepped with ``run_until``, so every check is at an exact sim time.
"""

import math
from pathlib import Path
import shutil

import numpy as np
import pytest
import yaml

from sim_bridge import lockstep
from sim_bridge.paths import find_world
from sim_bridge.robot import DriveLimits
from sim_bridge.simulator import Simulator
from sim_bridge.world import World

NANOSECONDS_PER_SECOND = 10 ** 9
STEP_NS = NANOSECONDS_PER_SECOND // 100     # the default physics_rate, 100 Hz
SCAN_PERIOD_NS = NANOSECONDS_PER_SECOND // 10
ODOM_PERIOD_NS = NANOSECONDS_PER_SECOND // 50
COMMAND_PERIOD_S = 0.1                       # how often the probe repeats a command


class Session:
    """A lockstep runtime with rclpy initialised, and the nodes a test starts in it."""

    def __init__(self, runtime):
        self.runtime = runtime
        self.nodes = []

    def bridge(self, namespace=None, **params):
        """Start a SimBridge with ``params`` as parameter overrides."""
        from rclpy.parameter import Parameter
        from sim_bridge.bridge import SimBridge
        node = SimBridge(namespace=namespace, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()])
        self.nodes.append(node)
        return node

    def probe(self, name='probe'):
        """Start a plain node, as ``rclpy.create_node`` gives a user."""
        import rclpy
        node = rclpy.create_node(name)
        self.nodes.append(node)
        return node

    def listen(self, node, msg_type, topic, qos=10):
        """Subscribe ``node`` to ``topic``; return the list of (sim time ns, msg) it receives."""
        received = []
        node.create_subscription(
            msg_type, topic, lambda msg: received.append((self.runtime.now_ns, msg)), qos)
        return received

    def run_for(self, seconds):
        """Advance sim time by ``seconds``, running every callback due."""
        self.runtime.run_until(self.runtime.now_ns + round(seconds * NANOSECONDS_PER_SECOND))

    def drive(self, publisher, message, seconds):
        """Publish ``message`` now and every COMMAND_PERIOD_S for ``seconds``, like teleop."""
        for _ in range(round(seconds / COMMAND_PERIOD_S)):
            publisher.publish(message)
            self.run_for(COMMAND_PERIOD_S)


@pytest.fixture
def session():
    """Install the lockstep runtime and init rclpy; destroy the nodes and uninstall after."""
    with lockstep.installed_runtime() as runtime:
        import rclpy
        rclpy.init(args=[])
        started = Session(runtime)
        try:
            yield started
        finally:
            for node in started.nodes:
                node.destroy_node()
            rclpy.try_shutdown()


@pytest.fixture
def logs(session):
    """Collect the log records of the test's nodes."""
    records = []
    session.runtime.set_log_sink(records.append)
    return records


def twist(linear, angular=0.0):
    """Return a geometry_msgs/Twist command (m/s, rad/s)."""
    from geometry_msgs.msg import Twist
    message = Twist()
    message.linear.x = float(linear)
    message.angular.z = float(angular)
    return message


def periodic_times(period_ns, end_ns):
    """Return the times (ns) of something happening every ``period_ns`` up to ``end_ns``."""
    return list(range(period_ns, end_ns + 1, period_ns))


def stamp_ns(stamp):
    """Return a builtin_interfaces/Time as ns."""
    return stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec


def yaw_of(quaternion):
    """Return the yaw (rad) of a rotation about z."""
    return math.atan2(2.0 * (quaternion.w * quaternion.z + quaternion.x * quaternion.y),
                      1.0 - 2.0 * (quaternion.y ** 2 + quaternion.z ** 2))


def warnings_of(logs, node_name='sim_bridge'):
    """Return the texts of the WARN records of ``node_name``."""
    return [record.text for record in logs if record.level == 'WARN' and
            record.name == node_name]


def ramp_loss(speed, accel):
    """Return the distance (m) lost accelerating from rest to ``speed`` (m/s) at ``accel``."""
    return speed ** 2 / (2.0 * accel)


# --- what the bridge publishes ---------------------------------------------------------------

def test_clock_is_published_every_physics_step_with_the_sim_time(session):
    from rosgraph_msgs.msg import Clock
    session.bridge()
    clocks = session.listen(session.probe(), Clock, '/clock')
    session.run_for(0.5)
    assert [t for t, _ in clocks] == periodic_times(STEP_NS, NANOSECONDS_PER_SECOND // 2)
    assert [stamp_ns(msg.clock) for t, msg in clocks] == [t for t, _ in clocks]


def test_scan_is_published_at_the_lidar_rate_in_the_laser_frame(session):
    from sensor_msgs.msg import LaserScan
    session.bridge()
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(1.0)
    assert [t for t, _ in scans] == periodic_times(SCAN_PERIOD_NS, NANOSECONDS_PER_SECOND)
    for t, scan in scans:
        assert stamp_ns(scan.header.stamp) == t
        assert scan.header.frame_id == 'laser'


def test_scan_has_the_labs_geometry(session):
    from sensor_msgs.msg import LaserScan
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


def test_scan_is_reliable_depth_10_and_reaches_best_effort_and_reliable_subscribers(session):
    from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import LaserScan
    bridge = session.bridge()
    assert bridge.scan_pub.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    assert bridge.scan_pub.qos_profile.depth == 10
    probe = session.probe()
    best_effort = session.listen(probe, LaserScan, 'scan', qos_profile_sensor_data)
    reliable = session.listen(probe, LaserScan, 'scan', QoSProfile(depth=10))
    session.run_for(1.0)
    assert len(best_effort) == len(reliable) == 10


def test_scan_ranges_are_the_simulators(session):
    from sensor_msgs.msg import LaserScan
    session.bridge(seed=5)
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.2)
    with Simulator('obstacles', seed=5) as simulator:
        for _, scan in scans:
            for _ in range(SCAN_PERIOD_NS // STEP_NS):
                simulator.step(STEP_NS / NANOSECONDS_PER_SECOND)
            expected = np.asarray(simulator.scan().ranges, dtype=np.float32)
            assert np.array_equal(np.asarray(scan.ranges, dtype=np.float32), expected)


def test_odometry_and_tf_follow_the_simulated_robot(session):
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    from tf2_msgs.msg import TFMessage
    bridge = session.bridge()
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'odom')
    transforms = session.listen(probe, TFMessage, '/tf')
    session.drive(probe.create_publisher(Twist, 'cmd_vel', 10), twist(0.2, 0.5), 1.0)
    assert [t for t, _ in odometry] == periodic_times(ODOM_PERIOD_NS, NANOSECONDS_PER_SECOND)
    t, odom = odometry[-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    assert stamp_ns(odom.header.stamp) == t
    x, y, yaw = bridge.sim.pose
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (x, y)
    assert yaw_of(odom.pose.pose.orientation) == pytest.approx(yaw, abs=1e-9)
    assert (odom.twist.twist.linear.x, odom.twist.twist.angular.z) == bridge.sim.velocity
    assert bridge.sim.velocity == pytest.approx((0.2, 0.5))
    assert [t for t, _ in transforms] == [t for t, _ in odometry]
    for (_, odom), (_, message) in zip(odometry, transforms):
        (transform,) = message.transforms
        assert (transform.header.frame_id, transform.child_frame_id) == ('odom', 'base_link')
        assert transform.header.stamp == odom.header.stamp
        assert (transform.transform.translation.x, transform.transform.translation.y) == \
            (odom.pose.pose.position.x, odom.pose.pose.position.y)
        assert transform.transform.rotation == odom.pose.pose.orientation


def test_static_laser_transform_reaches_a_late_transient_local_subscriber(session):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from tf2_msgs.msg import TFMessage
    bridge = session.bridge()
    session.run_for(0.5)
    probe = session.probe()
    latched = session.listen(probe, TFMessage, '/tf_static',
                             QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    volatile = session.listen(probe, TFMessage, '/tf_static', QoSProfile(depth=100))
    session.run_for(0.5)
    (_, message), = latched
    (transform,) = message.transforms
    assert (transform.header.frame_id, transform.child_frame_id) == ('base_link', 'laser')
    laser = bridge.sim.lidar_config.pose
    offset = transform.transform.translation
    assert (offset.x, offset.y, offset.z) == pytest.approx(laser[:3])
    assert yaw_of(transform.transform.rotation) == pytest.approx(laser[5])
    assert volatile == []


def test_frame_parameters_rename_the_frames(session):
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import LaserScan
    from tf2_msgs.msg import TFMessage
    session.bridge(odom_frame='world', base_link_frame='base_footprint', laser_frame='base_scan')
    probe = session.probe()
    scans = session.listen(probe, LaserScan, 'scan')
    odometry = session.listen(probe, Odometry, 'odom')
    static = session.listen(probe, TFMessage, '/tf_static',
                            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    session.run_for(0.1)
    assert scans[0][1].header.frame_id == 'base_scan'
    assert (odometry[0][1].header.frame_id, odometry[0][1].child_frame_id) == \
        ('world', 'base_footprint')
    (transform,) = static[0][1].transforms
    assert (transform.header.frame_id, transform.child_frame_id) == \
        ('base_footprint', 'base_scan')


# --- cmd_vel ---------------------------------------------------------------------------------

def test_twist_drives_the_robot_forward(session):
    from geometry_msgs.msg import Twist
    bridge = session.bridge()
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(0.2), 1.0)
    x, y, yaw = bridge.sim.pose
    assert x == pytest.approx(0.2 * 1.0 - ramp_loss(0.2, DriveLimits().max_linear_accel),
                              abs=1e-9)
    assert (y, yaw) == (0.0, 0.0)


def test_twist_stamped_drives_a_bridge_with_cmd_vel_stamped(session):
    from geometry_msgs.msg import TwistStamped
    bridge = session.bridge(cmd_vel_stamped=True)
    probe = session.probe()
    publisher = probe.create_publisher(TwistStamped, 'cmd_vel', 10)
    command = TwistStamped(twist=twist(0.2))
    command.header.stamp = probe.get_clock().now().to_msg()
    session.drive(publisher, command, 1.0)
    assert bridge.sim.pose[0] == pytest.approx(
        0.2 - ramp_loss(0.2, DriveLimits().max_linear_accel), abs=1e-9)


def test_twist_publisher_on_a_stamped_bridge_is_a_topic_type_error(session):
    from geometry_msgs.msg import Twist
    session.bridge(cmd_vel_stamped=True)
    # DDS would never connect the two; the lockstep runtime says so at once.
    with pytest.raises(lockstep.TopicTypeError, match=r'/cmd_vel.*geometry_msgs/msg/Twist'):
        session.probe().create_publisher(Twist, 'cmd_vel', 10)


@pytest.mark.parametrize('timeout_s', [0.5, 1.0])
def test_robot_stops_when_commands_stop_for_cmd_vel_timeout(timeout_s, session):
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    bridge = session.bridge(cmd_vel_timeout=timeout_s)
    probe = session.probe()
    odometry = session.listen(probe, Odometry, 'odom')
    probe.create_publisher(Twist, 'cmd_vel', 10).publish(twist(0.2))
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
    from geometry_msgs.msg import Twist
    bridge = session.bridge()
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(0.2), 1.0)
    assert bridge.sim.velocity[0] == pytest.approx(0.2)
    session.drive(publisher, twist(linear, angular), 0.5)
    assert bridge.sim.command == (0.0, 0.0)
    assert bridge.sim.velocity == (0.0, 0.0)
    # Five bad commands in 0.5 s: the warning is throttled to one a second.
    (warning,) = warnings_of(logs)
    assert warning.startswith('cmd_vel: rejected command') and 'not a finite number' in warning


@pytest.mark.parametrize('linear, angular, limit', [
    (1e9, 0.0, (DriveLimits().max_linear_speed, 0.0)),
    (-1e9, 0.0, (-DriveLimits().max_linear_speed, 0.0)),
    (0.0, 1e9, (0.0, DriveLimits().max_angular_speed)),
])
def test_huge_command_is_clamped_with_a_warning(linear, angular, limit, session, logs):
    from geometry_msgs.msg import Twist
    bridge = session.bridge()
    publisher = session.probe().create_publisher(Twist, 'cmd_vel', 10)
    session.drive(publisher, twist(linear, angular), 1.0)
    assert bridge.sim.command == limit
    assert bridge.sim.velocity == pytest.approx(limit)
    (warning,) = warnings_of(logs)
    assert warning.startswith('cmd_vel: clamped command')


def test_collision_is_logged_and_published(session, logs):
    from geometry_msgs.msg import PointStamped, Twist
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


# --- parameters ------------------------------------------------------------------------------

def first_pose(session, **params):
    """Start a bridge with ``params`` and return (bridge, the pose of its first odometry)."""
    from nav_msgs.msg import Odometry
    bridge = session.bridge(**params)
    odometry = session.listen(session.probe(), Odometry, 'odom')
    session.run_for(ODOM_PERIOD_NS / NANOSECONDS_PER_SECOND)
    pose = odometry[0][1].pose.pose
    return bridge, (pose.position.x, pose.position.y, yaw_of(pose.orientation))


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


def test_start_pose_parameter_places_the_robot(session):
    _, pose = first_pose(session, start_pose=[1.0, -1.0, 0.5])
    assert pose == pytest.approx((1.0, -1.0, 0.5))


def test_same_seed_gives_identical_scans_and_another_seed_does_not(session):
    from sensor_msgs.msg import LaserScan
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
    from sensor_msgs.msg import LaserScan
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
    from sensor_msgs.msg import LaserScan
    session.bridge()
    scans = session.listen(session.probe(), LaserScan, 'scan')
    session.run_for(0.2)
    (_, first), (_, second) = scans
    assert list(first.ranges) != list(second.ranges)


@pytest.mark.parametrize('name, value', [
    ('seed', 1.5), ('physics_rate', 100), ('cmd_vel_timeout', 1), ('cmd_vel_stamped', 'true'),
    ('world', 3), ('start_pose', [0, 0, 0])])
def test_parameter_of_the_wrong_type_raises_as_rclpy_does(name, value, session):
    from rclpy.exceptions import InvalidParameterTypeException
    with pytest.raises(InvalidParameterTypeException, match=f"parameter '{name}'"):
        session.bridge(**{name: value})


@pytest.mark.parametrize('name', ['physics_rate', 'odom_rate', 'real_time_factor'])
def test_rate_parameters_must_be_positive(name, session):
    with pytest.raises(ValueError, match=f"'{name}' must be positive"):
        session.bridge(**{name: 0.0})


def test_a_rate_the_physics_cannot_keep_is_warned_of_with_the_rate_kept(session):
    warnings = []
    session.runtime.set_log_sink(lambda record: warnings.append(record.text))
    bridge = session.bridge(physics_rate=25.0, odom_rate=25.0)
    assert (bridge.steps_per_scan, bridge.steps_per_odom) == (2, 1)
    assert warnings == ['lidar update_rate 10 Hz is not physics_rate 25 Hz divided by a whole '
                        'number: publishing every 2 steps, at 12.5 Hz']


def test_the_installed_params_file_holds_the_nodes_own_defaults(session):
    path = Path(__file__).resolve().parents[1] / 'params' / 'sim.yaml'
    shipped = yaml.safe_load(path.read_text())['sim_bridge']['ros__parameters']
    bridge = session.bridge()
    for name, value in shipped.items():
        default = bridge.get_parameter(name).value
        assert (type(value), value) == (type(default), default), name
