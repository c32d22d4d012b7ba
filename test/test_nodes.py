"""
The five scan_pkg nodes driven through rclpy: the lockstep runtime, and real rclpy when present.

Each test is written against the rclpy API only and runs once per backend (the ``ros``
fixture): 'lockstep' always, 'rclpy' when a real rclpy is importable without the runtime (a ROS 2
Jazzy machine). A node's log is read through a recording logger patched onto it, so both
backends are observed alike, and time advances only through ``spin_once(timeout_sec=...)``: sim
time on lockstep, a bounded wait on ROS. Running a node's ``main()`` needs a horizon to end it,
so those tests run on lockstep only.
"""

from contextlib import contextmanager, nullcontext
import importlib
import importlib.util
import math
import sys
from typing import Callable, Iterator

import numpy as np
import pytest

from sim_bridge import lockstep
from sim_bridge.lockstep import messages

REAL_RCLPY = not lockstep.installed() and importlib.util.find_spec('rclpy') is not None
BACKENDS = ['lockstep', pytest.param('rclpy', marks=pytest.mark.skipif(
    not REAL_RCLPY, reason='no real rclpy here (ROS 2 Jazzy is not installed); these tests '
    'run against it on a ROS machine'))]

# The modules of these packages belong to one backend: rclpy, tf2_ros, the message packages,
# and scan_pkg, whose node modules bind rclpy's names when imported.
BACKEND_PACKAGES = frozenset(['rclpy', 'tf2_ros', 'scan_pkg', *messages.packages()])
# Real rclpy is imported once and put back for each of its tests: a C extension cannot be
# imported afresh, and the lockstep runtime will not install while real rclpy is imported.
_real_ros_modules: dict = {}

SPIN_TIMEOUT_S = 0.05
MAX_SPINS = 100

# The lab's scanner: 36 beams from -1.57 to +1.57 rad; beams 17 and 18 are the two nearest
# straight ahead (+-2.6 deg), beam 0 points right (-90 deg) and beam 35 left (+90 deg).
BEAMS, ANGLE_MIN, ANGLE_MAX = 36, -1.57, 1.57
RANGE_MIN, RANGE_MAX = 0.12, 10.0
INF, NAN = math.inf, math.nan

SCAN_NODES = {'scan_ahead': 'ScanAhead', 'scan_around': 'ScanAround',
              'closest_obstacle': 'ClosestObstacle'}
DRIVING_NODES = {'wanderbot': 'Wanderbot', 'wall_follow': 'WallFollow'}


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


def laser_scan(ranges, **fields):
    """Return a sensor_msgs/msg/LaserScan of the current backend from the lab's scanner."""
    from sensor_msgs.msg import LaserScan
    beams = len(ranges)
    message = {'angle_min': ANGLE_MIN, 'angle_max': ANGLE_MAX,
               'angle_increment': (ANGLE_MAX - ANGLE_MIN) / max(beams - 1, 1),
               'range_min': RANGE_MIN, 'range_max': RANGE_MAX}
    message.update(fields)
    msg = LaserScan(**message)
    msg.header.frame_id = 'laser'
    msg.ranges = [float(value) for value in ranges]
    return msg


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

    def has(self, level: str, *words: str) -> bool:
        """Tell whether a record of ``level`` contains every one of ``words``."""
        return any(record_level == level and all(word in text for word in words)
                   for record_level, text in self.records)


def record_logs(node) -> RecordingLogger:
    """Make ``node.get_logger()`` return a new recording logger, and return that."""
    recorder = RecordingLogger()
    node.get_logger = lambda: recorder
    return recorder


def twist_values(msg) -> list:
    """Return the six numbers of a Twist or a TwistStamped message."""
    twist = getattr(msg, 'twist', msg)
    return [twist.linear.x, twist.linear.y, twist.linear.z,
            twist.angular.x, twist.angular.y, twist.angular.z]


class Session:
    """
    One test's ROS session on one backend: init, the nodes made, spinning, and shutdown.

    Uses the rclpy API only. Every node made through it is added to one executor and destroyed
    at the end.
    """

    def __init__(self, backend: str):
        self.backend = backend
        self.rclpy = importlib.import_module('rclpy')
        self.executor = None
        self._nodes = []

    def start(self, *ros_args: str) -> None:
        """Call rclpy.init with ``--ros-args ros_args`` (none: no arguments)."""
        from rclpy.executors import SingleThreadedExecutor
        self.rclpy.init(args=['--ros-args', *ros_args] if ros_args else [])
        self.executor = SingleThreadedExecutor()

    def add(self, node):
        """Spin ``node`` with the others and destroy it at the end; return it."""
        self._nodes.append(node)
        self.executor.add_node(node)
        return node

    def make(self, node_module: str):
        """Construct the node of ``scan_pkg.<node_module>`` (imported on this backend)."""
        module = importlib.import_module(f'scan_pkg.{node_module}')
        return self.add(getattr(module, {**SCAN_NODES, **DRIVING_NODES}[node_module])())

    def test_node(self, name: str):
        """Construct a plain rclpy Node for the test's own publishers and subscriptions."""
        from rclpy.node import Node
        return self.add(Node(name))

    def spin_until(self, condition: Callable[[], bool]) -> bool:
        """Spin until ``condition()`` holds, at most MAX_SPINS times; tell whether it held."""
        for _ in range(MAX_SPINS):
            self.executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
            if condition():
                return True
        return False

    def publish_until(self, node, publications: Callable[[], None],
                      condition: Callable[[], bool]) -> bool:
        """
        Spin with ``node`` calling ``publications()`` every spin timeout until ``condition()``.

        Publishing again and again, as a sensor does, reaches a best-effort subscription even
        when DDS drops a message or discovery is not complete.
        """
        timer = node.create_timer(SPIN_TIMEOUT_S, publications)
        try:
            return self.spin_until(condition)
        finally:
            node.destroy_timer(timer)

    def close(self) -> None:
        """Destroy the nodes, shut the executor and rclpy down."""
        for node in reversed(self._nodes):
            node.destroy_node()
        if self.executor is not None:
            self.executor.shutdown()
        self.rclpy.try_shutdown()


def _take_backend_modules() -> dict:
    taken = {name: module for name, module in sys.modules.items()
             if name.partition('.')[0] in BACKEND_PACKAGES}
    for name in taken:
        del sys.modules[name]
    return taken


@contextmanager
def backend_session(backend: str) -> Iterator[Session]:
    """Give the block a Session on ``backend`` with its own modules; restore the others after."""
    real = backend == 'rclpy'
    outside = _take_backend_modules()
    if real:
        # ROS modules found outside are real ones: the runtime is only ever installed in here.
        _real_ros_modules.update({name: module for name, module in outside.items()
                                  if not name.startswith('scan_pkg')})
        sys.modules.update(_real_ros_modules)
    try:
        with nullcontext() if real else lockstep.installed_runtime():
            session = Session(backend)
            try:
                yield session
            finally:
                session.close()
    finally:
        inside = _take_backend_modules()
        if real:
            _real_ros_modules.update({name: module for name, module in inside.items()
                                      if not name.startswith('scan_pkg')})
        sys.modules.update(outside)


@pytest.fixture(params=BACKENDS)
def ros(request) -> Iterator[Session]:
    """Give a Session on each backend: lockstep always, real rclpy where it is installed."""
    with backend_session(request.param) as session:
        yield session


@pytest.fixture
def lockstep_ros() -> Iterator[Session]:
    """Give a Session on the lockstep runtime only."""
    with backend_session('lockstep') as session:
        yield session


# --- the scan-reading nodes ----------------------------------------------------------------------

def scan_node_with_source(ros, node_module: str, *ros_args: str):
    """
    Start rclpy, the node under test with its log recorded, and a test node to feed it scans.

    Returns the log and ``send(msg, condition)``, which publishes ``msg`` on /scan (reliable)
    until ``condition()`` holds and tells whether it did.
    """
    from sensor_msgs.msg import LaserScan
    ros.start(*ros_args)
    log = record_logs(ros.make(node_module))
    source = ros.test_node('scan_source')
    publisher = source.create_publisher(LaserScan, 'scan', 10)

    def send(msg, condition: Callable[[], bool]) -> bool:
        return ros.publish_until(source, lambda: publisher.publish(msg), condition)

    return log, send


@pytest.mark.parametrize('node_module', SCAN_NODES)
def test_scan_node_logs_its_line_for_a_known_scan(ros, node_module):
    log, send = scan_node_with_source(ros, node_module)
    line = REFERENCE_LINES[node_module]
    assert send(laser_scan(reference_ranges()), lambda: log.has('INFO', line))
    assert {level for level, _ in log.records} == {'INFO'}


@pytest.mark.parametrize('node_module, line', [
    ('scan_ahead', 'Range ahead: 1.00 m'),
    ('scan_around', 'right: 0.80 m | front-right: 1.00 m | front: 1.00 m | front-left: 1.00 m '
                    '| left: 1.00 m'),
])
def test_max_range_parameter_caps_the_logged_ranges(ros, node_module, line):
    log, send = scan_node_with_source(ros, node_module, '-p', 'max_range:=1.0')
    assert send(laser_scan(reference_ranges()), lambda: log.has('INFO', line))


@pytest.mark.parametrize('node_module', ['scan_ahead', 'scan_around'])
def test_an_integer_max_range_is_refused_at_construction_as_jazzy_does(ros, node_module):
    from rclpy.exceptions import InvalidParameterTypeException
    ros.start('-p', 'max_range:=5')
    with pytest.raises(InvalidParameterTypeException):
        ros.make(node_module)


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
@pytest.mark.parametrize('node_module', SCAN_NODES)
def test_scan_node_reports_a_bad_scan_and_carries_on(ros, node_module, bad_scan):
    make_msg, warning, lines = BAD_SCANS[bad_scan]
    line = None if lines is None else lines[node_module]
    log, send = scan_node_with_source(ros, node_module)
    assert send(make_msg(), lambda: (warning is None or log.has('WARN', *warning)) and
                (line is None or log.has('INFO', line))), log.records
    assert {text for level, text in log.records if level == 'INFO'} == (
        set() if line is None else {line})
    assert all(level == 'WARN' for level, _ in log.records if level != 'INFO')
    assert (warning is None) == (not log.has('WARN'))
    # Still alive: the next good scan is handled as ever.
    assert send(laser_scan(reference_ranges()),
                lambda: log.has('INFO', REFERENCE_LINES[node_module]))


def test_scans_reach_the_node_from_best_effort_and_reliable_publishers(ros):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import LaserScan
    ros.start()
    log = record_logs(ros.make('scan_ahead'))
    source = ros.test_node('scan_source')
    best_effort = source.create_publisher(
        LaserScan, 'scan', QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    reliable = source.create_publisher(
        LaserScan, 'scan', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    for publisher, ahead in ((best_effort, 1.5), (reliable, 2.5)):
        msg = laser_scan(reference_ranges(ahead))
        assert ros.publish_until(source, lambda: publisher.publish(msg),
                                 lambda: log.has('INFO', f'Range ahead: {ahead:.2f} m'))


# --- the driving nodes -------------------------------------------------------------------------

def cmd_vel_type(stamped: bool):
    """Return the class of the cmd_vel messages: TwistStamped if ``stamped``, else Twist."""
    from geometry_msgs.msg import Twist, TwistStamped
    return TwistStamped if stamped else Twist


def odometry(yaw: float):
    """Return a nav_msgs/msg/Odometry of the current backend, heading ``yaw`` (rad)."""
    from nav_msgs.msg import Odometry
    msg = Odometry()
    msg.header.frame_id = 'odom'
    msg.child_frame_id = 'base_link'
    msg.pose.pose.orientation.z = math.sin(yaw / 2.0)
    msg.pose.pose.orientation.w = math.cos(yaw / 2.0)
    return msg


@pytest.mark.parametrize('stamped', [False, True], ids=['twist', 'stamped'])
@pytest.mark.parametrize('node_module, speed', [('wanderbot', 0.25), ('wall_follow', 0.2)])
def test_driving_node_publishes_float_velocity_commands(ros, node_module, speed, stamped):
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan
    ros.start('-p', f'speed:={speed}', '-p', f'stamped:={str(stamped).lower()}')
    ros.make(node_module)
    test_node = ros.test_node('base')
    scans = test_node.create_publisher(LaserScan, 'scan', 10)
    odom = test_node.create_publisher(Odometry, 'odom', 10)
    commands = []
    test_node.create_subscription(cmd_vel_type(stamped), 'cmd_vel', commands.append, 10)
    # A straight wall 0.5 m on the right and nothing ahead: both drive on at full speed.
    scan = laser_scan(room_ranges(ahead=INF, right=0.5))

    def publish_sensors():
        scans.publish(scan)
        odom.publish(odometry(0.0))

    assert ros.publish_until(
        test_node, publish_sensors,
        lambda: len(commands) >= 5 and twist_values(commands[-1])[0] > 0.0)
    for command in commands:
        assert type(command) is cmd_vel_type(stamped)
        assert [type(value) for value in twist_values(command)] == [float] * 6
    assert max(twist_values(command)[0] for command in commands) == pytest.approx(speed)
    if stamped:
        assert any(command.header.stamp.sec or command.header.stamp.nanosec
                   for command in commands)


SCAN_PERIOD_S = 0.1
ODOM_PERIOD_S = 0.05
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


def start_fake_base(stamped: bool):
    """
    Start a node in its own context standing in for the robot: noisy scans, odometry of yaw.

    The yaw (rad) integrates the commanded turn rate, so a turn measured on /odom ends.
    """
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.node import Node
    from sensor_msgs.msg import LaserScan
    context = Context()
    context.init(args=[])
    node = Node('fake_base', context=context)
    clock = node.get_clock()
    rng = np.random.default_rng(7)
    scans = node.create_publisher(LaserScan, 'scan', 10)
    odom = node.create_publisher(Odometry, 'odom', 10)
    state = {'yaw': 0.0, 'angular': 0.0}

    def on_cmd_vel(msg):
        state['angular'] = twist_values(msg)[5]

    def on_scan_timer():
        time = clock.now().nanoseconds * 1e-9
        scans.publish(laser_scan(noisy_room_ranges(time, rng)))

    def on_odom_timer():
        state['yaw'] += state['angular'] * ODOM_PERIOD_S
        odom.publish(odometry(state['yaw']))

    node.create_subscription(cmd_vel_type(stamped), 'cmd_vel', on_cmd_vel, 10)
    node.create_timer(SCAN_PERIOD_S, on_scan_timer)
    node.create_timer(ODOM_PERIOD_S, on_odom_timer)
    return context, node


@pytest.mark.usefixtures('lockstep_ros')
@pytest.mark.parametrize('stamped', [False, True], ids=['twist', 'stamped'])
@pytest.mark.parametrize('node_module', DRIVING_NODES)
def test_driving_node_main_runs_30_s_of_noisy_scans_and_stops_the_robot_last(
        node_module, stamped):
    runtime = lockstep.runtime()
    runtime.set_log_sink(lambda record: None)
    published = []

    def record_cmd_vel(topic, msg, t_ns):
        # A tap reads the message during the publish: it keeps what it needs, not the message.
        published.append((type(msg), twist_values(msg), t_ns))

    runtime.add_tap(record_cmd_vel, topics=['/cmd_vel'])
    context, fake_base = start_fake_base(stamped)
    horizon_ns = int(RUN_S * 1e9)
    runtime.set_horizon(horizon_ns)
    module = importlib.import_module(f'scan_pkg.{node_module}')
    try:
        # A publish of a wrong-typed field would raise out of main() here.
        module.main(args=['--ros-args', '-p', f'stamped:={str(stamped).lower()}'])
    finally:
        fake_base.destroy_node()
        context.try_shutdown()
    commands = [values for _, values, _ in published]
    assert {msg_type for msg_type, _, _ in published} == {cmd_vel_type(stamped)}
    assert all(type(value) is float for values in commands for value in values)
    # It drove and it turned: the changing scans took it through more than one behaviour.
    assert any(values[0] > 0.0 for values in commands)
    assert any(values[5] != 0.0 for values in commands)
    # Driving on along the wall at the end, then the stop at shutdown, at the horizon.
    stop, stop_ns = commands[-1], published[-1][2]
    assert stop == [0.0] * 6 and stop_ns == horizon_ns
    assert commands[-2][0] > 0.0
