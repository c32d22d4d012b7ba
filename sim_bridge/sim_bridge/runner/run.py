"""
Run unmodified rclpy nodes against the simulator in one process, on simulated time.

``python -m sim_bridge.run --world wall_follow_box --node wall_follow --duration 60`` runs the
SimBridge node and the named nodes on real rclpy in one process, stepped (every ready callback
runs before physics advances, see sim_bridge.runner.stepping), as if each had been started with
``ros2 run ... --ros-args --params-file <out>/params.yaml -p use_sim_time:=true``, then writes
``metrics.json``, ``trajectory.png`` and a rosbag2 recording ``run/`` (MCAP) to ``--out``.
"""


from contextlib import contextmanager
import gc
import inspect
import math
import os
from pathlib import Path
import resource
import tempfile
import time
from typing import Any, Callable, Iterable, Iterator, Sequence

from sim_bridge.common.errors import RunError, RunStopped, UserInterrupt
from sim_bridge.common.run_environment import (
    FIELD_CHECK_HINT, is_field_check_failure, run_environment)
from sim_bridge.common.text import json_safe
from sim_bridge.runner.hints import ros_module_hint, scan_hint
from sim_bridge.runner.node_output import NodeLog, OutputCapture, terminal_colours, to_terminal
from sim_bridge.runner.options import (
    BRIDGE_NODE, check_remap, default_out_dir, drive_plan, gui_problem, load_world, node_commands,
    node_parameters, Params, RunResult, SETPOINT_PARAMETER, write_params_file)
from sim_bridge.runner.outputs import (
    close_outputs, Observer, open_outputs, RunRecorder, write_outputs)
from sim_bridge.runner.process_run import run_as_process
from sim_bridge.runner.ros_graph import (
    NANOSECONDS_PER_SECOND, NO_TYPE_DESCRIPTION_SERVICE, parameter_warnings, runner_node, Teleop,
    unconnected_topics)
from sim_bridge.runner.stepping import (
    describe, next_timer_ns, NodeEnded, NodeError, spin_until_idle, SteppedExecutor)
from sim_bridge.runner.targets import (
    load_node_class, run_mode, StudentCode, target_name, TargetError)


GUI_FRAME_RATE = 60


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

        Shown on the terminal as written, unless the run is quiet (sim_bridge.runner.node_output).
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
    Run ``targets`` (sim_bridge.runner.targets) with the simulator in ``world`` for duration_s.

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
    refuses a value of the wrong type in a message field (see sim_bridge.common.run_environment);
    off, the run behaves as Jazzy's default does on a robot. ``drive`` is a list of segments
    (sim_bridge.ros.drive) the runner's teleop node publishes on the simulator's command topic
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
    modes = [run_mode(target) for target in targets]
    process = [(t, mode) for t, mode in zip(targets, modes) if not mode.steppable]
    if process:
        target, mode = process[0]
        if len(targets) > 1:
            raise RunError(f'{target}: {mode.reason}, so it runs as its own process; a process '
                           'run takes one node file: run it alone')
        result = run_as_process(
            world_model, target, mode, node_params, duration_s=duration_s, out_dir=out_dir,
            remap=remap, ros_args=ros_args, setpoint=setpoint, printed=printed, quiet=quiet,
            record=record, plot=plot, field_checks=field_checks, segments=segments,
            progress=progress)
        # The run's rclpy objects (its context, executor and nodes hold one another) are freed
        # now, not by a later collection: in a process forked from this one (a multiprocessing
        # pool's worker) that would free them without their DDS threads, and crash it.
        gc.collect()
        return result
    run_modes = {'mode': 'stepped', 'reason': '; '.join(mode.reason for mode in modes)}

    node_errors, warnings, ended_by = [], [], None
    wall_start = time.perf_counter()
    with run_environment(field_checks), terminal_colours(), \
            tempfile.TemporaryDirectory() as scratch:
        from rclpy.node import Node
        from sim_bridge.ros.bridge import SimBridge
        try:
            classes = [load_node_class(target, Node) for target in targets]
        except TargetError as error:
            failure = import_failure(error)
            if not quiet and failure.traceback:
                to_terminal(failure.traceback)  # what `python3 node.py` would print
            raise failure from None
        code = StudentCode.of(inspect.getfile(node_class) for node_class in classes)
        params_file = Path(scratch) / 'params.yaml'
        write_params_file(params_file, node_params)
        # The bridge reads its own entry alone: EVERY_NODE's parameters are the targets'.
        bridge_params_file = Path(scratch) / f'{BRIDGE_NODE}.yaml'
        write_params_file(bridge_params_file, {BRIDGE_NODE: node_params[BRIDGE_NODE]})
        run = SteppedRun(params_file, quiet, code, bridge_params_file=bridge_params_file,
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
                start_failure = run.start_nodes(zip(targets, classes), node_params)
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
            close_outputs(warnings, log, teleop, recorder, bag)
            run.close()
    return write_outputs(
        out_dir, observer, world_model, interrupt, plot=plot,
        title=f"{world_model.name}: {', '.join(map(target_name, targets))}", setpoint=setpoint,
        printed=printed, wall_start=wall_start, node_errors=node_errors, warnings=warnings,
        ended_by=ended_by, run_mode=run_modes, commands=node_commands(targets, remap, ros_args),
        log_lines=log.entries)
