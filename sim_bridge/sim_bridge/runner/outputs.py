"""
A run's outputs: what it observed, its recording, and the files it writes when it ends.

``metrics.json``, ``trajectory.png``, the node log and the rosbag2 recording ``run/`` (MCAP)
in the run's output folder, opened and closed alike by every run (and a live recording).

Each is bounded: the recording's messages at BAG_CAP_BYTES, the nodes' output at
sim_bridge.runner.boundary.outside.link.OUTPUT_CAP_BYTES (and node_output.MAX_LINES lines), kept on
/rosout in the bag and in ``log.jsonl``, itself LOG_CAP_BYTES at most (a line is kept printable and
twice: escapes make it longer). A run whose recording reaches its cap, or whose disk is full, ends
with one line (OutputsFull, RunError), and no other run with it.
"""

from dataclasses import dataclass
import functools
import json
from pathlib import Path
import shutil
import time
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from rclpy.event_handler import SubscriptionEventCallbacks
from sim_bridge.common.errors import OutputsFull, RunError, RunStopped, UserInterrupt
from sim_bridge.common.message_types import message_type_name
from sim_bridge.media.plot import plot_trajectory
from sim_bridge.runner.node_output import (
    LOG_FILE, NodeLog, ROSOUT_TOPIC, ROSOUT_TYPE, to_terminal, write_log)
from sim_bridge.runner.options import BRIDGE_NODE, RunResult
from sim_bridge.runner.record import BagFull, BagRecorder, DEFAULT_TOPICS
from sim_bridge.runner.ros_graph import RunGraph, Teleop, TELEOP_NODE
from sim_bridge.scoring.metrics import compute_metrics
from sim_bridge.scoring.run_trace import CollisionEvent, ScanSnapshot, Trace
from sim_bridge.simulation.geometry import point_in_world
from sim_bridge.simulation.world import World

#: Messages the recorder holds at most before it writes them to the bag.
HELD_MESSAGES = 100
#: Bytes of messages a run's recording holds at most (an honest 76 s run: about 3 MiB).
BAG_CAP_BYTES = 64 * 2 ** 20
#: Bytes of ``log.jsonl`` at most.
LOG_CAP_BYTES = 32 * 2 ** 20


def close_outputs(warnings: list[str], log: NodeLog, teleop: 'Teleop | None',
                  recorder: 'RunRecorder | None', bag: BagRecorder | None) -> None:
    """
    Add the log's and the teleop's warnings to ``warnings``; write the lines to ``bag``.

    OutputsFull when the bag cannot be written (see :meth:`RunRecorder.flush`).
    """
    if log.warning():
        warnings.append(log.warning())
    if teleop is not None:
        warnings += teleop.plan.missed
    if bag is not None and recorder is not None:
        recorder.write_log()
        recorder.flush()
        try:
            bag.close()
        except OSError as error:  # the index found the disk full
            raise recorder.stop_recording(error) from None


class Observer:
    """
    Fill a Trace from the bridge's simulator, and keep every scan sent on ``/scan``.

    The simulator appends its ground truth to the trace after every physics step. A 60 s run
    of the lab's lidar (36 beams at 10 Hz) keeps 600 scans, about 90 kB of ranges.
    """

    def __init__(self, simulator):
        self.sim = simulator
        self.trace = Trace(robot_radius=simulator.robot_radius,
                           scan_period_s=simulator.lidar_config.scan_period)
        simulator.trajectory = self.trace.samples

    def on_scan(self, msg: Any) -> None:
        """Keep the scan (a LaserScan) with the laser's pose in the world."""
        x, y, yaw = self.sim.pose
        laser_x, laser_y, *_, laser_yaw = self.sim.lidar_config.pose
        pose = (*point_in_world((x, y, yaw), (laser_x, laser_y)), yaw + laser_yaw)
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

    The bridge's own messages are recorded as the bytes it published them as (rclpy's
    ``serialize_message``, see SimBridge.on_publish); every other recorded topic (/cmd_vel,
    TF) has a raw subscription on the runner's own node, as ``ros2 bag record`` has. Messages
    are stamped with the sim time of the step that sent them. The lines the nodes wrote
    (``log``) are recorded on /rosout, each at its own time, before the next message. Messages
    are held and written in order by :meth:`flush`: a stepped run flushes while a node process
    handles its step. Those sent before :meth:`record` (while the nodes start) wait for it,
    so that a run which cannot start has written nothing.
    """

    def __init__(self, run: RunGraph, observer: 'Observer', record: bool, log: NodeLog):
        from rclpy.qos import DurabilityPolicy, QoSProfile
        self.run = run
        self.observer = observer
        self.recording = record
        self.log = log
        self.held: list[tuple[str, str, bytes | Callable[[], bytes], int]] | None = []
        self.bag = None
        self.type_names: dict[type, str] = {}
        bridge = run.bridge
        bridge.on_publish = self.on_bridge_message
        bridge.on_unheard = self.on_unheard_message
        self.node = None
        if not record:
            return
        # Its view of the run's graph gives the bag each topic's offered QoS.
        self.node = node = run.node('sim_bridge_recorder', sink=True)  # it only records
        bridge_topics = {publisher.topic_name for publisher in bridge.publishers}
        subscribed = {sub.topic_name: sub.msg_type for sub in bridge.subscriptions
                      if sub is not bridge.command_subscription}
        for publisher in bridge.publishers:
            subscribed.setdefault(publisher.topic_name, publisher.msg_type)
        latched = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node = node
        for topic, msg_type in subscribed.items():
            if topic not in bridge_topics or topic.startswith('/tf'):
                self.subscribe(topic, msg_type, latched if topic == '/tf_static' else 10)
        # The command topic's type is the one its publishers use (see SimBridge).
        self.command_subscription = None
        if bridge.command_subscription is not None:
            self.follow_command_type(bridge.command_subscription.msg_type)
        bridge.command_listeners.append(self.follow_command_type)

    def follow_command_type(self, msg_type: type | None) -> None:
        """Record the bridge's command topic in ``msg_type``; None: drop its subscription."""
        if self.command_subscription is not None:
            self.node.destroy_subscription(self.command_subscription)
            self.command_subscription = None
        if msg_type is not None:
            self.command_subscription = self.subscribe(self.run.bridge.command_topic, msg_type)

    def subscribe(self, topic: str, msg_type: type, qos: Any = 10) -> Any:
        """Record ``topic`` (a default topic) as DDS delivers it, raw; return the subscription."""
        if topic not in DEFAULT_TOPICS:
            return None
        write = functools.partial(self.write, topic, self.type_name(msg_type))
        return self.node.create_subscription(
            msg_type, topic, write, qos, raw=True,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))

    def type_name(self, msg_type: type) -> str:
        """Return (and keep) the ROS type name of a message class."""
        if msg_type not in self.type_names:
            self.type_names[msg_type] = message_type_name(msg_type)
        return self.type_names[msg_type]

    def on_bridge_message(self, topic: str, msg: Any, data: bytes) -> None:
        """Record a message the bridge publishes (its CDR bytes); show scans to the observer."""
        if topic == '/scan':
            self.observer.on_scan(msg)
        if self.recording and topic in DEFAULT_TOPICS:
            self.write(topic, self.type_name(type(msg)), data)

    def on_unheard_message(self, topic: str, type_name: str,
                           make_data: Callable[[], bytes]) -> None:
        """Record a message the bridge sent to no one: ``make_data()`` makes its bytes later."""
        if self.recording and topic in DEFAULT_TOPICS:
            self.write(topic, type_name, make_data)

    def write(self, topic: str, type_name: str, data: bytes | Callable[[], bytes]) -> None:
        """Hold one message's CDR bytes (or what makes them) at the current sim time."""
        self.write_log()
        self.store(topic, type_name, data, self.run.bridge.now_ns)

    def write_log(self) -> None:
        """Write (or hold) the nodes' lines not yet recorded, on /rosout at their own times."""
        for t_ns, data in self.log.take_rosout():
            self.store(ROSOUT_TOPIC, ROSOUT_TYPE, data, t_ns)

    def store(self, topic: str, type_name: str, data: bytes | Callable[[], bytes],
              t_ns: int) -> None:
        """
        Hold one message's CDR bytes (or what makes them) at ``t_ns`` (ns), in the order sent.

        Held until :meth:`flush` (a stepped run flushes while a node process handles its
        step), or until HELD_MESSAGES are held, once the bag is open.
        """
        if self.held is not None:
            self.held.append((topic, type_name, data, t_ns))
            if self.bag is not None and len(self.held) >= HELD_MESSAGES:
                self.flush()

    def flush(self) -> None:
        """
        Write the messages held to the bag, once it is open.

        OutputsFull when the bag reached its cap or the disk is full: the bag is closed as it
        is, and nothing more is recorded.
        """
        if self.bag is not None and self.held:
            held, self.held = self.held, []
            try:
                for topic, type_name, data, t_ns in held:
                    self.bag.write(topic, type_name, data() if callable(data) else data, t_ns)
            except (BagFull, OSError) as error:
                raise self.stop_recording(error) from None

    def stop_recording(self, error: BagFull | OSError) -> OutputsFull:
        """Close the bag as it is, record nothing more; return the run's end, in one line."""
        bag, self.bag, self.held = self.bag, None, None
        try:
            bag.close()
        except OSError:  # a full disk: the MCAP's messages are whole (record.recover)
            pass
        if isinstance(error, BagFull):
            return OutputsFull(f'the run ended at {self.run.bridge.now_ns / 1e9:g} s of sim '
                               f'time: {error} (its nodes published too much)')
        why = error.strerror or str(error)
        return OutputsFull(f'the run ended at {self.run.bridge.now_ns / 1e9:g} s of sim time: '
                           f'its recording could not be written ({why})')

    def record(self, bag: BagRecorder | None) -> None:
        """Write the held messages to ``bag`` and everything sent from now on."""
        self.write_log()
        if bag is None:
            self.held = None
            return
        bag.graph = self.node
        self.bag = bag
        self.flush()


def open_outputs(out_dir: Path, params_file: Path, record: bool) -> BagRecorder | None:
    """Create ``out_dir`` with a copy of the params file, and the run's bag when recording."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(params_file, out_dir / 'params.yaml')
        return (BagRecorder(out_dir / 'run', overwrite=True, sim_clock=True,
                            max_bytes=BAG_CAP_BYTES) if record else None)
    except OSError as error:
        raise RunError(f'cannot write to {out_dir}: {error}') from None


@dataclass(frozen=True)
class RunAccount:
    """
    What a finished run tells its outputs: how it ran, how its nodes ended, what they wrote.

    ``run_mode`` says how the run was driven (stepped or live, the sandbox); ``commands`` the
    command line that starts each node (:func:`node_commands`), kept for the run's video;
    ``log_lines`` the lines the nodes wrote, dicts with the keys ``t`` (sim time, s), ``node``,
    ``level``, ``text`` and ``line`` (sim_bridge.runner.node_output), in the order written.
    """

    run_mode: Mapping[str, Any]
    commands: Sequence[str] = ()
    node_errors: Sequence[dict] = ()
    warnings: Sequence[str] = ()
    ended_by: str | None = None
    log_lines: Sequence[dict] = ()


@dataclass(frozen=True)
class Scoring:
    """
    How a finished run is scored and drawn.

    ``wall_start`` is the run's start on the perf counter (s); ``setpoint`` the wall distance
    (m) the run is judged against, if any; ``printed`` as in :func:`run_simulation`, scored over
    the whole ``duration_s`` (s) of the scenario when given (see printed_values.score_printed);
    ``title`` the plot's, drawn when ``plot``.
    """

    title: str
    wall_start: float
    setpoint: float | None = None
    printed: Sequence[str] = ()
    duration_s: float | None = None
    plot: bool = True


def write_outputs(out_dir: Path, observer: Observer, world_model: World,
                  interrupt: 'UserInterrupt', account: RunAccount, scoring: Scoring
                  ) -> RunResult:
    """
    Score a finished run and write ``metrics.json``, ``log.jsonl`` and the plot; return it.

    A Ctrl-C while they are written waits for them (``interrupt``); one pressed during the run
    is raised after them. RunError (one line) when they cannot be written (a full disk).
    """
    try:
        warnings = list(account.warnings)
        left = write_log(out_dir / LOG_FILE, account.log_lines, LOG_CAP_BYTES)
        if left:
            warnings.append(f'{LOG_FILE} holds the lines that fit its cap of '
                            f'{LOG_CAP_BYTES} bytes; {left} more were not written')
        metrics = compute_metrics(observer.finish(), world_model, setpoint=scoring.setpoint,
                                  wall_time_s=time.perf_counter() - scoring.wall_start,
                                  node_errors=list(account.node_errors),
                                  log_lines=account.log_lines, printed=scoring.printed,
                                  runner_nodes=(BRIDGE_NODE, TELEOP_NODE),
                                  duration_s=scoring.duration_s)
        metrics['warnings'] = [*metrics.get('warnings', []), *warnings]
        metrics['ended_by'] = account.ended_by
        metrics['ignored'] = world_model.ignored
        metrics['run_mode'] = dict(account.run_mode)
        metrics['commands'] = list(account.commands)
        (out_dir / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
        if scoring.plot:
            plot_trajectory(observer.trace, world_model, out_dir / 'trajectory.png',
                            title=scoring.title)
    except OSError as error:  # a full disk: this run fails, in one line
        raise RunError(f'cannot write {error.filename}: {error.strerror or error}'
                       if error.filename else
                       f"cannot write the run's outputs ({error.strerror or error})") from None
    finally:
        interrupt.restore()
    if interrupt.pressed:
        raise KeyboardInterrupt(f'run interrupted at {metrics["sim_time_s"]:.1f} s of sim time; '
                                f'its outputs are in {out_dir}')
    return RunResult(metrics, out_dir)


class RunOutputs:
    """
    The skeleton of every run: watch, open the outputs, run, close, write.

    :meth:`watch` puts the observer, the recorder and the teleop on the run's simulator;
    :meth:`start` starts the output folder and the recording. ``with outputs:`` around the run
    closes the recording on the way out, and ends the run with its outputs written when the
    user's Ctrl-C (``interrupt``) or RunStopped (once the outputs are open) cut it short;
    :meth:`write` then writes them with the run's ``node_errors``, ``warnings`` and
    ``ended_by``.
    """

    def __init__(self, record: bool):
        self.record = record
        self.log = NodeLog(record)
        self.interrupt = UserInterrupt()
        self.node_errors: list[dict] = []
        self.warnings: list[str] = []
        self.ended_by: str | None = None
        self.observer: Observer | None = None
        self.recorder: RunRecorder | None = None
        self.teleop: Teleop | None = None
        self.bag: BagRecorder | None = None
        self.opened = False

    def watch(self, graph: RunGraph, bridge: Any, world: World, segments: Sequence[Any]) -> None:
        """Observe and record the simulator of ``bridge``; drive it by ``segments`` if any."""
        self.observer = Observer(bridge.sim)
        self.recorder = RunRecorder(graph, self.observer, self.record, self.log)
        self.teleop = Teleop(graph, bridge, world, segments) if segments else None

    def start(self, out_dir: Path, params_file: Path) -> None:
        """Start the output folder and the recording (held messages first)."""
        self.bag = open_outputs(out_dir, params_file, self.record)
        self.recorder.record(self.bag)
        self.opened = True

    def warn(self, warning: str) -> None:
        """Keep ``warning`` for metrics.json and show it on the terminal now."""
        self.warnings.append(warning)
        to_terminal(f'warning: {warning}\n')

    def __enter__(self) -> 'RunOutputs':
        return self

    def __exit__(self, kind, error, traceback) -> bool:
        try:
            close_outputs(self.warnings, self.log, self.teleop, self.recorder, self.bag)
        except OutputsFull as full:  # the last messages found the disk full
            kind, error = (OutputsFull, full) if kind is None else (kind, error)
        if kind is not None and issubclass(kind, OutputsFull):
            self.node_errors.append({'node': BRIDGE_NODE, 'error': str(error)})
            return True
        if kind is not None and issubclass(kind, KeyboardInterrupt):
            return self.interrupt.pressed  # the user's Ctrl-C: the outputs are written
        if kind is not None and issubclass(kind, RunStopped) and self.opened:
            self.node_errors.append({'node': BRIDGE_NODE,
                                     'error': f'{error} (in the simulator)'})
            return True
        return False

    def write(self, out_dir: Path, world: World, scoring: Scoring, run_mode: Mapping[str, Any],
              commands: Sequence[str]) -> RunResult:
        """Write the run's outputs (see :func:`write_outputs`); return its result."""
        account = RunAccount(run_mode, commands, self.node_errors, self.warnings, self.ended_by,
                             self.log.entries)
        return write_outputs(out_dir, self.observer, world, self.interrupt, account, scoring)
