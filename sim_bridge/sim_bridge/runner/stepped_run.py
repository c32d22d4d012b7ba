"""
A stepped run's trusted side: the simulator and the runner's nodes, the targets' processes.

The SimBridge node, the recorder and the teleop run here on real rclpy, stepped (every ready
callback runs before physics advances, see sim_bridge.runner.stepping); each target node file
runs in a process of its own (sim_bridge.runner.boundary.inside.agent) in lockstep with them
(sim_bridge.runner.boundary.outside.link), with the command line its process would get
(``--ros-args --params-file <params.yaml> -p use_sim_time:=true -r FROM:=TO ...``). This process
never imports a target's code.
"""

from contextlib import contextmanager
import re
import traceback
from typing import Any, Callable, Iterable, Iterator, Sequence

from sim_bridge.common.errors import OutputsFull, RunError, RunStopped
from sim_bridge.common.text import one_line
from sim_bridge.runner.boundary.outside import link
from sim_bridge.runner.boundary.outside.link import Agent, AgentFailure, AgentStartError, Lockstep
from sim_bridge.runner.boundary.outside.node_sandbox import node_limits, NodeSandbox, say_isolation
from sim_bridge.runner.boundary.outside.sandbox_host import SandboxError
from sim_bridge.runner.node_output import NodeLog, StreamLines, to_terminal
from sim_bridge.runner.options import BRIDGE_NODE, Params
from sim_bridge.runner.ros_graph import (
    NO_TYPE_DESCRIPTION_SERVICE, parameter_warnings, runner_node, unconnected_topics)
from sim_bridge.runner.stepping import (
    describe, next_timer_ns, spin_after_publishing, spin_until_idle, SteppedExecutor)
from sim_bridge.runner.targets import target_name


#: A frame of a traceback as Python prints it, and the error a ROS-module hint reads.
FRAME_LINE = re.compile(r'  File "(?P<file>.+)", line (?P<line>\d+), in (?P<name>.+)$')
MISSING_MODULE = re.compile(r"ModuleNotFoundError: No module named '(?P<name>[\w.]+)'")


class GraphView:
    """
    The ROS graph as the runner's warnings read it: the bridge's ends, the processes' nodes.

    The node processes' nodes are known from what they said they are
    (sim_bridge.runner.boundary.inside.agent); the counts are this process's graph, where the
    boundary's taps and publishers stand for them.
    """

    def __init__(self, bridge, agents: Sequence[Agent]):
        self.bridge = bridge
        self.publishers = bridge.publishers
        self.subscriptions = bridge.subscriptions
        self.command_topic = bridge.command_topic
        self.entries = {(entry['name'], entry['namespace']): entry
                        for agent in agents for entry in agent.graph}
        self.count_publishers = bridge.count_publishers
        self.count_subscribers = bridge.count_subscribers

    def get_subscriber_names_and_types_by_node(self, name: str, namespace: str) -> list:
        return [(topic, [kind]) for topic, kind in self.entries[name, namespace]['subscribes']]

    def get_publisher_names_and_types_by_node(self, name: str, namespace: str) -> list:
        return [(topic, [kind]) for topic, kind in self.entries[name, namespace]['publishes']]


class LockstepRun:
    """
    The SimBridge node and the runner's nodes here, the targets in their processes, stepped.

    The bridge reads only ``bridge_params_file``; the targets get ``node_arguments``. RunError
    when rcl cannot read the arguments (a remapping rule it refuses).
    """

    def __init__(self, params_file, quiet: bool, *, bridge_params_file=None,
                 remap: Sequence[str] = (), ros_args: Sequence[str] = ()):
        import rclpy
        from rclpy.impl.implementation_singleton import rclpy_implementation
        from rclpy.signals import SignalHandlerOptions
        self.rclpy = rclpy
        self.quiet = quiet
        self.params_file = params_file
        #: How the node processes are isolated (sim_bridge.runner.boundary.outside.sandbox), once
        #: one started.
        self.isolation = ''
        self.node_arguments = ['--ros-args', '--params-file', str(params_file),
                               '-p', 'use_sim_time:=true',
                               *(argument for rule in remap for argument in ('-r', rule)),
                               *ros_args]
        self.bridge_arguments = ['--ros-args', '--params-file',
                                 str(bridge_params_file or params_file)]
        try:  # rcl reads the nodes' arguments here first: a bad one is the run's error
            rclpy.init(args=self.node_arguments, signal_handler_options=SignalHandlerOptions.NO)
        except rclpy_implementation.RCLError as error:
            why = str(error).partition(': ')[2].split(', at ')[0].split('. Error:')[0]
            raise RunError(f"rcl cannot read the nodes' arguments: {why}") from None
        self.context = rclpy.utilities.get_default_context()
        self.executor = SteppedExecutor(self.context)
        self.boundary_node = runner_node('sim_bridge_boundary', self.context, False)
        self.agents: list[Agent] = []
        self.lockstep = Lockstep(self.agents,
                                 lambda topics: spin_after_publishing(self.executor, topics))
        self.bridge = None
        self.duration_s = 0.0
        self.lines: StreamLines | None = None
        #: What the node processes said as they were stopped: threads left running.
        self.stop_warnings: list[str] = []

    def node(self, name: str, sim_time: bool = False, sink: bool = False):
        """
        Create one of the runner's own nodes: no services or /rosout; on sim time if asked.

        ``sink``: its callbacks make nothing ready (SteppedExecutor.sink_nodes).
        """
        node = runner_node(name, self.context, sim_time)
        self.executor.add_node(node)
        self.executor.own_nodes.add(node)
        if sink:
            self.executor.sink_nodes.add(node)
        return node

    @contextmanager
    def capture_output(self, log: NodeLog) -> Iterator[StreamLines]:
        """Keep what the node processes write in the block in ``log``, at the sim time of it."""
        self.lines = StreamLines(log, quiet=self.quiet, cap_bytes=link.OUTPUT_CAP_BYTES)
        try:
            yield self.lines
        finally:
            for agent in self.agents:
                self.stop_warnings += agent.close()
            self.lines.close(self.bridge.now_ns if self.bridge is not None else 0)
            log.output_warning = self.lines.warning()

    def start_simulator(self, bridge_class: type):
        """Start the SimBridge node, stepped, and return it; RunError when it cannot start."""
        from sim_bridge.ros.bridge import START_ERRORS  # imported with bridge_class
        try:
            self.bridge = bridge_class(
                stepped=True, use_global_arguments=False, cli_args=self.bridge_arguments,
                start_parameter_services=False, enable_rosout=False,
                parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
        except START_ERRORS as error:  # bad input, said in its message
            raise RunError(f'{BRIDGE_NODE}: {one_line(str(error))}') from None
        except Exception as error:  # noqa: B902 a fault of its own: where it was raised
            raise RunError(f'{BRIDGE_NODE}: {describe(error)}') from None
        self.executor.add_node(self.bridge)
        self.executor.own_nodes.add(self.bridge)
        self.executor.sink_nodes.add(self.bridge)  # its one callback sets the drive's command
        return self.bridge

    def start_nodes(self, targets: Iterable[str], params: Params) -> AgentFailure | None:
        """
        Start a process for each TARGET; return the failure of a node that did not start.

        RunError when a TARGET cannot start: it does not import, it names no Node class, a
        parameter is of the wrong type (see :func:`start_error`), or no node process can start
        in its sandbox on this machine (:class:`SandboxError`, one line).
        """
        limits = node_limits(self.duration_s)
        try:
            for target in targets:
                box = NodeSandbox(target, limits, readable=[self.params_file])
                if not self.isolation:
                    self.isolation = box.sandbox.isolation
                    if not self.quiet:
                        say_isolation(self.isolation)
                try:
                    agent = Agent(box, target_name(target), self.node_arguments,
                                  self.boundary_node, self.lines, lambda: self.bridge.now_ns)
                except BaseException:
                    box.sandbox.close()
                    raise
                self.agents.append(agent)
                agent.start()
        except AgentFailure as failure:
            return failure
        except RunStopped as stop:  # the grader's watchdog: the node is stuck as it starts
            return AgentFailure(f'{stop}: {self.agents[-1].where_stuck()}',
                                self.agents[-1].running)
        except SandboxError as error:  # this machine cannot run any node: not the node's fault
            raise RunError(str(error)) from None
        except AgentStartError as error:
            if not self.quiet and error.traceback:
                to_terminal(error.traceback)  # what `python3 node.py` would print
            raise start_error(error, target) from None
        self.bridge.check_command_publishers()  # the command type their publishers use
        return None

    def notes(self) -> dict:
        """Return what the node processes said of how they run (``{'notes': [...]}``), or {}."""
        notes = sorted({note for agent in self.agents for note in agent.notes})
        return {'notes': notes} if notes else {}

    def target_nodes(self) -> list[dict]:
        """Return what the target processes said their nodes are (boundary.inside.agent)."""
        return [entry for agent in self.agents for entry in agent.graph]

    def parameter_warnings(self, params: Params) -> list[str]:
        """Return a warning for each node in ``params`` not running, and each not declared."""
        declared = {BRIDGE_NODE: set(self.bridge.list_parameters([], 0).names)}
        declared.update((entry['name'], set(entry['parameters']))
                        for entry in self.target_nodes())
        targets = [name for name in declared if name != BRIDGE_NODE]
        return parameter_warnings(params, declared, targets)

    def unconnected_topics(self) -> list[str]:
        """Return a warning for each topic a target node uses with nothing at its other end."""
        return unconnected_topics(GraphView(self.bridge, self.agents),
                                  [(e['name'], e['namespace']) for e in self.target_nodes()])

    def advance(self, end_ns: int, step_ns: int, on_step: Callable[[int], None]) -> None:
        """
        Step physics to ``end_ns``, each step's due callbacks and exchanges done after it.

        /clock goes out with every message the bridge sends, and on its own only when a
        timer of the runner's nodes or a node process's wake time falls due;
        ``on_step(now_ns)`` is called every ``step_ns`` of sim time.
        """
        bridge, lockstep = self.bridge, self.lockstep
        if bridge.now_ns == 0:
            bridge.publish(bridge.clock_pub, bridge.clock)
        spin_until_idle(self.executor)
        try:
            self.step_to(end_ns, step_ns, on_step)
        except RunStopped as stop:  # the grader's watchdog: a node's code, if it was its turn
            if lockstep.current is None or isinstance(stop, OutputsFull):
                raise
            raise AgentFailure(f'{stop}: {lockstep.current.where_stuck()}',
                               lockstep.current.running) from None

    def step_to(self, end_ns: int, step_ns: int, on_step: Callable[[int], None]) -> None:
        """Step physics to ``end_ns``: see :meth:`advance`."""
        bridge, executor, lockstep = self.bridge, self.executor, self.lockstep
        own = [node for node in executor.own_nodes if node is not bridge]
        lockstep.exchange_due(bridge.now_ns, force=True)
        timer_due = next_timer_ns(own)
        next_call_ns = bridge.now_ns + step_ns
        physics_ns = bridge.step_ns
        bridge_topics = {publisher.topic_name for publisher in bridge.publishers}
        while bridge.now_ns < end_ns:
            wakes = [wake for wake in (timer_due, lockstep.next_wake_ns()) if wake is not None]
            # Steps in which nothing is due are taken in one (SimBridge.quiet_steps).
            steps = bridge.quiet_steps(min([end_ns, next_call_ns, *wakes]))
            clock_due = bool(wakes) and min(wakes) <= bridge.now_ns + steps * physics_ns
            if bridge.step(clock_due, steps):  # something was sent: to the runner's or targets'
                if self.hears(bridge_topics):
                    spin_until_idle(executor)
                lockstep.exchange_due(bridge.now_ns)  # a wake time due sends /clock: heard
                timer_due = next_timer_ns(own)
            if bridge.now_ns >= next_call_ns:
                on_step(bridge.now_ns)
                next_call_ns += step_ns

    def hears(self, topics: set[str]) -> bool:
        """
        Tell whether a node on this process's executor subscribes to one of ``topics``.

        Only then can a step of the bridge (``topics``: those it publishes) make one of its
        callbacks ready (a timer on sim time needs /clock, a subscription too): when none does
        (the taps of the node processes are not on the executor), the wait that would find
        nothing ready is not made.
        """
        return any(subscription.topic_name in topics
                   for node in self.executor.get_nodes() for subscription in node.subscriptions)

    def close(self) -> None:
        """Destroy every node (the bridge last) and shut this run's rclpy context down."""
        nodes = [node for node in self.executor.get_nodes() if node is not self.bridge]
        self.executor.shutdown()
        for node in nodes + [self.boundary_node] + ([self.bridge] if self.bridge else []):
            node.destroy_node()
        self.rclpy.try_shutdown()


def memory_limit() -> str:
    """Return the memory limit of this process's nodes as text ('2 GiB'; see node_limits)."""
    limit = node_limits(0.0).memory_bytes
    return f'{limit / 2 ** 30:g} GiB' if limit >= 2 ** 30 else f'{limit / 2 ** 20:g} MiB'


def last_traceback(lines: Iterable[str]) -> tuple[list[traceback.FrameSummary], str] | None:
    """
    Return the frames (outermost first) and the error line of the last traceback in ``lines``.

    ``lines`` are what a Python process printed, as Python prints an uncaught exception; None
    when they hold no traceback. Only the last of chained exceptions is read: the one that
    ended the process.
    """
    lines = list(lines)
    starts = [index for index, line in enumerate(lines)
              if line.startswith('Traceback (most recent call last):')]
    if not starts:
        return None
    frames: list[list] = []
    for line in lines[starts[-1] + 1:]:
        match = FRAME_LINE.match(line)
        if match:
            frames.append([match['file'], int(match['line']), match['name'], ''])
        elif line.startswith('    '):
            code = line.strip()
            if frames and not frames[-1][3] and code.strip('^~ '):  # not 3.11's carets
                frames[-1][3] = code
        elif line.strip():
            summaries = [traceback.FrameSummary(file, number, name, lookup_line=False,
                                                line=code)
                         for file, number, name, code in frames]
            return summaries, line.strip()
    return None


def printed_error(error_line: str) -> BaseException | None:
    """
    Return what a hint needs of the error a node's process printed (``Type: message``), or None.

    A ``ModuleNotFoundError: No module named 'x'`` is that error, naming ``x``
    (sim_bridge.runner.hints.ros_module_hint reads it); other errors are not rebuilt.
    """
    match = MISSING_MODULE.match(error_line)
    if match is None:
        return None
    return ModuleNotFoundError(error_line.partition(': ')[2], name=match['name'])


def start_error(error: AgentStartError, target: str) -> RunError:
    """
    Return the RunError of TARGET that could not start, with the node's part of the traceback.

    A MemoryError names the run's memory limit and the file; a module of a ROS installation
    says so (hints.ros_module_hint).
    """
    from sim_bridge.runner.hints import ros_module_hint
    from sim_bridge.runner.targets import module_file, split_target
    message = str(error)
    raised = message.partition(' fails to import: ')[2].partition(' at ')[0]
    if raised == 'MemoryError':
        message += (f' (memory limit {memory_limit()} reached while importing '
                    f'{module_file(split_target(target)[0])})')
    elif ros_module_hint(printed_error(raised)):
        message += f' ({ros_module_hint(printed_error(raised))})'
    return RunError(message, error.traceback or None)


def node_error(failure: AgentFailure, lidar: Any) -> dict:
    """Return the ``node_errors`` entry of a node process that failed, with a hint."""
    from sim_bridge.runner.hints import printed_scan_hint, ros_module_hint
    printed = last_traceback(failure.traceback.splitlines())
    code_line = printed[0][-1].line if printed and printed[0] else ''
    error_line = printed[1] if printed else failure.error_line
    from sim_bridge.common.run_environment import FIELD_CHECK_HINT
    if error_line.startswith('AssertionError') and 'field must be' in error_line:
        hint = FIELD_CHECK_HINT
    elif failure.memory:
        hint = f'memory limit {memory_limit()} reached in {failure.place}'
    else:
        hint = (ros_module_hint(printed_error(error_line))
                or printed_scan_hint(error_line, code_line or '', lidar))
    entry = {'node': failure.node or '', 'error': str(failure) + (f' ({hint})' if hint else '')}
    if failure.traceback:
        entry['traceback'] = failure.traceback
    return entry
