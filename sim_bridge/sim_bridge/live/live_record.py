"""
Record a live session (``./lab live TASK --record OUT_DIR``) as a stepped run's outputs.

A node of this process listens to the live simulator over DDS, as ``ros2 bag record`` would:
``/scan``, ``/odom``, ``/cmd_vel`` and ``/clock`` go into the rosbag2 recording ``run/``
(stamped with sim time: a message's header stamp, else the last /clock), ``/odom`` (the
simulator's exact pose and velocity from the spawn pose, put back in the world frame) and
``/collisions`` into the run's trace. Each line the task's node writes is kept
(sim_bridge.runner.node_output: ``log.jsonl`` and ``/rosout``) with the sim time it arrives at,
as a process run keeps its node's. When the
session ends, the trace is scored and plotted as a stepped run's (``metrics.json``,
``trajectory.png``; sim_bridge.runner.run.write_outputs), and ``params.yaml`` holds the simulator's
world and robot: ``python -m sim_bridge.commands.video OUT_DIR`` then makes the session's video.
"""

import math
from pathlib import Path
import threading
import time
from typing import Mapping, Sequence

from sim_bridge.common.errors import UserInterrupt
from sim_bridge.common.message_types import message_type_name
from sim_bridge.common.run_environment import environment_set
from sim_bridge.runner.node_output import NodeLog, ROSOUT_TOPIC, ROSOUT_TYPE
from sim_bridge.runner.options import load_world, started_world, write_params_file
from sim_bridge.runner.outputs import open_outputs, RunAccount, Scoring, write_outputs
from sim_bridge.scoring.run_trace import CollisionEvent, Trace
from sim_bridge.simulation.robot import pose_in_world

#: Topics recorded, as the stepped runner records them (tf aside: the live bridge's TF needs
#: tf2_ros, and the video does not read it).
RECORDED_TOPICS = ('/scan', '/odom', '/cmd_vel', '/clock')


class _Observer:
    """What write_outputs reads of a run: its trace (``finish`` returns it)."""

    def __init__(self, trace: Trace):
        self.trace = trace

    def finish(self) -> Trace:
        return self.trace


class LiveRecorder:
    """
    Record a live session into ``out_dir``; use as a context manager around the session.

    ``env`` is the environment of the session's processes (their ROS domain and discovery
    range); ``world`` the simulator's world name or path, ``robot`` and ``robot_pose`` (x m,
    y m, yaw rad) its robot; ``commands`` the node's command lines; ``params`` the session's
    parameter overrides per node.
    """

    def __init__(self, out_dir: Path, env: Mapping[str, str], *, world: str,
                 robot: str | None = None, robot_pose: Sequence[float] | None = None,
                 commands: Sequence[str] = (), params: Mapping[str, Mapping] | None = None,
                 real_time_factor: float = 1.0):
        self.out_dir = Path(out_dir)
        # The robot where the bridge spawns it: the session's trace is /odom from there.
        self.world = started_world(load_world(world, robot, robot_pose), robot_pose)
        self.commands = list(commands)
        self.trace = Trace(robot_radius=self.world.robot.radius)
        self.clock_ns = 0
        self.real_time_factor = real_time_factor
        #: Lines that arrived before the first /clock was heard: (wall s, stream, line).
        self.early: list[tuple[float, str, str]] = []
        self.lock = threading.Lock()
        simulator = {'world': str(self.world.path), 'robot': robot,
                     'robot_pose': list(robot_pose) if robot_pose is not None else None}
        document = {node: dict(values) for node, values in (params or {}).items()}
        document['sim_bridge'] = {**document.get('sim_bridge', {}),
                                  **{k: v for k, v in simulator.items() if v is not None}}
        scratch = self.out_dir / '.params.yaml'
        self.out_dir.mkdir(parents=True, exist_ok=True)
        write_params_file(scratch, document)
        self.bag = open_outputs(self.out_dir, scratch, record=True)
        scratch.unlink()
        self.log = NodeLog(record=True)
        self.env = {name: env.get(name) for name in
                    ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS')}
        self.wall_start = time.perf_counter()
        self.context = self.executor = self.spinner = None

    def __enter__(self) -> 'LiveRecorder':
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        self.context = Context()
        with environment_set(self.env):
            rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        node = self.node()
        self.bag.graph = node  # the live processes' offered QoS, as DDS discovery reports it
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(node)
        self.spinner = threading.Thread(target=self.executor.spin, name='live-recorder',
                                        daemon=True)
        self.spinner.start()
        return self

    def node(self):
        """Create the recording node: the recorded topics, the trace's odometry, collisions."""
        from functools import partial
        from geometry_msgs.msg import PointStamped, Twist
        from nav_msgs.msg import Odometry
        from rclpy.node import Node
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import LaserScan
        node = Node('lab_recorder', context=self.context, start_parameter_services=False,
                    enable_rosout=False)
        types = {'/scan': LaserScan, '/odom': Odometry, '/cmd_vel': Twist, '/clock': Clock}
        for topic in RECORDED_TOPICS:
            node.create_subscription(types[topic], topic, partial(self.on_message, topic), 10)
        node.create_subscription(PointStamped, '/collisions', self.on_collision, 10)
        return node

    def on_message(self, topic: str, msg) -> None:
        """Record a message at its sim time; keep the clock and the odometry's pose."""
        from rclpy.serialization import serialize_message
        stamp = getattr(msg, 'clock', None) or getattr(getattr(msg, 'header', None), 'stamp',
                                                       None)
        with self.lock:
            if stamp is not None:
                self.clock_ns = max(self.clock_ns, stamp.sec * 10 ** 9 + stamp.nanosec)
                if self.early:
                    self.keep_early()
            if topic == '/odom':
                pose, twist = msg.pose.pose, msg.twist.twist
                # Odometry starts at 0 in odom, the spawn pose's frame: the trace is the world's.
                x, y, yaw = pose_in_world(self.world.robot_start, (
                    pose.position.x, pose.position.y,
                    2.0 * math.atan2(pose.orientation.z, pose.orientation.w)))
                gap, _ = self.world.floor_slice.clearance((x, y, yaw))
                self.trace.append(self.clock_ns * 1e-9, x, y, float(yaw), twist.linear.x,
                                  twist.angular.z, gap)
            if not self.bag.closed:
                self.write_log()
                self.bag.write(topic, message_type_name(msg), serialize_message(msg),
                               self.clock_ns)

    def write_log(self) -> None:
        """Record the console lines not yet recorded, on /rosout at their sim time."""
        for t_ns, data in self.log.take_rosout():
            self.bag.write(ROSOUT_TOPIC, ROSOUT_TYPE, data, t_ns)

    def on_collision(self, msg) -> None:
        """Keep a contact the simulator reports (where in odom, when; not with what)."""
        x, y, _ = pose_in_world(self.world.robot_start, (msg.point.x, msg.point.y, 0.0))
        with self.lock:
            self.trace.collisions.append(CollisionEvent(self.clock_ns * 1e-9, x, y, ''))

    def line(self, stream: str, line: str) -> None:
        """Keep a line the node wrote on ``stream`` at the sim time it arrives (last /clock)."""
        with self.lock:
            if not self.clock_ns:
                self.early.append((time.monotonic(), stream, line))
                return
            self.log.add(self.clock_ns, '', stream, line)

    def keep_early(self) -> None:
        """
        Keep the lines that arrived before the first /clock, at the sim time they arrived.

        Until DDS discovery joins this node to the simulator (a second or more on a busy
        machine), sim time is not heard; it is told from the wall time then, the simulator
        pacing sim time at ``real_time_factor`` x wall time.
        """
        now = time.monotonic()
        for wall_s, stream, line in self.early:
            back_ns = round((now - wall_s) * self.real_time_factor * 1e9)
            self.log.add(max(0, self.clock_ns - back_ns), '', stream, line)
        self.early = []

    def __exit__(self, *exc_info) -> None:
        self.executor.shutdown()
        self.context.try_shutdown()
        with self.lock:
            if self.early:  # the simulator was never heard: the lines are kept at 0 s
                self.keep_early()
            self.write_log()
            self.bag.close()
        if len(self.trace):
            account = RunAccount({'mode': 'live', 'reason': 'recorded by ./lab live --record'},
                                 self.commands, log_lines=self.log.entries)
            write_outputs(self.out_dir, _Observer(self.trace), self.world, UserInterrupt(),
                          account, Scoring(f'{self.world.name}: live', self.wall_start))
