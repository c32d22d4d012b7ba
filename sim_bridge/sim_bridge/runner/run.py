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
from pathlib import Path
import resource
import tempfile
import time
from typing import Any, Callable, Iterable, Iterator, Sequence

from sim_bridge.common.errors import RunError, RunStopped
from sim_bridge.common.run_environment import (
    FIELD_CHECK_HINT, is_field_check_failure, run_environment)
from sim_bridge.common.text import json_safe
from sim_bridge.runner.hints import ros_module_hint, scan_hint, topic_type_hint
from sim_bridge.runner.node_output import NodeLog, OutputCapture, terminal_colours, to_terminal
from sim_bridge.runner.options import (
    BRIDGE_NODE, node_commands, Params, prepare_run, PreparedRun, RunResult, RunSpec,
    SETPOINT_PARAMETER, write_params_files)
from sim_bridge.runner.outputs import RunOutputs
from sim_bridge.runner.process_run import run_as_process
from sim_bridge.runner.ros_graph import (
    NANOSECONDS_PER_SECOND, NO_TYPE_DESCRIPTION_SERVICE, parameter_warnings, runner_node,
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
        self.bridge.check_command_publishers()  # the command type their publishers use
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
            # Steps in which nothing is due are taken in one (SimBridge.quiet_steps).
            steps = bridge.quiet_steps(min(end_ns, next_call_ns,
                                           end_ns if timer_due is None else timer_due))
            clock_due = timer_due is not None and timer_due <= bridge.now_ns + steps * physics_ns
            if bridge.step(clock_due, steps):
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
    elif text := (ros_module_hint(error.original) or topic_type_hint(error.original)
                  or scan_hint(error.original, error.code)):
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


def run_simulation(world: str, targets: Sequence[str], **options: Any) -> RunResult:
    """Run ``targets`` with the simulator in ``world``; ``options`` are RunSpec's (see there)."""
    return run(RunSpec(world, tuple(targets), **options))


def run(spec: RunSpec) -> RunResult:
    """
    Run ``spec``: stepped, or as its own process when its one node file cannot be stepped.

    What the world's files hold that the simulator does not simulate (``World.ignored``) is
    logged once by the simulator at start and kept in ``metrics['ignored']``. Raises RunError
    when the run cannot start, before writing anything to ``spec.out_dir``; a node that raises
    (while starting or during the run) ends it early, is reported in ``metrics['node_errors']``
    and, unless ``quiet``, with its traceback on stderr, and every output is written up to
    that point. A node that shuts ROS down (``rclpy.shutdown()``) ends the run there, as it
    would end its process: not a node error, but ``metrics['ended_by']`` says which node and
    where. A parameter its node did not declare, or given for a node that is not running, is
    ignored, with a line in ``metrics['warnings']`` (one-line texts, also printed on stderr),
    as is each topic a target node uses with nothing at its other end when the run ends
    (:meth:`SteppedRun.unconnected_topics`).
    """
    prepared = prepare_run(spec)
    modes = [run_mode(target) for target in spec.targets]
    process = [(t, mode) for t, mode in zip(spec.targets, modes) if not mode.steppable]
    if not process:
        return run_stepped(spec, prepared, '; '.join(mode.reason for mode in modes))
    target, mode = process[0]
    if len(spec.targets) > 1:
        raise RunError(f'{target}: {mode.reason}, so it runs as its own process; a process '
                       'run takes one node file: run it alone')
    result = run_as_process(spec, prepared, target, mode)
    # The run's rclpy objects (its context, executor and nodes hold one another) are freed
    # now, not by a later collection: in a process forked from this one (a multiprocessing
    # pool's worker) that would free them without their DDS threads, and crash it.
    gc.collect()
    return result


def load_classes(targets: Sequence[str], quiet: bool) -> list[type]:
    """Import each TARGET's Node class; RunError (its traceback shown unless quiet) if not."""
    from rclpy.node import Node
    try:
        return [load_node_class(target, Node) for target in targets]
    except TargetError as error:
        failure = import_failure(error)
        if not quiet and failure.traceback:
            to_terminal(failure.traceback)  # what `python3 node.py` would print
        raise failure from None


def keep_node_error(error: NodeError, outputs: RunOutputs, now_ns: int, quiet: bool) -> None:
    """
    Report a node's error: in the run's node errors, among its lines, and on the terminal.

    What the node's own process would print before dying, its own part: on the terminal and,
    as a process run's would be, among the node's lines. A Ctrl-C while a callback ran is the
    user's, not the node's.
    """
    if outputs.interrupt.pressed:
        return
    student_traceback = error.code.traceback(error.original)
    outputs.node_errors.append(json_safe({'node': error.node_name, 'error': node_failure(error),
                                          'traceback': student_traceback}))
    for line in student_traceback.splitlines():
        outputs.log.add(now_ns, error.node_name, 'STDERR', line)
    if not quiet:
        to_terminal(student_traceback)


def run_stepped(spec: RunSpec, prepared: PreparedRun, reason: str) -> RunResult:
    """Run ``spec``'s nodes in this process, stepped with the simulator (see :func:`run`)."""
    outputs, setpoint = RunOutputs(spec.record), spec.setpoint
    wall_start = time.perf_counter()
    with run_environment(spec.field_checks), terminal_colours(), \
            tempfile.TemporaryDirectory() as scratch:
        from sim_bridge.ros.bridge import SimBridge
        classes = load_classes(spec.targets, spec.quiet)
        code = StudentCode.of(inspect.getfile(node_class) for node_class in classes)
        params_file, bridge_params_file = write_params_files(Path(scratch), prepared.node_params)
        run = SteppedRun(params_file, spec.quiet, code, bridge_params_file=bridge_params_file,
                         remap=prepared.remap, ros_args=spec.ros_args)
        try:
            with outputs:
                try:
                    bridge = run.start_simulator(SimBridge)
                    outputs.watch(run, bridge, prepared.world, prepared.segments)
                    with run.capture_output(outputs.log):
                        start_failure = run.start_nodes(zip(spec.targets, classes),
                                                        prepared.node_params)
                        if start_failure is None:
                            for warning in run.parameter_warnings(prepared.node_params):
                                outputs.warn(warning)
                        if setpoint is None:
                            setpoint = run.parameter(SETPOINT_PARAMETER)
                        outputs.start(prepared.out_dir, params_file)
                        if start_failure is not None:
                            raise start_failure
                        pacing = Pacing(spec.duration_s, spec.gui, spec.progress)
                        pacing(bridge.now_ns)  # the nodes are up: simulated time starts
                        with outputs.interrupt:
                            run.advance(round(spec.duration_s * NANOSECONDS_PER_SECOND),
                                        pacing.step_ns, pacing)
                except NodeEnded as end:
                    outputs.ended_by = str(end)
                    outputs.warn(f'{end}: the run ended at '
                                 f'{bridge.now_ns / NANOSECONDS_PER_SECOND:g} s of its '
                                 f'{spec.duration_s:g} s')
                except NodeError as error:
                    keep_node_error(error, outputs, bridge.now_ns, spec.quiet)
                finally:
                    if outputs.opened and run.context.ok():  # rclpy.shutdown() ends the graph
                        for warning in run.unconnected_topics():
                            outputs.warn(warning)
        finally:
            run.close()
    return outputs.write(
        prepared.out_dir, prepared.world, plot=spec.plot,
        title=f"{prepared.world.name}: {', '.join(map(target_name, spec.targets))}",
        setpoint=setpoint, printed=spec.printed, wall_start=wall_start,
        run_mode={'mode': 'stepped', 'reason': reason},
        commands=node_commands(spec.targets, prepared.remap, spec.ros_args))
