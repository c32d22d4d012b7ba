"""
The five scan_pkg nodes on real rclpy, stepped: every callback runs before the test goes on.

In one process Fast DDS delivers a publish before ``publish()`` returns, so a test publishes,
then runs every ready callback with ``sim_bridge.runner.stepping.spin_until_idle`` and checks what
happened: no waiting on the wall clock, and exactly one callback per message. Time is sim time
(``use_sim_time``, /clock published by the test) wherever a node reads its clock. A node's log
is read through a recording logger patched onto it. Field checks are on
(``ROS_PYTHON_CHECK_FIELDS=1``): an int or a numpy scalar in a float field of a published
message raises in the node's callback instead of arriving as garbage.
"""

import math
import sys

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.time import Time
from rclpy.utilities import get_default_context
from rosgraph_msgs.msg import Clock as ClockMsg
from scan_pkg.closest_obstacle import ClosestObstacle
from scan_pkg.scan_ahead import ScanAhead
from scan_pkg.scan_around import ScanAround
from scan_pkg.wall_follow import WallFollow
from scan_pkg.wanderbot import Wanderbot
from sensor_msgs.msg import LaserScan
from sim_bridge.common.run_environment import run_environment
from sim_bridge.runner.stepping import spin_until_idle, SteppedExecutor

# The lab's scanner: 36 beams from -1.57 to +1.57 rad; beams 17 and 18 are the two nearest
# straight ahead (+-2.6 deg), beam 0 points right (-90 deg) and beam 35 left (+90 deg).
BEAMS, ANGLE_MIN, ANGLE_MAX = 36, -1.57, 1.57
RANGE_MIN, RANGE_MAX = 0.12, 10.0
INF, NAN = math.inf, math.nan

SCAN_NODES = {'scan_ahead': ScanAhead, 'scan_around': ScanAround,
              'closest_obstacle': ClosestObstacle}
DRIVING_NODES = {'wanderbot': Wanderbot, 'wall_follow': WallFollow}

NS_PER_S = 1_000_000_000
#: Period (ns) of the test's clock ticks: the wanderbot's default control period (20 Hz).
TICK_NS = 50_000_000


def reference_ranges(ahead: float = 1.23) -> list:
    """Return ranges (m): an obstacle ``ahead`` m straight ahead, 0.80 m right, 2.50 m left."""
    ranges = [INF] * BEAMS
    ranges[17] = ranges[18] = ahead
    ranges[0] = 0.8
    ranges[35] = 2.5
    return ranges


REFERENCE_LINES = {
    'scan_ahead': 'Range ahead: 1.23 m',
    'scan_around': 'right: 0.80 m | front-right: 10.00 m | front: 1.23 m | front-left: 10.00 m '
                   '| left: 2.50 m',
    'closest_obstacle': 'Closest obstacle: 0.80 m at -90.0 deg',
}


def room_ranges(ahead: float, right: float, beams: int = BEAMS) -> np.ndarray:
    """
    Return the lab scanner's ranges (m) between walls ``ahead`` m in front, ``right`` m right.

    Either distance may be inf (no wall); returns beyond range_max are +inf.
    """
    angles = np.linspace(ANGLE_MIN, ANGLE_MAX, beams)
    with np.errstate(divide='ignore'):
        to_front = np.where(np.cos(angles) > 0.0, ahead / np.cos(angles), INF)
        to_right = np.where(np.sin(angles) < 0.0, right / -np.sin(angles), INF)
    ranges = np.minimum(to_front, to_right)
    ranges[ranges > RANGE_MAX] = INF
    return ranges


def laser_scan(ranges, **fields) -> LaserScan:
    """Return a sensor_msgs/msg/LaserScan of the lab's scanner with ``ranges`` (m)."""
    beams = len(ranges)
    message = {'angle_min': ANGLE_MIN, 'angle_max': ANGLE_MAX,
               'angle_increment': (ANGLE_MAX - ANGLE_MIN) / max(beams - 1, 1),
               'range_min': RANGE_MIN, 'range_max': RANGE_MAX}
    message.update(fields)
    msg = LaserScan(**message)
    msg.header.frame_id = 'laser'
    msg.ranges = [float(value) for value in ranges]
    return msg


def odometry(yaw: float) -> Odometry:
    """Return a nav_msgs/msg/Odometry heading ``yaw`` (rad)."""
    msg = Odometry()
    msg.header.frame_id = 'odom'
    msg.child_frame_id = 'base_link'
    msg.pose.pose.orientation.z = math.sin(yaw / 2.0)
    msg.pose.pose.orientation.w = math.cos(yaw / 2.0)
    return msg


def clock(time_ns: int) -> ClockMsg:
    """Return a rosgraph_msgs/msg/Clock at ``time_ns`` (ns)."""
    return ClockMsg(clock=Time(nanoseconds=time_ns).to_msg())


def cmd_vel_type(stamped: bool) -> type:
    """Return the class of the cmd_vel messages: TwistStamped if ``stamped``, else Twist."""
    return TwistStamped if stamped else Twist


def twist_values(msg) -> list:
    """Return the six numbers of a Twist or a TwistStamped message."""
    twist = getattr(msg, 'twist', msg)
    return [twist.linear.x, twist.linear.y, twist.linear.z,
            twist.angular.x, twist.angular.y, twist.angular.z]


def stamp_ns(msg) -> int:
    """Return the header stamp (ns) of a stamped message."""
    return msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec


class RecordingLogger:
    """
    Stands in for a node's rclpy logger and records ``(level, text)`` of every call.

    It accepts what an rclpy logger accepts (a str, rclpy's filter options) and ignores the
    filters, so every warning a node attempts is seen.
    """

    FILTERS = {'throttle_duration_sec', 'throttle_time_source_type', 'skip_first', 'once'}

    def __init__(self):
        self.records = []

    def _log(self, level: str, message, **options) -> bool:
        if not isinstance(message, str):
            raise TypeError(f'rclpy logs str messages only, got {type(message).__name__}')
        unknown = set(options) - self.FILTERS
        if unknown:
            raise TypeError(f'unknown logging options {sorted(unknown)}')
        self.records.append((level, message))
        return True

    def debug(self, message, **options) -> bool:
        return self._log('DEBUG', message, **options)

    def info(self, message, **options) -> bool:
        return self._log('INFO', message, **options)

    def warn(self, message, **options) -> bool:
        return self._log('WARN', message, **options)

    def warning(self, message, **options) -> bool:
        return self._log('WARN', message, **options)

    def error(self, message, **options) -> bool:
        return self._log('ERROR', message, **options)

    def fatal(self, message, **options) -> bool:
        return self._log('FATAL', message, **options)

    def levels(self) -> list:
        """Return the level of every record, in order."""
        return [level for level, _ in self.records]

    def has(self, level: str, *words: str) -> bool:
        """Tell whether a record of ``level`` contains every one of ``words``."""
        return any(record_level == level and all(word in text for word in words)
                   for record_level, text in self.records)


def record_logs(node: Node) -> RecordingLogger:
    """Make ``node.get_logger()`` return a new recording logger, and return that."""
    recorder = RecordingLogger()
    node.get_logger = lambda: recorder
    return recorder


class Session:
    """
    One test's ROS session: rclpy.init, the nodes made, stepping, and shutdown.

    Every node made through it is added to one executor and destroyed at the end.
    """

    def __init__(self):
        self.executor = None
        self._nodes = []

    def start(self, *ros_args: str) -> None:
        """Call rclpy.init with ``--ros-args ros_args``, no signal handlers (pytest's own)."""
        rclpy.init(args=['--ros-args', *ros_args],
                   signal_handler_options=SignalHandlerOptions.NO)
        self.executor = SteppedExecutor(get_default_context())

    def add(self, node: Node) -> Node:
        """Spin ``node`` with the others and destroy it at the end; return it."""
        self._nodes.append(node)
        self.executor.add_node(node)
        return node

    def make(self, node_class: type) -> Node:
        """Construct a node of ``node_class`` as its ``main()`` does, and spin it."""
        return self.add(node_class())

    def helper(self, name: str) -> Node:
        """Construct a plain rclpy Node for the test's own publishers and subscriptions."""
        return self.add(Node(name))

    def step(self) -> int:
        """Run every ready callback until none is ready; return how many ran."""
        return spin_until_idle(self.executor)

    def close(self) -> None:
        """Destroy the nodes, shut the executor and rclpy down."""
        for node in reversed(self._nodes):
            node.destroy_node()
        if self.executor is not None:
            self.executor.shutdown()
        rclpy.try_shutdown()


@pytest.fixture(autouse=True)
def field_checks():
    """Turn rosidl's field type checks on, as runs do; shut rclpy down after the test."""
    with run_environment(field_checks=True):
        try:
            yield
        finally:
            rclpy.try_shutdown()


@pytest.fixture
def ros():
    """Give the test a Session, closed after it."""
    session = Session()
    try:
        yield session
    finally:
        session.close()


def test_field_checks_refuse_an_int_in_a_float_field():
    # Without them the float checks below could not fail: an int would be sent as garbage.
    with pytest.raises(AssertionError, match="'x' field must be of type 'float'"):
        Twist().linear.x = 1


# --- the scan-reading nodes ----------------------------------------------------------------------

def scan_node_with_source(ros: Session, node_name: str, *ros_args: str):
    """
    Start rclpy, the node under test with its log recorded, and a test node to feed it scans.

    Returns the log and ``send(msg)``, which publishes ``msg`` on /scan (reliable) and runs
    every callback it makes ready.
    """
    ros.start(*ros_args)
    log = record_logs(ros.make(SCAN_NODES[node_name]))
    publisher = ros.helper('scan_source').create_publisher(LaserScan, 'scan', 10)

    def send(msg: LaserScan) -> None:
        publisher.publish(msg)
        ros.step()

    return log, send


@pytest.mark.parametrize('node_name', SCAN_NODES)
def test_scan_node_logs_its_line_for_a_known_scan(ros, node_name):
    log, send = scan_node_with_source(ros, node_name)
    send(laser_scan(reference_ranges()))
    assert log.records == [('INFO', REFERENCE_LINES[node_name])]
    send(laser_scan(reference_ranges()))
    assert log.records == [('INFO', REFERENCE_LINES[node_name])] * 2


@pytest.mark.parametrize('node_name, line', [
    ('scan_ahead', 'Range ahead: 1.00 m'),
    ('scan_around', 'right: 0.80 m | front-right: 1.00 m | front: 1.00 m | front-left: 1.00 m '
                    '| left: 1.00 m'),
])
def test_max_range_parameter_caps_the_logged_ranges(ros, node_name, line):
    log, send = scan_node_with_source(ros, node_name, '-p', 'max_range:=1.0')
    send(laser_scan(reference_ranges()))
    assert log.records == [('INFO', line)]


@pytest.mark.parametrize('node_name', ['scan_ahead', 'scan_around'])
def test_an_integer_max_range_is_refused_at_construction_as_jazzy_does(ros, node_name):
    ros.start('-p', 'max_range:=5')
    with pytest.raises(InvalidParameterTypeException):
        ros.make(SCAN_NODES[node_name])


HUNDRED_THOUSAND = 100_000
TOO_CLOSE_LINES = {
    'scan_ahead': 'Range ahead: 0.12 m',
    'scan_around': 'right: 0.12 m | front-right: 0.12 m | front: 0.12 m | front-left: 0.12 m '
                   '| left: 0.12 m',
    'closest_obstacle': 'No valid obstacle readings.',
}
# For each bad scan: the words of the warning naming the problem (None: no warning), and each
# node's line (None: no line, as the scan tells nothing).
BAD_SCANS = {
    'empty': (lambda: laser_scan([]), ('no ranges',), None),
    'all-inf': (lambda: laser_scan([INF] * BEAMS), None, {
        'scan_ahead': 'Range ahead: 10.00 m',
        'scan_around': 'right: 10.00 m | front-right: 10.00 m | front: 10.00 m | '
                       'front-left: 10.00 m | left: 10.00 m',
        'closest_obstacle': 'No valid obstacle readings.'}),
    'all-nan': (lambda: laser_scan([NAN] * BEAMS), ('no valid reading', '36 NaN'), None),
    # Too close to measure: an obstacle at range_min, never free space.
    'all-minus-inf': (lambda: laser_scan([-INF] * BEAMS),
                      ('no valid reading', '36 -inf (too close)'), TOO_CLOSE_LINES),
    'negative': (lambda: laser_scan([-1.0] * BEAMS),
                 ('no valid reading', '36 outside [0.12, 10] m'), TOO_CLOSE_LINES),
    'zero-increment': (lambda: laser_scan(reference_ranges(), angle_increment=0.0),
                       ('malformed', 'angle_increment', '> 0'), None),
    'nan-angle-min': (lambda: laser_scan(reference_ranges(), angle_min=NAN),
                      ('malformed', 'angle_min', 'nan'), None),
    '100000-beams': (lambda: laser_scan([2.0] * HUNDRED_THOUSAND), None, {
        'scan_ahead': 'Range ahead: 2.00 m',
        'scan_around': 'right: 2.00 m | front-right: 2.00 m | front: 2.00 m | '
                       'front-left: 2.00 m | left: 2.00 m',
        'closest_obstacle': 'Closest obstacle: 2.00 m at -90.0 deg'}),
}


@pytest.mark.parametrize('bad_scan', BAD_SCANS)
@pytest.mark.parametrize('node_name', SCAN_NODES)
def test_scan_node_reports_a_bad_scan_and_carries_on(ros, node_name, bad_scan):
    make_msg, warning, lines = BAD_SCANS[bad_scan]
    line = None if lines is None else lines[node_name]
    log, send = scan_node_with_source(ros, node_name)
    # A callback that raised would fail here with sim_bridge.runner.stepping.NodeError.
    send(make_msg())
    # One warning naming the problem, if any, then the node's line, if the scan tells one.
    assert log.levels() == ['WARN'] * (warning is not None) + ['INFO'] * (line is not None), (
        log.records)
    assert warning is None or log.has('WARN', *warning), log.records
    assert line is None or log.has('INFO', line), log.records
    # Still alive: the next good scan is handled as ever.
    log.records.clear()
    send(laser_scan(reference_ranges()))
    assert log.records == [('INFO', REFERENCE_LINES[node_name])]


def test_scans_reach_the_node_from_best_effort_and_reliable_publishers(ros):
    ros.start()
    log = record_logs(ros.make(ScanAhead))
    source = ros.helper('scan_source')
    best_effort = source.create_publisher(
        LaserScan, 'scan', QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    reliable = source.create_publisher(
        LaserScan, 'scan', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    for publisher, ahead in ((best_effort, 1.5), (reliable, 2.5)):
        log.records.clear()
        publisher.publish(laser_scan(reference_ranges(ahead)))
        ros.step()
        assert log.records == [('INFO', f'Range ahead: {ahead:.2f} m')]


# --- the driving nodes -------------------------------------------------------------------------

def bool_arg(value: bool) -> str:
    """Return ``value`` as a --ros-args parameter value."""
    return str(value).lower()


@pytest.mark.parametrize('stamped', [False, True], ids=['twist', 'stamped'])
@pytest.mark.parametrize('node_name, speed', [('wanderbot', 0.25), ('wall_follow', 0.2)])
def test_driving_node_publishes_float_velocity_commands(ros, node_name, speed, stamped):
    ros.start('-p', f'speed:={speed}', '-p', f'stamped:={bool_arg(stamped)}',
              '-p', 'use_sim_time:=true')
    ros.make(DRIVING_NODES[node_name])
    base = ros.helper('base')
    clock_publisher = base.create_publisher(ClockMsg, '/clock', 10)
    scans = base.create_publisher(LaserScan, 'scan', 10)
    odom = base.create_publisher(Odometry, 'odom', 10)
    commands = []
    base.create_subscription(cmd_vel_type(stamped), 'cmd_vel', commands.append, 10)
    # A straight wall 0.5 m on the right and nothing ahead: both drive on at full speed.
    scan = laser_scan(room_ranges(ahead=INF, right=0.5))
    ticks_ns = [TICK_NS * step for step in range(1, 11)]
    for time_ns in ticks_ns:
        clock_publisher.publish(clock(time_ns))
        scans.publish(scan)
        odom.publish(odometry(0.0))
        ros.step()
    # One command per tick: the wanderbot's timer at 20 Hz, the wall follower's per scan. A
    # received message always holds floats: an int or a numpy scalar in a published one fails
    # the field check in the node's callback, and step() raises NodeError.
    assert len(commands) == len(ticks_ns)
    for command in commands:
        assert type(command) is cmd_vel_type(stamped)
        assert twist_values(command)[0] > 0.0
    assert max(twist_values(command)[0] for command in commands) == pytest.approx(speed)
    if stamped:
        # Stamped with the node's clock (sim time) when the command was made.
        assert [stamp_ns(command) for command in commands] == ticks_ns


SCAN_PERIOD_S = 0.1
ODOM_PERIOD_S = TICK_NS / NS_PER_S
RUN_S = 30.0
CLEAR_FROM_S = 26.0


def noisy_room_ranges(time: float, rng: np.random.Generator) -> np.ndarray:
    """
    Return the ranges (m) of a changing room at ``time`` (s), 1 cm noise, 5 % dropouts (NaN).

    A wall 0.5 m on the right; a wall ahead coming from 2.4 m to 0.4 m and back every 6 s
    (blocking the way, an inside corner) until CLEAR_FROM_S, then nothing ahead; now and then
    a scan with no ranges or only NaN.
    """
    step = round(time / SCAN_PERIOD_S)
    if step % 47 == 13:
        return np.array([])
    if step % 53 == 7:
        return np.full(BEAMS, NAN)
    ahead = INF if time >= CLEAR_FROM_S else 0.4 + 2.0 * abs((time % 6.0) / 3.0 - 1.0)
    ranges = room_ranges(ahead, 0.5)
    finite = np.isfinite(ranges)
    ranges[finite] += rng.normal(0.0, 0.01, finite.sum())
    ranges[rng.random(BEAMS) < 0.05] = NAN
    return ranges


@pytest.mark.parametrize('stamped', [False, True], ids=['twist', 'stamped'])
@pytest.mark.parametrize('node_name', DRIVING_NODES)
def test_driving_node_drives_30_s_of_noisy_scans(ros, node_name, stamped):
    ros.start('-p', f'stamped:={bool_arg(stamped)}', '-p', 'use_sim_time:=true')
    log = record_logs(ros.make(DRIVING_NODES[node_name]))
    # The robot's base: noisy scans at 10 Hz, odometry at 20 Hz of the yaw (rad) integrated
    # from the commanded turn rate, so a turn measured on /odom ends.
    base = ros.helper('fake_base')
    clock_publisher = base.create_publisher(ClockMsg, '/clock', 10)
    scans = base.create_publisher(LaserScan, 'scan', 10)
    odom = base.create_publisher(Odometry, 'odom', 10)
    rng = np.random.default_rng(7)
    state = {'yaw': 0.0, 'angular': 0.0}
    commands = []

    def on_cmd_vel(msg):
        assert type(msg) is cmd_vel_type(stamped)
        commands.append(twist_values(msg))
        state['angular'] = twist_values(msg)[5]

    base.create_subscription(cmd_vel_type(stamped), 'cmd_vel', on_cmd_vel, 10)
    scan_every = round(SCAN_PERIOD_S / ODOM_PERIOD_S)
    for step in range(1, round(RUN_S / ODOM_PERIOD_S) + 1):
        time_ns = step * TICK_NS
        clock_publisher.publish(clock(time_ns))
        state['yaw'] += state['angular'] * ODOM_PERIOD_S
        odom.publish(odometry(state['yaw']))
        if step % scan_every == 0:
            scans.publish(laser_scan(noisy_room_ranges(time_ns / NS_PER_S, rng)))
        # A callback that raised (on a bad scan, on a non-float field of a command it
        # published) fails here with NodeError.
        ros.step()
    assert commands
    # It drove and it turned: the changing scans took it through more than one behaviour.
    assert any(values[0] > 0.0 for values in commands)
    assert any(values[5] != 0.0 for values in commands)
    # Driving on along the wall at the end, when nothing is ahead any more.
    assert commands[-1][0] > 0.0
    # The scans with no ranges and with only NaN were reported, not fatal.
    assert log.has('WARN', 'no ranges') and log.has('WARN', 'NaN')


#: Commands the node under main() sends before the test presses Ctrl-C.
COMMANDS_BEFORE_CTRL_C = 5
#: Longest wall-clock time (s) main() may spin before the test gives up on it.
MAIN_TIMEOUT_S = 5.0


@pytest.mark.parametrize('stamped', [False, True], ids=['twist', 'stamped'])
@pytest.mark.parametrize('node_name', DRIVING_NODES)
def test_driving_node_main_stops_the_robot_on_ctrl_c(monkeypatch, node_name, stamped):
    node_class = DRIVING_NODES[node_name]
    published = []  # (message type, the six values as published, ROS time in ns)
    main_node = []

    class NodeUnderMain(node_class):
        """
        The node as main() makes it, fed by itself: a clear wall, a clock tick per command.

        Its cmd_vel publishes are recorded as they are made (the last one, the stop, is sent
        after the spinning ends, when no subscription callback can run); after
        COMMANDS_BEFORE_CTRL_C commands, KeyboardInterrupt is raised in the publishing
        callback, as Ctrl-C does with rclpy's signal handler off.
        """

        def __init__(self):
            super().__init__()
            main_node.append(self)
            cmd_vel, = (publisher for publisher in self.publishers
                        if publisher.topic_name == '/cmd_vel')
            publish_cmd_vel = cmd_vel.publish
            cmd_vel.publish = lambda msg: self.on_cmd_vel(publish_cmd_vel, msg)
            self.clock_publisher = self.create_publisher(ClockMsg, '/clock', 10)
            self.scans = self.create_publisher(LaserScan, 'scan', 10)
            self.odom = self.create_publisher(Odometry, 'odom', 10)
            self.create_timer(MAIN_TIMEOUT_S, self.time_out,
                              clock=Clock(clock_type=ClockType.STEADY_TIME))
            self.feed(TICK_NS)

        def feed(self, time_ns: int) -> None:
            self.clock_publisher.publish(clock(time_ns))
            self.scans.publish(laser_scan(room_ranges(ahead=INF, right=0.5)))
            self.odom.publish(odometry(0.0))

        def on_cmd_vel(self, publish, msg) -> None:
            publish(msg)
            time_ns = self.get_clock().now().nanoseconds
            published.append((type(msg), twist_values(msg), time_ns))
            if len(published) == COMMANDS_BEFORE_CTRL_C:
                raise KeyboardInterrupt
            if len(published) < COMMANDS_BEFORE_CTRL_C:
                self.feed((len(published) + 1) * TICK_NS)

        def time_out(self) -> None:
            raise TimeoutError(f'main() spun {MAIN_TIMEOUT_S} s: {len(published)} commands')

    module = sys.modules[node_class.__module__]
    monkeypatch.setattr(module, node_class.__name__, NodeUnderMain)
    try:
        # A publish of a wrong-typed field would raise out of main() here.
        module.main(args=['--ros-args', '-p', f'stamped:={bool_arg(stamped)}',
                          '-p', 'use_sim_time:=true'])
    except KeyboardInterrupt:
        pytest.fail('Ctrl-C (KeyboardInterrupt) escaped from main()')
    assert len(main_node) == 1
    assert not rclpy.ok()
    assert {msg_type for msg_type, _, _ in published} == {cmd_vel_type(stamped)}
    assert all(type(value) is float for _, values, _ in published for value in values)
    # It drove along the wall, then sent the stop last, at once (no sim time passed).
    *commands, (_, stop, stop_ns) = published
    assert len(commands) == COMMANDS_BEFORE_CTRL_C
    assert all(values[0] > 0.0 for _, values, _ in commands)
    assert [time_ns for _, _, time_ns in commands] == [
        TICK_NS * step for step in range(1, COMMANDS_BEFORE_CTRL_C + 1)]
    assert stop == [0.0] * 6 and stop_ns == commands[-1][2]
