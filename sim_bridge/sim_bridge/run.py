"""
Run unmodified rclpy nodes against the simulator in one process, on simulated time.

``python -m sim_bridge.run --world wall_follow_box --node wall_follow --duration 60`` runs the
SimBridge node and the named nodes on real rclpy in one process, stepped (every ready callback
runs before physics advances, see sim_bridge.stepping), as if each had been started with
``ros2 run ... --ros-args --params-file <out>/params.yaml -p use_sim_time:=true``, then writes
``metrics.json``, ``trajectory.png`` and a rosbag2 recording ``run/`` (MCAP) to ``--out``.
"""

import argparse
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass
import difflib
import functools
import json
import math
import os
from pathlib import Path
import resource
import shutil
import signal
import sys
import tempfile
import threading
import time
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.parameter import get_parameter_value, Parameter, parameter_value_to_python
from rclpy.serialization import serialize_message
from sim_bridge.drive import check_obstacles, DriveError, DrivePlan, parse_drive, Segment
from sim_bridge.hints import printed_scan_hint, ros_module_hint, scan_hint
from sim_bridge.live import LiveRun, prefixed, print_line, process_names
from sim_bridge.metrics import compute_metrics
from sim_bridge.node_output import (
    LOG_FILE, NodeLog, OutputCapture, rosout_message, ROSOUT_TOPIC, ROSOUT_TYPE,
    terminal_colours, to_terminal, write_log)
from sim_bridge.node_styles import Decision
from sim_bridge.paths import find_world
from sim_bridge.plot import plot_trajectory
from sim_bridge.process_run import (
    DomainReservation, last_traceback, node_spec, NODE_START_TIMEOUT_S, OUTPUT_TAIL_LINES,
    printed_error, private_ros_environment, process_environment)
from sim_bridge.record import BagRecorder, DEFAULT_TOPICS, message_type_name
from sim_bridge.report_text import json_safe
from sim_bridge.run_environment import (
    FIELD_CHECK_HINT, is_field_check_failure, run_environment)
from sim_bridge.run_trace import CollisionEvent, ScanSnapshot, Trace
from sim_bridge.scenario import EVERY_NODE, is_seed, MAX_SEED, remap_problem, target_name
from sim_bridge.simulation.world import World, WorldError
from sim_bridge.stepping import (
    describe, next_timer_ns, NodeEnded, NodeError, spin_until_idle, SteppedExecutor)
from sim_bridge.targets import (
    module_file, node_command, split_target, StudentCode, TargetError)
import yaml

BRIDGE_NODE = 'sim_bridge'
#: SimBridge parameters the runner alone sets: the world and robot the metrics are scored in,
#: the seed and gui options, the robot's start pose, and the pace (a run is on sim time; --gui
#: paces it).
RUNNER_BRIDGE_PARAMETERS = ('world', 'robot', 'robot_pose', 'seed', 'gui', 'real_time_factor')
#: The node parameter wall_distance_m is measured against when the run is given no setpoint.
SETPOINT_PARAMETER = 'distance'
#: ROS's own topics of every node (and /clock, of every use_sim_time node): a node's use of
#: them says nothing about how it is wired to the simulator.
ROS_TOPICS = ('/rosout', '/parameter_events', '/clock')
PROGRESS_AFTER_S = 2.0
GUI_FRAME_RATE = 60
#: The runner's teleop node (a scenario's ``drive:``), and how often (Hz of sim time) it
#: publishes the command, as a held key of teleop_twist_keyboard repeats it.
TELEOP_NODE = 'teleop'
TELEOP_RATE_HZ = 20.0
#: A process run stamps a line when it arrives; its node, on a busy machine behind the live
#: simulator, may be printing about a scan it had queued this long (s) before.
PROCESS_LINE_LATENESS_S = 0.5
NANOSECONDS_PER_SECOND = 10 ** 9
#: How every run runs its target nodes (sim_bridge.stepped_run).
STEPPED_REASON = ('its main() runs as ros2 run starts it, in a process of its own, in lockstep '
                  'with the simulator')
#: Longest wait (wall s) for a node run as a process to list its parameters.
PARAMETER_ANSWER_S = 2.0

Params = dict[str, dict[str, Any]]
# The runner's own nodes serve nothing: the service is one more entity in every wait.
NO_TYPE_DESCRIPTION_SERVICE = Parameter('start_type_description_service', value=False)


class RunError(Exception):
    """
    A run that could not start: unknown world, bad target or parameter, bad output folder.

    ``traceback`` is the node's part of the traceback when its code failed (a node file that
    fails to import), else None.
    """

    def __init__(self, message: str, traceback: str | None = None):
        super().__init__(message)
        self.traceback = traceback


class RunStopped(BaseException):
    """
    Raised into a run by whoever supervises it (the grader's watchdog); the text says why.

    A BaseException, so that a node's ``except Exception`` does not swallow it: the run ends
    as a failed one with its outputs written, naming the node code that was running.
    """


@dataclass
class RunResult:
    """What a run measured (``metrics``, as in metrics.json) and where its outputs are."""

    metrics: dict
    out_dir: Path

    @property
    def ok(self) -> bool:
        """Return True when the run completed without a node raising."""
        return not self.metrics['node_errors']


def parse_param(text: str) -> tuple[str, str, Any]:
    """
    Split ``NODE:NAME=VALUE`` into node name, parameter name and typed value.

    VALUE is typed as ``--ros-args -p NAME:=VALUE`` types it (YAML: ``1`` is an integer,
    ``1.0`` a double, ``true`` a bool, ``[1.0, 2.0]`` a double array).
    """
    node, colon, rest = text.partition(':')
    name, equals, value = rest.partition('=')
    if not (colon and equals and node and name):
        raise RunError(f"--param '{text}': expected NODE:NAME=VALUE, "
                       'e.g. wall_follow:distance=0.6')
    return node, name, parameter_value_to_python(get_parameter_value(value))


def check_remap(rule: str) -> str:
    """Return ``rule`` when it reads as a ROS remapping rule, else raise a one-line RunError."""
    problem = remap_problem(rule)
    if problem is not None:
        raise RunError(f'--remap {problem}')
    return rule


def gui_problem(environ: Mapping[str, str], platform: str = sys.platform) -> str | None:
    """
    Return why ``--gui`` cannot open the pybullet window here, or None.

    On Linux the window needs an X display (pybullet's GUI speaks X11, XWayland included);
    without one pybullet ends the whole process with 'cannot connect to X server'.
    """
    if platform.startswith('linux') and not environ.get('DISPLAY'):
        return ('--gui needs a display, and DISPLAY is not set (a terminal without one, e.g. '
                'over ssh): run without --gui, or under xvfb-run')
    return None


def nearest_topic(topic: str, topics: Iterable[str]) -> str | None:
    """Return the topic of ``topics`` most like ``topic``: of the same last name, else by text."""
    topics = sorted(topics)
    base = topic.rpartition('/')[2]
    same = [candidate for candidate in topics if candidate.rpartition('/')[2] == base]
    near = same or difflib.get_close_matches(topic, topics, n=1)
    return near[0] if near else None


def parameter_warnings(params: Params, declared: dict[str, set[str] | None],
                       targets: Iterable[str]) -> list[str]:
    """
    Return a warning for each node in ``params`` not running, and each parameter not declared.

    ``declared`` holds the parameter names each running node declared, by node name (the
    simulator's among them; None for a node that did not say: nothing is warned of it);
    ``targets`` names the target nodes. ROS ignores a params file's entry for a node that is
    not running, and rclpy an override of a parameter a node never declares: a misspelt name
    would otherwise grade the default in silence. A parameter for every node (EVERY_NODE) is
    one that none of the target nodes declares.
    """
    targets = list(targets)
    absent = [name for name in params if name not in declared and name != EVERY_NODE]
    warnings = [f"parameters given for node(s) {', '.join(absent)}, but the nodes are "
                f"{', '.join(declared)}; they were ignored"] if absent else []
    for node_name, values in params.items():
        for name in values:
            if name == 'use_sim_time' or node_name in absent or (
                    node_name == BRIDGE_NODE and name in RUNNER_BRIDGE_PARAMETERS):
                continue
            if node_name == EVERY_NODE:
                names = [declared[target] for target in targets]
                if None not in names and not any(name in each for each in names):
                    warnings.append(f"no node declared parameter '{name}' (given for every "
                                    f'node, {EVERY_NODE}); it was ignored')
            elif declared[node_name] is not None and name not in declared[node_name]:
                warnings.append(f"node '{node_name}' did not declare parameter '{name}' "
                                '(given by --param or the params file); it was ignored')
    return warnings


def call_service(client_node, service_type: type, service: str, request: Any,
                 timeout_s: float) -> Any | None:
    """
    Call ``service`` from ``client_node`` (whose executor spins in another thread), bounded.

    Return the response, or None when the service does not answer within ``timeout_s`` (wall
    s) to wait for it, and as long again to answer.
    """
    client = client_node.create_client(service_type, service)
    try:
        if not client.wait_for_service(timeout_sec=timeout_s):
            return None
        answered = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: answered.set())
        return future.result() if answered.wait(timeout_s) else None
    finally:
        client_node.destroy_client(client)


def declared_parameters(client_node, nodes: Iterable[tuple[str, str]],
                        timeout_s: float) -> dict[str, set[str] | None]:
    """
    Return the names of the parameters each of ``nodes`` declared, asked over ROS.

    ``nodes`` are (name, namespace) of nodes in another process; each is asked with its own
    ``list_parameters`` service (as ``ros2 param list`` asks it) from ``client_node``. A node
    that does not answer within ``timeout_s`` (wall s; no parameter services, or a main() that
    does not spin) is None.
    """
    from rcl_interfaces.srv import ListParameters
    declared = {}
    for name, namespace in nodes:
        response = call_service(client_node, ListParameters,
                                f"{namespace.rstrip('/')}/{name}/list_parameters",
                                ListParameters.Request(), timeout_s)
        declared[name] = None if response is None else set(response.result.names)
    return declared


def parameter_of(client_node, nodes: Iterable[tuple[str, str]], name: str,
                 timeout_s: float) -> Any:
    """Return the value of parameter ``name`` of the first of ``nodes`` that has it, or None."""
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters
    for node, namespace in nodes:
        response = call_service(client_node, GetParameters,
                                f"{namespace.rstrip('/')}/{node}/get_parameters",
                                GetParameters.Request(names=[name]), timeout_s)
        values = [] if response is None else response.values
        if values and values[0].type != ParameterType.PARAMETER_NOT_SET:
            return parameter_value_to_python(values[0])
    return None


def unconnected_topics(bridge, nodes: Iterable[tuple[str, str]]) -> list[str]:
    """
    Return a warning for each topic one of ``nodes`` uses with nothing at its other end.

    ``nodes`` are (name, namespace) of the target nodes, in this process or another on the
    run's ROS domain. A subscription that nothing publishes, a publisher that nothing
    subscribes to, read from the ROS graph as the SimBridge node ``bridge`` sees it, each with
    the simulator's topic most like it and the remapping rule that would connect them.
    ROS_TOPICS are left out.
    """
    ends = {'publishes': {publisher.topic_name for publisher in bridge.publishers},
            'subscribes to': {sub.topic_name for sub in bridge.subscriptions}}
    uses = (('subscribes to', bridge.get_subscriber_names_and_types_by_node,
             bridge.count_publishers, 'nothing publishes it', 'publishes'),
            ('publishes', bridge.get_publisher_names_and_types_by_node,
             bridge.count_subscribers, 'nothing subscribes to it', 'subscribes to'))
    warnings = []
    for name, namespace in nodes:
        for verb, topics_of, count, nothing, other_end in uses:
            for topic, _ in topics_of(name, namespace):
                if topic in ROS_TOPICS or count(topic):
                    continue
                near = nearest_topic(topic, ends[other_end] - set(ROS_TOPICS))
                hint = (f' (the simulator {other_end} {near}: --remap {topic}:={near})'
                        if near else '')
                warning = f'{name} {verb} {topic}: {nothing}{hint}'
                if warning not in warnings:
                    warnings.append(warning)
    return warnings


def load_world(world: str, robot: str | None = None,
               start: Sequence[float] | str | None = None) -> World:
    """
    Load a world by name or path, turning every failure into a one-line RunError.

    ``robot`` names a robot model (a model folder, as the world file's ``robot: model:``)
    spawned in it instead of the world's own robot, at ``start`` when that is a pose (x m, y m,
    yaw rad), else at the world's robot start; as the bridge's ``robot`` parameter does.
    """
    pose = None if start is None or isinstance(start, str) else start
    try:
        return World.load(find_world(world), robot=robot, robot_pose=pose)
    except (FileNotFoundError, WorldError) as error:
        raise RunError(str(error)) from None


def start_pose(world: World, start: Sequence[float] | str | None) -> list[float] | None:
    """Return the robot start override (x m, y m, yaw rad); 'mirrored' puts the target left."""
    if start is None:
        return None
    if start == 'mirrored':
        start = world.mirrored_start().robot_start
    try:
        world.with_robot_start(*start)
    except (TypeError, ValueError, WorldError) as error:
        raise RunError(f'start pose {start!r}: {error}') from None
    return [float(value) for value in start]


def node_parameters(world: World, params: Params | None, *, seed: int, gui: bool,
                    start: Sequence[float] | str | None, robot: str | None = None) -> Params:
    """
    Return every node's parameters: ``params`` plus the simulator's own.

    The simulator's: world, robot, robot pose, seed and gui. RunError when ``params`` sets
    one of the RUNNER_BRIDGE_PARAMETERS.
    """
    if not is_seed(seed):
        raise RunError(f'seed must be a non-negative integer up to {MAX_SEED} (a ROS integer '
                       f'parameter is int64), got {seed!r}')
    bridge_params = {'world': str(world.path), 'seed': seed, 'gui': bool(gui)}
    if robot is not None:
        bridge_params['robot'] = robot
    pose = start_pose(world, start)
    if pose is not None:
        bridge_params['robot_pose'] = pose
    params = dict(params or {})
    clash = [name for name in RUNNER_BRIDGE_PARAMETERS if name in params.get(BRIDGE_NODE, {})]
    if clash:
        raise RunError(f'--param {BRIDGE_NODE}:{clash[0]}: the runner sets it (use --world, '
                       '--robot, --robot-pose, --seed, --gui)')
    params[BRIDGE_NODE] = {**params.get(BRIDGE_NODE, {}), **bridge_params}
    return params


def write_params_file(path: Path, params: Params) -> None:
    """Write per-node parameters as a ROS 2 params file (``node: ros__parameters: ...``)."""
    document = {node: {'ros__parameters': values} for node, values in params.items()}
    path.write_text(yaml.safe_dump(document, sort_keys=False))


def runner_node(name: str, context, sim_time: bool):
    """Return a node of the runner's own: no services or /rosout; on sim time if asked."""
    from rclpy.node import Node
    return Node(name, context=context, use_global_arguments=False,
                start_parameter_services=False, enable_rosout=False,
                parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE,
                                     *([Parameter('use_sim_time', value=True)] if sim_time
                                       else [])])


class Teleop:
    """
    The person at the teleop: a node of the runner's driving the robot by a DrivePlan.

    Every 1/TELEOP_RATE_HZ s of sim time it publishes the plan's command on the simulator's
    command topic (its type: Twist, or TwistStamped), as teleop_twist_keyboard publishes while
    a key is held; once the plan is done, a zero command, and nothing more. The robot's centre
    is the simulator's ground truth (what the person sees), for segments that end near an
    obstacle of ``world``.
    """

    def __init__(self, graph: 'SteppedRun | LiveGraph', bridge, world: World,
                 segments: Sequence[Segment]):
        self.bridge = bridge
        subscription = next(sub for sub in bridge.subscriptions
                            if sub.callback == bridge.on_cmd_vel)
        self.msg_type = subscription.msg_type
        self.node = graph.node(TELEOP_NODE, sim_time=True)
        self.publisher = self.node.create_publisher(self.msg_type, subscription.topic_name, 10)
        self.plan = DrivePlan(segments, lambda name, x, y: world.obstacle(name).distance(x, y))
        self.timer = self.node.create_timer(1.0 / TELEOP_RATE_HZ, self.tick)
        self.tick()  # the first segment starts with the run

    def tick(self) -> None:
        """Publish the command of the plan at the current sim time."""
        now = self.node.get_clock().now()
        x, y, _ = self.bridge.sim.pose
        command = self.plan.command(now.nanoseconds / NANOSECONDS_PER_SECOND, x, y)
        if command is None:
            self.timer.cancel()
        message = self.msg_type()
        twist = getattr(message, 'twist', message)
        twist.linear.x, twist.angular.z = command or (0.0, 0.0)
        if twist is not message:
            message.header.stamp = now.to_msg()
        self.publisher.publish(message)


def close_outputs(warnings: list[str], log: NodeLog, teleop: 'Teleop | None',
                  recorder: 'RunRecorder | None', bag: BagRecorder | None) -> None:
    """Add the log's and the teleop's warnings to ``warnings``; write the lines to ``bag``."""
    if log.warning():
        warnings.append(log.warning())
    if teleop is not None:
        warnings += teleop.plan.missed
    if bag is not None and recorder is not None:
        recorder.write_log()
        bag.close()


def drive_plan(drive: Sequence[Any] | None, world: World) -> tuple[Segment, ...]:
    """Return the validated segments of ``drive`` (see sim_bridge.drive); RunError if bad."""
    if drive is None:
        return ()
    try:
        segments = parse_drive(drive)
        check_obstacles(segments, [obstacle.name for obstacle in world.obstacles], world.name)
    except DriveError as error:
        raise RunError(str(error)) from None
    return segments


class Observer:
    """
    Fill a Trace from the bridge's simulator, and keep every scan sent on ``/scan``.

    The simulator appends its ground truth to the trace after every physics step. A 60 s run
    of the lab's lidar (36 beams at 10 Hz) keeps 600 scans, about 90 kB of ranges.
    """

    def __init__(self, simulator):
        self.sim = simulator
        self.trace = Trace(robot_radius=simulator.robot_radius)
        simulator.trajectory = self.trace.samples

    def on_scan(self, msg: Any) -> None:
        """Keep the scan (a LaserScan) with the laser's pose in the world."""
        x, y, yaw = self.sim.pose
        laser_x, laser_y, *_, laser_yaw = self.sim.lidar_config.pose
        pose = (x + laser_x * math.cos(yaw) - laser_y * math.sin(yaw),
                y + laser_x * math.sin(yaw) + laser_y * math.cos(yaw), yaw + laser_yaw)
        self.trace.scans.append(ScanSnapshot(
            self.sim.time, pose, np.array(msg.ranges, dtype=np.float32), msg.angle_min,
            msg.angle_increment, msg.range_min, msg.range_max))

    def finish(self) -> Trace:
        self.trace.collisions.extend(CollisionEvent(c.time, c.x, c.y, c.obstacle)
                                     for c in self.sim.collisions)
        return self.trace


class RunRecorder:
    """
    What the run records: the bridge's messages as it publishes them, the rest as DDS delivers.

    The bridge's own messages are serialised by rclpy (``serialize_message``) as they are
    published; every other recorded topic (/cmd_vel, TF) has a raw subscription on the
    runner's own node, as ``ros2 bag record`` has. Messages are stamped with the sim time of the
    step that sent them. The lines the nodes wrote (``log``) are recorded on /rosout, each at
    its own time, before the next message. Messages sent before :meth:`record` (while the nodes
    start) are held, so that a run which cannot start has written nothing.
    """

    def __init__(self, run: 'SteppedRun', observer: 'Observer', record: bool, log: NodeLog):
        from rclpy.qos import DurabilityPolicy, QoSProfile
        self.run = run
        self.observer = observer
        self.recording = record
        self.log = log
        self.held: list[tuple[str, str, bytes, int]] | None = []
        self.bag = None
        self.type_names: dict[type, str] = {}
        bridge = run.bridge
        bridge.on_publish = self.on_bridge_message
        if not record:
            return
        node = run.node('sim_bridge_recorder')
        bridge_topics = {publisher.topic_name for publisher in bridge.publishers}
        subscribed = {sub.topic_name: sub.msg_type for sub in bridge.subscriptions}
        for publisher in bridge.publishers:
            subscribed.setdefault(publisher.topic_name, publisher.msg_type)
        latched = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        for topic, msg_type in subscribed.items():
            if topic in DEFAULT_TOPICS and (topic not in bridge_topics or topic.startswith('/tf')):
                write = functools.partial(self.write, topic, self.type_name(msg_type))
                node.create_subscription(
                    msg_type, topic, write, latched if topic == '/tf_static' else 10, raw=True,
                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))

    def type_name(self, msg_type: type) -> str:
        """Return (and keep) the ROS type name of a message class."""
        if msg_type not in self.type_names:
            self.type_names[msg_type] = message_type_name(msg_type)
        return self.type_names[msg_type]

    def on_bridge_message(self, topic: str, msg: Any) -> None:
        """Record a message the bridge publishes; show scans to the observer."""
        if topic == '/scan':
            self.observer.on_scan(msg)
        if self.recording and topic in DEFAULT_TOPICS:
            self.write(topic, self.type_name(type(msg)), serialize_message(msg))

    def write(self, topic: str, type_name: str, data: bytes) -> None:
        """Write (or hold) one message's CDR bytes at the current sim time."""
        self.write_log()
        self.store(topic, type_name, data, self.run.bridge.now_ns)

    def write_log(self) -> None:
        """Write (or hold) the nodes' lines not yet recorded, on /rosout at their own times."""
        for t_ns, entry in self.log.take_pending():
            self.store(ROSOUT_TOPIC, ROSOUT_TYPE, rosout_message(entry, t_ns), t_ns)

    def store(self, topic: str, type_name: str, data: bytes, t_ns: int) -> None:
        """Write (or hold) one message's CDR bytes at ``t_ns`` (ns)."""
        if self.bag is not None:
            self.bag.write(topic, type_name, data, t_ns)
        elif self.held is not None:
            self.held.append((topic, type_name, data, t_ns))

    def record(self, bag: BagRecorder | None) -> None:
        """Write the held messages to ``bag`` and everything sent from now on."""
        self.write_log()
        if bag is not None:
            for message in self.held:
                bag.write(*message)
        self.bag, self.held = bag, None


class SteppedRun:
    """
    The SimBridge node and the target nodes in one process on real rclpy, stepped to an end.

    Every node but the bridge gets the command line its own process would have
    (``--ros-args --params-file <params.yaml> -p use_sim_time:=true -r FROM:=TO ...``, the
    remapping rules ``remap``, then ``ros_args`` as given: ``--ros-args ...``); the bridge
    reads only ``bridge_params_file``, and neither it nor the runner's own nodes are remapped.
    The run's DDS traffic stays in the process (``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF``, see
    README). RunError when rcl cannot read the arguments (a remapping rule it refuses).
    """

    def __init__(self, params_file: Path, quiet: bool, code: StudentCode = StudentCode(), *,
                 bridge_params_file: Path | None = None, remap: Sequence[str] = (),
                 ros_args: Sequence[str] = ()):
        import rclpy
        from rclpy.impl.implementation_singleton import rclpy_implementation
        from rclpy.signals import SignalHandlerOptions
        self.rclpy = rclpy
        self.quiet = quiet
        self.node_arguments = ['--ros-args', '--params-file', str(params_file),
                               '-p', 'use_sim_time:=true',
                               *(argument for rule in remap for argument in ('-r', rule)),
                               *ros_args]
        self.bridge_arguments = ['--ros-args', '--params-file',
                                 str(bridge_params_file or params_file)]
        # The default context, as the nodes' own code uses it. Ctrl-C stays a
        # KeyboardInterrupt: the runner then writes what the run produced.
        try:
            rclpy.init(args=self.node_arguments, signal_handler_options=SignalHandlerOptions.NO)
        except rclpy_implementation.RCLError as error:
            # rcl's text: 'failed to initialize rcl: <why>, at <file:line>, at ...'
            why = str(error).partition(': ')[2].split(', at ')[0].split('. Error:')[0]
            raise RunError(f"rcl cannot read the nodes' arguments: {why}") from None
        self.context = rclpy.utilities.get_default_context()
        self.executor = SteppedExecutor(self.context, code)
        self.nodes = []
        self.bridge = None

    def node(self, name: str, sim_time: bool = False):
        """Create one of the runner's own nodes: no services or /rosout; on sim time if asked."""
        node = runner_node(name, self.context, sim_time)
        self.executor.add_node(node)
        self.executor.own_nodes.add(node)
        return node

    @contextmanager
    def capture_output(self, log: NodeLog) -> Iterator[OutputCapture]:
        """
        Keep what the nodes write in the block in ``log``, each line at the sim time of its code.

        Shown on the terminal as written, unless the run is quiet (sim_bridge.node_output).
        """
        with OutputCapture(log, lambda: self.bridge.now_ns, quiet=self.quiet) as capture:
            self.executor.output = capture
            try:
                yield capture
            finally:
                self.executor.output = None

    def start(self, node_class: type, label: str, **kwargs):
        """
        Create a node as if its process had been started with the run's command line.

        A parameter override of the wrong type is a RunError; any other exception from the
        node's constructor is the node failing, reported as a NodeError under ``label``; a
        constructor that shuts ROS down ends the run (NodeEnded). What the constructor writes
        is the node's, at the time the run is at.
        """
        output, name = self.executor.output, ''
        if output is not None:
            output.sync()
        try:
            node = node_class(**kwargs)
            name = node.get_name()
        except self.rclpy.exceptions.InvalidParameterTypeException as error:
            raise RunError(f'{label}: {error}') from None
        except BaseException as error:  # noqa: B902 sys.exit() in a constructor ends the run
            raise NodeError(label, error, code=self.executor.code) from error
        finally:
            if output is not None:
                output.sync(name)
        self.nodes.append(node)
        if not self.context.ok():
            raise NodeEnded(label, 'its constructor', self.executor.shutdown_where or '')
        self.executor.add_node(node)
        return node

    def start_simulator(self, bridge_class: type):
        """
        Start the SimBridge node, stepped, and return it; RunError when it cannot start.

        It reads the params file but not ``use_sim_time``: it makes sim time. Nothing in the
        process could call its services or read its /rosout, so it has none: every entity of
        every node is one more for each wait of the executor.
        """
        try:
            self.bridge = self.start(
                bridge_class, BRIDGE_NODE, stepped=True, use_global_arguments=False,
                cli_args=self.bridge_arguments, start_parameter_services=False,
                enable_rosout=False, parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
        except NodeError as error:
            raise RunError(f'{BRIDGE_NODE}: {describe(error.original)}') from None
        self.executor.own_nodes.add(self.bridge)
        return self.bridge

    def start_nodes(self, targets: Iterable[tuple[str, type]],
                    params: Params) -> NodeError | NodeEnded | None:
        """
        Start each (label, Node class) in ``targets``; return the error of one that raised.

        Or the end of one that shut ROS down.
        """
        try:
            for label, node_class in targets:
                self.start(node_class, label)
        except (NodeError, NodeEnded) as error:
            return error
        return None

    def parameter_warnings(self, params: Params) -> list[str]:
        """Return a warning for each node in ``params`` not running, and each not declared."""
        declared = {node.get_name(): set(node.list_parameters([], 0).names)
                    for node in self.nodes}
        targets = [node.get_name() for node in self.nodes if node is not self.bridge]
        return parameter_warnings(params, declared, targets)

    def unconnected_topics(self) -> list[str]:
        """Return a warning for each topic a target node uses with nothing at its other end."""
        return unconnected_topics(self.bridge, [(node.get_name(), node.get_namespace())
                                                for node in self.nodes if node is not self.bridge])

    def parameter(self, name: str) -> Any:
        """Return the value of parameter ``name`` of the first node that has it, else None."""
        return next((node.get_parameter(name).value for node in self.nodes
                     if node.has_parameter(name)), None)

    def advance(self, end_ns: int, step_ns: int, on_step: Callable[[int], None]) -> None:
        """
        Step physics to ``end_ns``, running every ready callback after each step.

        /clock goes out with every message the bridge sends, and on its own only when a node's
        timer falls due; ``on_step(now_ns)`` is called every ``step_ns`` of sim time.
        """
        bridge, executor = self.bridge, self.executor
        targets = [node for node in (*self.nodes, *executor.own_nodes) if node is not bridge]
        if bridge.now_ns == 0:
            bridge.publish(bridge.clock_pub, bridge.clock)
        spin_until_idle(executor)
        timer_due = next_timer_ns(targets)
        next_call_ns = bridge.now_ns + step_ns
        physics_ns = bridge.step_ns
        while bridge.now_ns < end_ns:
            clock_due = timer_due is not None and timer_due <= bridge.now_ns + physics_ns
            if bridge.step(clock_due):
                spin_until_idle(executor)
                timer_due = next_timer_ns(targets)
            if bridge.now_ns >= next_call_ns:
                on_step(bridge.now_ns)
                next_call_ns += step_ns

    def close(self) -> None:
        """Destroy every node (the bridge last) and shut this run's rclpy context down."""
        own_nodes = [node for node in self.executor.get_nodes() if node not in self.nodes]
        self.executor.shutdown()
        for node in own_nodes + self.nodes[::-1]:
            node.destroy_node()
        self.rclpy.try_shutdown()  # a fresh default context for the next run


class UserInterrupt:
    """
    While the block runs, Ctrl-C (SIGINT) is noted in ``pressed`` and raises KeyboardInterrupt.

    So that the runner tells the user's Ctrl-C from a node raising KeyboardInterrupt itself.
    Outside the main thread (where Python delivers signals) it only notes nothing.
    """

    def __init__(self) -> None:
        self.pressed = False
        self.previous = None

    def __enter__(self) -> 'UserInterrupt':
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self.on_sigint)
        return self

    def on_sigint(self, signum, frame) -> None:
        self.pressed = True
        raise KeyboardInterrupt

    def __exit__(self, *exc_info) -> None:
        if self.pressed and self.previous is not None:
            # The outputs are written now: an impatient second Ctrl-C must not cut them short.
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        else:
            self.restore()

    def restore(self) -> None:
        """Give Ctrl-C back its handler from before the block (once the outputs are written)."""
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
            self.previous = None


class Pacing:
    """
    What the runner does between steps of the loop: nothing, a progress bar, or wall-clock pace.

    With ``gui``, steps are one frame of the pybullet window (1/GUI_FRAME_RATE s) and sim time
    waits for the wall clock; otherwise steps are 1 s and ``progress(sim_s, duration_s)`` is
    called after each.
    """

    def __init__(self, duration_s: float, gui: bool,
                 progress: Callable[[float, float], None] | None):
        self.duration_s = duration_s
        self.gui = gui
        self.progress = progress
        self.step_ns = NANOSECONDS_PER_SECOND // (GUI_FRAME_RATE if gui else 1)
        self.wall_start = time.perf_counter()

    def __call__(self, now_ns: int) -> None:
        elapsed = time.perf_counter() - self.wall_start
        if self.gui:
            time.sleep(max(0.0, now_ns / NANOSECONDS_PER_SECOND - elapsed))
        elif self.progress is not None:
            self.progress(now_ns / NANOSECONDS_PER_SECOND, self.duration_s)


def memory_limit() -> str | None:
    """Return this process's address-space limit as text ('2 GiB'), or None when unlimited."""
    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit == resource.RLIM_INFINITY:
        return None
    return f'{limit / 2 ** 30:g} GiB' if limit >= 2 ** 30 else f'{limit / 2 ** 20:g} MiB'


def node_failure(error: NodeError) -> str:
    """
    Say how a node failed a run, with what a student needs to fix it.

    A watchdog's stop names the callback that did not return; a field check failure explains
    what Jazzy's default would have done; a MemoryError names the run's memory limit; a module
    of a ROS installation says so (hints.ros_module_hint); scan code written for another lidar
    gets the scan's geometry (hints.scan_hint).
    """
    if isinstance(error.original, RunStopped):
        return (f"{error.original}: node '{error.node_name}' did not return from "
                f'{error.place}{error.code.origin(error.original)}')
    hint = ''
    if is_field_check_failure(error.original):
        hint = f' ({FIELD_CHECK_HINT})'
    elif isinstance(error.original, MemoryError) and memory_limit() is not None:
        hint = f' (memory limit {memory_limit()} reached in {error.place})'
    elif text := ros_module_hint(error.original) or scan_hint(error.original, error.code):
        hint = f' ({text})'
    return str(error) + hint


def import_failure(error: TargetError) -> RunError:
    """
    Return the RunError of a TARGET that failed to import, with the node's part of the traceback.

    A MemoryError names the run's memory limit and the file; a module of a ROS installation
    says so (hints.ros_module_hint).
    """
    message, cause = str(error), error.__cause__
    if isinstance(cause, MemoryError) and memory_limit() is not None:
        message += f' (memory limit {memory_limit()} reached while importing {error.file})'
    elif ros_module_hint(cause):
        message += f' ({ros_module_hint(cause)})'
    if cause is None:
        return RunError(message)
    return RunError(message, StudentCode.of([error.file] if error.file else []).traceback(cause))


def default_out_dir(world: World, targets: Sequence[str]) -> Path:
    """Return ``out/<world>-<node>[+<node>...]``."""
    return Path('out') / f"{world.name}-{'+'.join(target_name(t) for t in targets)}"


def open_outputs(out_dir: Path, params_file: Path, record: bool) -> BagRecorder | None:
    """Create ``out_dir`` with a copy of the params file, and the run's bag when recording."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(params_file, out_dir / 'params.yaml')
        return BagRecorder(out_dir / 'run', overwrite=True, sim_clock=True) if record else None
    except OSError as error:
        raise RunError(f'cannot write to {out_dir}: {error}') from None


def run_simulation(world: str, targets: Sequence[str], *, duration_s: float = 60.0,
                   seed: int = 0, params: Params | None = None,
                   out_dir: Path | str | None = None,
                   start: Sequence[float] | str | None = None, robot: str | None = None,
                   remap: Sequence[str] = (), ros_args: Sequence[str] = (),
                   setpoint: float | None = None,
                   printed: Sequence[str] = (), quiet: bool = False,
                   record: bool = True, plot: bool = True, gui: bool = False,
                   field_checks: bool = True, drive: Sequence[Any] | None = None,
                   progress: Callable[[float, float], None] | None = None) -> RunResult:
    """
    Run ``targets`` (see sim_bridge.targets) with the simulator in ``world`` for ``duration_s``.

    ``params`` maps node names to parameter overrides; ``start`` overrides the robot's start
    pose (x m, y m, yaw rad), or is 'mirrored' to put the world's target on the robot's left;
    ``robot`` names a robot model spawned instead of the world's own (see :func:`load_world`);
    ``remap`` holds ROS remapping rules (``FROM:=TO``, ``NODE:FROM:=TO``) for the target nodes;
    ``ros_args`` (``--ros-args ...``, as given after ``ros2 run``'s executable) reach them
    unchanged;
    ``setpoint`` is the wall distance (m) ``wall_distance_m`` is measured against, by default
    the value of a node's ``distance`` parameter (SETPOINT_PARAMETER), if one has it;
    ``printed`` names the values (printed_values.KINDS) whose printed lines are scored against
    the scans (``metrics['printed']``).
    What the world's files hold that the simulator does not simulate (``World.ignored``) is
    logged once by the simulator at start and kept in ``metrics['ignored']``.
    ``gui`` shows the run in the pybullet window at wall-clock pace. ``field_checks``: rosidl
    refuses a value of the wrong type in a message field (see sim_bridge.run_environment); off,
    the run behaves as Jazzy's default does on a robot. ``drive`` is a list of segments
    (sim_bridge.drive) the runner's teleop node publishes on the simulator's command topic
    while the nodes run, as a person at teleop_twist_keyboard would. Raises RunError when the
    run cannot start, before writing anything to ``out_dir``; a node that raises (while
    starting or during the run) ends it early, is reported in ``metrics['node_errors']`` and,
    unless ``quiet``, with its traceback on stderr, and every output is written up to that
    point. A node that shuts ROS down (``rclpy.shutdown()``) ends the run there, as it would
    end its process: not a node error, but ``metrics['ended_by']`` says which node and where.
    A parameter its node did not declare, or given for a node that is not running, is
    ignored, with a line in ``metrics['warnings']`` (one-line texts, also printed on stderr),
    as is each topic a target node uses with nothing at its other end when the run ends
    (:meth:`SteppedRun.unconnected_topics`).
    """
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise RunError(f'duration must be a positive number of seconds, got {duration_s}')
    remap = [check_remap(rule) for rule in remap]
    if gui and gui_problem(os.environ):
        raise RunError(gui_problem(os.environ))
    world_model = load_world(world, robot, start)
    segments = drive_plan(drive, world_model)
    node_params = node_parameters(world_model, params, seed=seed, gui=gui, start=start,
                                  robot=robot)
    out_dir = Path(out_dir) if out_dir is not None else default_out_dir(world_model, targets)
    run_modes = {'mode': 'stepped', 'reason': STEPPED_REASON}

    node_errors, warnings, ended_by = [], [], None
    wall_start = time.perf_counter()
    with run_environment(field_checks), terminal_colours(), \
            tempfile.TemporaryDirectory() as scratch:
        from sim_bridge.bridge import SimBridge
        from sim_bridge.stepped_run import AgentFailure, LockstepRun, node_error
        params_file = Path(scratch) / 'params.yaml'
        write_params_file(params_file, node_params)
        # The bridge reads its own entry alone: EVERY_NODE's parameters are the targets'.
        bridge_params_file = Path(scratch) / f'{BRIDGE_NODE}.yaml'
        write_params_file(bridge_params_file, {BRIDGE_NODE: node_params[BRIDGE_NODE]})
        run = LockstepRun(params_file, quiet, bridge_params_file=bridge_params_file,
                          remap=remap, ros_args=ros_args)
        bag, interrupt, outputs_open, teleop = None, UserInterrupt(), False, None
        recorder: RunRecorder | None = None
        log = NodeLog(record)
        try:
            bridge = run.start_simulator(SimBridge)
            observer = Observer(bridge.sim)
            recorder = RunRecorder(run, observer, record, log)
            teleop = Teleop(run, bridge, world_model, segments) if segments else None
            with run.capture_output(log):
                start_failure = run.start_nodes(targets, node_params)
                if start_failure is None:
                    warnings += run.parameter_warnings(node_params)
                    for warning in warnings:
                        to_terminal(f'warning: {warning}\n')
                if setpoint is None:
                    setpoint = run.parameter(SETPOINT_PARAMETER)
                bag = open_outputs(out_dir, params_file, record)
                recorder.record(bag)
                outputs_open = True
                if start_failure is not None:
                    raise start_failure
                pacing = Pacing(duration_s, gui, progress)
                pacing(bridge.now_ns)  # the nodes are up: simulated time starts
                with interrupt:
                    run.advance(round(duration_s * NANOSECONDS_PER_SECOND), pacing.step_ns,
                                pacing)
        except KeyboardInterrupt:
            if not interrupt.pressed:
                raise
            # Ctrl-C outside the nodes' code: the outputs are written, then it goes on.
        except AgentFailure as failure:
            if failure.returned:
                ended_by = str(failure)
                warnings.append(f'{failure}: the run ended at '
                                f'{bridge.now_ns / NANOSECONDS_PER_SECOND:g} s of its '
                                f'{duration_s:g} s')
                to_terminal(f'warning: {warnings[-1]}\n')
            elif not interrupt.pressed:
                node_errors.append(json_safe(node_error(failure, bridge.sim.lidar_config)))
                for line in failure.traceback.splitlines():
                    log.add(bridge.now_ns, failure.node, 'STDERR', line)
                if not quiet:
                    to_terminal(failure.traceback or f'{failure}\n')
        except NodeEnded as end:
            ended_by = str(end)
            warnings.append(f'{end}: the run ended at {bridge.now_ns / NANOSECONDS_PER_SECOND:g} '
                            f's of its {duration_s:g} s')
            to_terminal(f'warning: {warnings[-1]}\n')
        except NodeError as error:
            student_traceback = error.code.traceback(error.original)
            if not interrupt.pressed:  # a Ctrl-C while a callback ran is the user's
                node_errors.append(json_safe({'node': error.node_name,
                                              'error': node_failure(error),
                                              'traceback': student_traceback}))
            if not interrupt.pressed:
                # What the node's own process would print before dying, its own part: on
                # the terminal and, as a process run's would be, among the node's lines.
                for line in student_traceback.splitlines():
                    log.add(bridge.now_ns, error.node_name, 'STDERR', line)
                if not quiet:
                    to_terminal(student_traceback)
        except RunStopped as stop:
            if not outputs_open:  # stopped while starting: there is nothing to write yet
                raise
            node_errors.append({'node': BRIDGE_NODE, 'error': f'{stop} (in the simulator)'})
        finally:
            if outputs_open and run.context.ok():  # a node's rclpy.shutdown() ends the graph
                for warning in run.unconnected_topics():
                    warnings.append(warning)
                    to_terminal(f'warning: {warning}\n')
            warnings += run.stop_warnings
            close_outputs(warnings, log, teleop, recorder, bag)
            run.close()
    return write_outputs(
        out_dir, observer, world_model, interrupt, plot=plot,
        title=f"{world_model.name}: {', '.join(map(target_name, targets))}", setpoint=setpoint,
        printed=printed, wall_start=wall_start, node_errors=node_errors, warnings=warnings,
        ended_by=ended_by, run_mode=run_modes, commands=node_commands(targets, remap, ros_args),
        log_lines=log.entries)


def node_commands(targets: Sequence[str], remap: Sequence[str],
                  ros_args: Sequence[str] = ()) -> list[str]:
    """Return the command line that starts each node, as its process gets it (out dir files)."""
    arguments = ['--ros-args', '--params-file', 'params.yaml', '-p', 'use_sim_time:=true',
                 *(argument for rule in remap for argument in ('-r', rule)), *ros_args[1:]]
    return [node_command(target, arguments) for target in targets]


def write_outputs(out_dir: Path, observer: Observer, world_model: World,
                  interrupt: 'UserInterrupt', *, plot: bool, title: str,
                  setpoint: float | None, wall_start: float, node_errors: list,
                  warnings: list[str], ended_by: str | None, run_mode: Any,
                  commands: Sequence[str] = (), log_lines: Sequence[dict] = (),
                  printed: Sequence[str] = ()) -> RunResult:
    """
    Score a finished run and write ``metrics.json``, ``log.jsonl`` and the plot; return it.

    ``wall_start`` is the run's start on the perf counter (s); ``log_lines`` the lines the
    nodes wrote, dicts with the keys ``t`` (sim time, s), ``node``, ``level``, ``text`` and
    ``line`` (sim_bridge.node_output), in the order written; ``commands`` (the command line
    that starts each node, :func:`node_commands`) are kept in the metrics for the run's video;
    ``printed`` as in :func:`run_simulation`. A Ctrl-C while they are written waits for them
    (``interrupt``); one pressed during the run is raised after them.
    """
    try:
        write_log(out_dir / LOG_FILE, log_lines)
        metrics = compute_metrics(observer.finish(), world_model, setpoint=setpoint,
                                  wall_time_s=time.perf_counter() - wall_start,
                                  node_errors=node_errors, log_lines=log_lines,
                                  printed=printed, runner_nodes=(BRIDGE_NODE, TELEOP_NODE),
                                  printed_lateness_s=PROCESS_LINE_LATENESS_S
                                  if run_mode.get('mode') == 'process' else 0.0)
        metrics['warnings'] = [*metrics.get('warnings', []), *warnings]
        metrics['ended_by'] = ended_by
        metrics['ignored'] = world_model.ignored
        metrics['run_mode'] = run_mode
        metrics['commands'] = list(commands)
        (out_dir / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
        if plot:
            plot_trajectory(observer.trace, world_model, out_dir / 'trajectory.png',
                            title=title)
    finally:
        interrupt.restore()
    if interrupt.pressed:
        raise KeyboardInterrupt(f'run interrupted at {metrics["sim_time_s"]:.1f} s of sim time; '
                                f'its outputs are in {out_dir}')
    return RunResult(metrics, out_dir)


class LiveGraph:
    """The runner's side of a process run: the live bridge and the runner's own nodes."""

    def __init__(self, bridge, executor):
        self.bridge = bridge
        self.executor = executor

    def node(self, name: str, sim_time: bool = False):
        """Create one of the runner's own nodes in the bridge's context and executor."""
        node = runner_node(name, self.bridge.context, sim_time)
        self.executor.add_node(node)
        return node


def run_as_process(world_model: World, target: str, mode: Decision, node_params: Params, *,
                   duration_s: float, out_dir: Path, remap: Sequence[str],
                   ros_args: Sequence[str],
                   setpoint: float | None, quiet: bool, record: bool, plot: bool,
                   field_checks: bool, segments: Sequence[Segment] = (),
                   printed: Sequence[str] = (),
                   progress: Callable[[float, float], None] | None = None) -> RunResult:
    """
    Run the node file ``target`` as its own process against the simulator run live here.

    The file's own ``main()`` runs (sim_bridge.process_run), on a ROS domain private to the
    run; the SimBridge node runs in this process at real time (``real_time_factor`` 1) on its
    own timer. Simulated time starts when the node is in the ROS graph (bounded by
    NODE_START_TIMEOUT_S of wall time) and the process is stopped (SIGINT, then SIGTERM, then
    SIGKILL, as launch does) after ``duration_s`` of it. Outputs as a stepped run's; what the
    node prints is the run's console output, each line kept at the sim time it arrived.
    ``segments`` drive the robot as in a stepped run (:class:`Teleop`).
    ``mode`` says why the file is not stepped; ``progress(sim_s, duration_s)`` is called as
    simulated time passes. Ctrl-C and RunStopped end it as they end a stepped run: the node
    stopped, the outputs written.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from sim_bridge.bridge import SimBridge
    where, _ = split_target(target)
    path = Path(module_file(where))
    node_errors, warnings, ended_by = [], [], None
    domain = DomainReservation()
    env = process_environment(os.environ, domain.domain_id)
    env['ROS_PYTHON_CHECK_FIELDS'] = '1' if field_checks else ''
    to_terminal(f'{target_name(target)} runs as its own process: {mode.reason}\n')
    wall_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        params_file = Path(scratch) / 'params.yaml'
        write_params_file(params_file, node_params)
        bridge_params_file = Path(scratch) / f'{BRIDGE_NODE}.yaml'
        write_params_file(bridge_params_file, {BRIDGE_NODE: node_params[BRIDGE_NODE]})
        spec = node_spec(path, ['--ros-args', '--params-file', str(params_file),
                                '-p', 'use_sim_time:=true',
                                *(argument for rule in remap for argument in ('-r', rule)),
                                *ros_args])
        context = Context()
        with private_ros_environment(domain.domain_id):
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        executor = SingleThreadedExecutor(context=context)
        bag, outputs_open, interrupt, teleop = None, False, UserInterrupt(), None
        recorder: RunRecorder | None = None
        log = NodeLog(record)
        try:
            bridge = SimBridge(stepped=False, context=context, use_global_arguments=False,
                               cli_args=['--ros-args', '--params-file', str(bridge_params_file)],
                               start_parameter_services=False, enable_rosout=False,
                               parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
            executor.add_node(bridge)
            observer = Observer(bridge.sim)
            graph = LiveGraph(bridge, executor)
            recorder = RunRecorder(graph, observer, record, log)
            teleop = Teleop(graph, bridge, world_model, segments) if segments else None
            bag = open_outputs(out_dir, params_file, record)
            recorder.record(bag)
            outputs_open = True
            tail: deque[str] = deque(maxlen=OUTPUT_TAIL_LINES)
            prefix = prefixed(process_names([spec])[0], '')

            def out(line: str) -> None:
                if line.startswith(prefix):  # the node's own line, not launch's about it
                    tail.append(line[len(prefix):])
                if not quiet:
                    print_line(line)

            def keep(index: int, stream: str, line: str) -> None:
                log.add(bridge.now_ns, '', stream, line)
            with LiveRun([spec], env=env, out=out, on_line=keep) as live, interrupt:
                live.start()
                name = live.names[0]
                deadline = time.monotonic() + NODE_START_TIMEOUT_S
                while (set(bridge.get_node_names()) <= {BRIDGE_NODE}
                       and time.monotonic() < deadline and not live.pump(0.05)):
                    pass
                spinner = threading.Thread(target=executor.spin, name='live-bridge', daemon=True)
                spinner.start()
                while bridge.sim.time < duration_s and name not in live.returncodes:
                    live.pump(0.05)
                    if progress is not None:
                        progress(min(bridge.sim.time, duration_s), duration_s)
                if name not in live.returncodes:  # its nodes are still in the graph
                    own = {(node.get_name(), node.get_namespace())
                           for node in executor.get_nodes()}
                    nodes = [node for node in bridge.get_node_names_and_namespaces()
                             if node not in own]
                    declared = declared_parameters(bridge, nodes, PARAMETER_ANSWER_S)
                    if setpoint is None:
                        setpoint = parameter_of(bridge, [
                            node for node in nodes if SETPOINT_PARAMETER in (
                                declared[node[0]] or ())], SETPOINT_PARAMETER, PARAMETER_ANSWER_S)
                    declared[BRIDGE_NODE] = set(bridge.list_parameters([], 0).names)
                    for warning in (parameter_warnings(node_params, declared, dict(nodes))
                                    + unconnected_topics(bridge, nodes)):
                        warnings.append(warning)
                        to_terminal(f'warning: {warning}\n')
                else:
                    code = live.returncodes[name]
                    ended = (f'{name} ended (exit status {code}) at {bridge.sim.time:g} s of '
                             f'its {duration_s:g} s')
                    if code:
                        node_errors.append(process_error(target_name(target), ended, tail,
                                                         path, bridge.sim.lidar_config))
                    else:  # its own rclpy.shutdown() ended it: the run ends there
                        ended_by = ended
                        warnings.append(ended)
        except KeyboardInterrupt:
            if not interrupt.pressed:
                raise
            # Ctrl-C: the node is stopped, the outputs are written, then it goes on.
        except RunStopped as stop:
            if not outputs_open:
                raise
            node_errors.append({'node': BRIDGE_NODE, 'error': f'{stop} (in the simulator)'})
        finally:
            executor.shutdown()
            close_outputs(warnings, log, teleop, recorder, bag)
            for node in executor.get_nodes():
                node.destroy_node()
            context.try_shutdown()
            domain.release()
    return write_outputs(
        out_dir, observer, world_model, interrupt, plot=plot,
        title=f'{world_model.name}: {target_name(target)}', setpoint=setpoint,
        printed=printed, wall_start=wall_start, node_errors=node_errors, warnings=warnings,
        ended_by=ended_by, run_mode={'mode': 'process', 'reason': mode.reason},
        commands=node_commands([target], remap, ros_args), log_lines=log.entries)


def process_error(node: str, ended: str, output: Iterable[str], path: Path, lidar: Any) -> dict:
    """
    Return the node error of the node file ``path`` whose process ended with an error status.

    ``ended`` says when. What the process printed last (``output``) gives the error and the
    deepest line of the node's own code, as a stepped run reports them, with the node's part of
    the traceback and a hint: for a module of a ROS installation (hints.ros_module_hint), or
    the geometry of the scans of the simulator's ``lidar`` (a LidarConfig) for scan code
    written for another lidar (hints.printed_scan_hint).
    """
    printed = last_traceback(output)
    if printed is None:  # os._exit(), a signal: only the status says anything
        return {'node': node, 'error': ended}
    frames, error_line = printed
    code = StudentCode.of([path])
    own = code.frames(frames)
    hint = (ros_module_hint(printed_error(error_line))
            or printed_scan_hint(error_line, own[-1].line if own else '', lidar))
    return json_safe({
        'node': node,
        'error': f'{ended}: {error_line}{code.stack_origin(frames)}'
                 + (f' ({hint})' if hint else ''),
        'traceback': code.stack_traceback(frames, [error_line + '\n'])})


def summary_table(metrics: dict) -> str:
    """Return the run's main metrics as an aligned two-column table."""
    wall = metrics['wall_distance_m']
    rows = [
        ('sim time', f"{metrics['sim_time_s']:.1f} s"),
        ('wall time', f"{metrics['wall_time_s']:.2f} s "
                      f"({metrics['real_time_factor']:.0f}x real time)"),
        ('distance driven', f"{metrics['distance_m']:.2f} m"),
        ('collisions', str(metrics['collisions'])),
        ('min clearance', f"{metrics['min_clearance_m']:.3f} m"
         if metrics['min_clearance_m'] is not None else 'n/a'),
        ('laps around target', str(metrics['laps'])),
        ('wall distance mean / MAE', 'n/a' if wall['mean'] is None else
         f"{wall['mean']:.3f} m / " + ('n/a' if wall['mae'] is None else f"{wall['mae']:.3f} m")),
        ('stop-and-turns', f"{len(metrics['turns_deg'])}"),
        ('longest stationary', f"{metrics['max_stationary_s']:.1f} s"),
        ('coverage', 'n/a' if metrics['coverage'] is None else f"{metrics['coverage']:.0%}"),
        ('node errors', '; '.join(f"{e['node']}: {e['error']}" for e in metrics['node_errors'])
         or 'none'),
        ('warnings', '; '.join(metrics['warnings']) or 'none'),
    ]
    if 'run_mode' in metrics:
        mode = metrics['run_mode']
        rows.append(('run mode', f"{mode['mode']} ({mode['reason']})"))
    width = max(len(name) for name, _ in rows)
    return '\n'.join(f'  {name:<{width}}  {value}' for name, value in rows)


def terminal_progress() -> Callable[[float, float], None]:
    """Return a progress callback that redraws a bar on stderr once a run takes 2 s of wall."""
    wall_start = time.perf_counter()

    def draw(sim_s: float, duration_s: float) -> None:
        if time.perf_counter() - wall_start < PROGRESS_AFTER_S:
            return
        done = int(30 * sim_s / duration_s)
        bar = '#' * done + '.' * (30 - done)
        to_terminal(f'\r[{bar}] {sim_s:6.1f} / {duration_s:g} s sim'
                    + ('\n' if sim_s >= duration_s else ''))
    return draw


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the runner's command line."""
    parser = argparse.ArgumentParser(
        prog='python -m sim_bridge.run', description=__doc__.strip().splitlines()[0],
        epilog='TARGET: a console script (wall_follow), a module (scan_pkg.wall_follow) or a '
               '.py file, optionally followed by :ClassName. Arguments from --ros-args on go '
               "to the nodes unchanged, as after ros2 run's executable.")
    parser.add_argument('--world', required=True,
                        help='world name (worlds/<name>.yaml) or path to a world file')
    parser.add_argument('--node', action='append', required=True, metavar='TARGET',
                        dest='nodes', help='node to run (repeatable)')
    parser.add_argument('--duration', type=float, default=60.0, metavar='S',
                        help='simulated seconds (default 60)')
    parser.add_argument('--robot', metavar='NAME',
                        help="robot model to spawn instead of the world's (a model folder, "
                             'also from GZ_SIM_RESOURCE_PATH / GAZEBO_MODEL_PATH)')
    parser.add_argument('--robot-pose', type=float, nargs=3, metavar=('X', 'Y', 'YAW'),
                        help="the robot's start pose (m, m, rad; default: the world's)")
    parser.add_argument('--seed', type=int, default=0, help='seed of the run (default 0)')
    parser.add_argument('--param', action='append', default=[], metavar='NODE:NAME=VALUE',
                        help='parameter override, typed as --ros-args -p types it (repeatable)')
    parser.add_argument('--remap', action='append', default=[], metavar='[NODE:]FROM:=TO',
                        help="ROS remapping rule for the nodes, as ros2 run's --ros-args -r "
                             '(repeatable), e.g. /robot/scan:=/scan')
    parser.add_argument('--out', type=Path, metavar='DIR',
                        help='output folder (default out/<world>-<node>)')
    parser.add_argument('--gui', action='store_true',
                        help='show the run in the pybullet window at wall-clock pace')
    parser.add_argument('--quiet', action='store_true',
                        help="print only the summary, not the nodes' log lines")
    parser.add_argument('--no-record', action='store_true',
                        help='write no rosbag2 recording (a faster run)')
    parser.add_argument('--no-plot', action='store_true', help='write no trajectory.png')
    parser.add_argument('--video', type=Path, metavar='FILE.mp4',
                        help="also write the run's video (sim_bridge.video): the world and the "
                             "robot beside the nodes' terminal")
    parser.add_argument('--names', default='', help="the students' names, on every frame")
    parser.add_argument('--speed', type=float, default=1.0, metavar='N',
                        help='simulated seconds per second of video (default 1: real time)')
    parser.add_argument('--no-field-checks', action='store_true',
                        help="run with Jazzy's default: no type check of message fields "
                             '(a wrong type is sent as garbage, as on a robot)')
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run from the command line; return 0 when the run completed, 1 if a node failed.

    Everything from the first ``--ros-args`` on is the nodes' own, as after ``ros2 run``'s
    executable: rcl reads it, not this parser.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    split = argv.index('--ros-args') if '--ros-args' in argv else len(argv)
    ros_args = argv[split:]
    args = parse_args(argv[:split])
    if args.video is not None and args.no_record:
        print('error: --video is made from the recording: drop --no-record', file=sys.stderr)
        return 2
    try:
        params: Params = {}
        for text in args.param:
            node, name, value = parse_param(text)
            params.setdefault(node, {})[name] = value
        result = run_simulation(
            args.world, args.nodes, duration_s=args.duration, seed=args.seed, params=params,
            start=args.robot_pose, robot=args.robot, remap=args.remap, ros_args=ros_args,
            out_dir=args.out, quiet=args.quiet, gui=args.gui, record=not args.no_record,
            plot=not args.no_plot, field_checks=not args.no_field_checks,
            progress=terminal_progress() if sys.stderr.isatty() and not args.quiet else None)
    except RunError as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    except OSError as error:  # an output the run could not write: metrics.json is a folder
        print(f'error: cannot write {error.filename or args.out}: {error.strerror or error}',
              file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        print(f'\n{interrupt}' if str(interrupt) else '\ninterrupted', file=sys.stderr)
        return 130
    print(f'\nRun summary ({result.out_dir}):')
    print(summary_table(result.metrics))
    written = ['metrics.json', LOG_FILE, *(['trajectory.png'] if not args.no_plot else []),
               *(['run/ (rosbag2, MCAP)'] if not args.no_record else [])]
    print(f"  outputs: {result.out_dir}/{', '.join(written)}")
    if args.video is not None:
        from sim_bridge.video import render_video, VideoError
        try:
            info = render_video(result.out_dir, args.video, args.names, speed=args.speed)
        except VideoError as error:
            print(f'error: video: {error}', file=sys.stderr)
            return 2
        except OSError as error:
            print(f'error: cannot write {error.filename or args.video}: '
                  f'{error.strerror or error}', file=sys.stderr)
            return 2
        print(f'  video: {info.path} ({info.duration_s:.1f} s at {args.speed:g}x)')
    return 0 if result.ok else 1


if __name__ == '__main__':
    # The runner's modules import this one as sim_bridge.run: one RunError for them all.
    from sim_bridge.run import main as package_main
    sys.exit(package_main())
