"""
Run a node file as its own process, as ``python3 FILE`` or ``ros2 run`` starts it.

A process run (:func:`run_as_process`) runs it against the runner's live simulator.

The pieces a runner needs for a file it cannot step (sim_bridge.runner.node_styles): the command
line that runs the file's own ``main()``, and a ROS environment private to the run (a domain of its
own, discovery on this machine only), so the node and the runner's live simulator see each
other and nothing else. Starting, printing and stopping the process is
sim_bridge.runner.processes'.
"""


from collections import deque
import fcntl
import os
from pathlib import Path
import re
import sys
import tempfile
import threading
import time
import traceback
from typing import Any, ContextManager, Iterable, Mapping, Sequence

from sim_bridge.common.run_environment import environment_set
from sim_bridge.common.text import json_safe
from sim_bridge.runner.hints import printed_scan_hint, ros_module_hint
from sim_bridge.runner.node_output import to_terminal
from sim_bridge.runner.node_styles import Decision, has_main_guard
from sim_bridge.runner.options import (
    BRIDGE_NODE, node_commands, Params, PreparedRun, RunResult, RunSpec, SETPOINT_PARAMETER,
    write_params_files)
from sim_bridge.runner.outputs import RunOutputs
from sim_bridge.runner.processes import (
    DISCOVERY_VARIABLE, LiveRun, prefixed, print_line, process_names, ProcessSpec)
from sim_bridge.runner.ros_graph import (
    declared_parameters, LiveGraph, NO_TYPE_DESCRIPTION_SERVICE, PARAMETER_ANSWER_S, parameter_of,
    parameter_warnings, unconnected_topics)
from sim_bridge.runner.targets import module_file, split_target, StudentCode, target_name


#: Private domains are taken from [DOMAIN_BASE, DOMAIN_BASE + DOMAIN_COUNT): ids Fast DDS can
#: open ports for on Linux, away from the default domain 0.
DOMAIN_BASE = 1
DOMAIN_COUNT = 100
#: Longest wait (wall s) for a node run as a process to join the ROS graph.
NODE_START_TIMEOUT_S = 20.0
#: Lines of a node process's output kept to read its traceback from, should it die.
OUTPUT_TAIL_LINES = 400
#: A frame of a traceback as Python prints it, and the error a ROS-module hint reads.
FRAME_LINE = re.compile(r'  File "(?P<file>.+)", line (?P<line>\d+), in (?P<name>.+)$')
MISSING_MODULE = re.compile(r"ModuleNotFoundError: No module named '(?P<name>[\w.]+)'")
#: Where the runs on this machine reserve their domains, a lock file each: one folder for all
#: of them, whatever a run's TMPDIR (a graded run's is its own scratch folder).
LOCK_FOLDER = Path('/tmp')


class DomainReservation:
    """
    A ROS_DOMAIN_ID no other run on this machine holds, until :meth:`release`.

    Each id has a lock file in LOCK_FOLDER, taken with ``flock``: two runs at once (a grader's
    ``--jobs 2``) never share a domain, so one's node never hears the other's simulator. The
    search starts at an id spread by ``pid``; a run that dies frees its lock with its process,
    and the lock is not inherited by the node's process (Python opens files close-on-exec).
    """

    def __init__(self, pid: int | None = None, folder: Path = LOCK_FOLDER) -> None:
        start = (os.getpid() if pid is None else pid) % DOMAIN_COUNT
        for offset in range(DOMAIN_COUNT):
            domain_id = DOMAIN_BASE + (start + offset) % DOMAIN_COUNT
            lock = open(folder / f'lab-ros-domain-{domain_id}.lock', 'a')
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:  # another run holds it
                lock.close()
                continue
            self.domain_id, self.lock = domain_id, lock
            return
        raise RuntimeError(f'every ROS domain from {DOMAIN_BASE} to '
                           f'{DOMAIN_BASE + DOMAIN_COUNT - 1} is held by another run on this '
                           'machine')

    def release(self) -> None:
        """Free the domain for another run."""
        self.lock.close()


def process_environment(base: Mapping[str, str], domain_id: int) -> dict[str, str]:
    """Return ``base`` on domain ``domain_id`` with discovery on this machine only."""
    env = dict(base)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env[DISCOVERY_VARIABLE] = 'LOCALHOST'
    env.pop('ROS_STATIC_PEERS', None)
    return env


def node_spec(path: Path, ros_arguments: Sequence[str], python: str = sys.executable
              ) -> ProcessSpec:
    """
    Return the process running the node file ``path`` with ``ros_arguments`` (``--ros-args``).

    Its ``if __name__ == '__main__'`` block when it has one, as ``python3 FILE`` runs it;
    otherwise its ``main()`` called as ``ros2 run``'s console script calls it, with the file's
    folder first on the import path, as ``python3 FILE`` would have it.
    """
    path = Path(path).resolve()
    if has_main_guard(path.read_text(encoding='utf-8')):
        cmd = (python, str(path), *ros_arguments)
    else:
        code = ('import runpy, sys; sys.argv[0] = {0!r}; sys.path.insert(0, {1!r}); '
                "sys.exit(runpy.run_path({0!r}, run_name='node_file')['main']())").format(
                    str(path), str(path.parent))
        cmd = (python, '-c', code, *ros_arguments)
    return ProcessSpec(path.stem, cmd)


def private_ros_environment(domain_id: int) -> ContextManager[None]:
    """Put this process on domain ``domain_id``, discovery local, while rclpy starts in it."""
    return environment_set({**process_environment({}, domain_id), 'ROS_STATIC_PEERS': None})


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


def start_live_bridge(context: Any, bridge_params_file: Path) -> tuple[Any, Any]:
    """Return the SimBridge node run live (on its own timer) in ``context``, and its executor."""
    from rclpy.executors import SingleThreadedExecutor
    from sim_bridge.ros.bridge import SimBridge
    executor = SingleThreadedExecutor(context=context)
    bridge = SimBridge(stepped=False, context=context, use_global_arguments=False,
                       cli_args=['--ros-args', '--params-file', str(bridge_params_file)],
                       start_parameter_services=False, enable_rosout=False,
                       parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
    executor.add_node(bridge)
    return bridge, executor


def check_live_graph(bridge: Any, executor: Any, outputs: RunOutputs, node_params: Params,
                     setpoint: float | None) -> float | None:
    """
    Warn of parameters and topics the node process left unused; return the setpoint (m).

    Read from the ROS graph while the node's process still runs: its declared parameters, and
    its ``distance`` parameter when the run was given no setpoint.
    """
    own = {(node.get_name(), node.get_namespace()) for node in executor.get_nodes()}
    nodes = [node for node in bridge.get_node_names_and_namespaces() if node not in own]
    declared = declared_parameters(bridge, nodes, PARAMETER_ANSWER_S)
    if setpoint is None:
        setpoint = parameter_of(bridge, [
            node for node in nodes if SETPOINT_PARAMETER in (declared[node[0]] or ())],
            SETPOINT_PARAMETER, PARAMETER_ANSWER_S)
    declared[BRIDGE_NODE] = set(bridge.list_parameters([], 0).names)
    for warning in (parameter_warnings(node_params, declared, dict(nodes))
                    + unconnected_topics(bridge, nodes)):
        outputs.warn(warning)
    return setpoint


def run_node_process(spec: RunSpec, prepared: PreparedRun, target: str, process: ProcessSpec,
                     env: dict[str, str], bridge: Any, executor: Any,
                     outputs: RunOutputs) -> float | None:
    """
    Run the node's ``process`` against the live ``bridge`` for the run's duration; the setpoint.

    Simulated time starts when the node is in the ROS graph (bounded by NODE_START_TIMEOUT_S
    of wall time); a node process that ends early ends the run: a node error when it failed,
    ``ended_by`` when its own rclpy.shutdown() ended it.
    """
    tail: deque[str] = deque(maxlen=OUTPUT_TAIL_LINES)
    prefix = prefixed(process_names([process])[0], '')

    def out(line: str) -> None:
        if line.startswith(prefix):  # the node's own line, not launch's about it
            tail.append(line[len(prefix):])
        if not spec.quiet:
            print_line(line)

    def keep(index: int, stream: str, line: str) -> None:
        outputs.log.add(bridge.now_ns, '', stream, line)
    with LiveRun([process], env=env, out=out, on_line=keep) as live, outputs.interrupt:
        live.start()
        name = live.names[0]
        deadline = time.monotonic() + NODE_START_TIMEOUT_S
        while (set(bridge.get_node_names()) <= {BRIDGE_NODE}
               and time.monotonic() < deadline and not live.pump(0.05)):
            pass
        threading.Thread(target=executor.spin, name='live-bridge', daemon=True).start()
        while bridge.sim.time < spec.duration_s and name not in live.returncodes:
            live.pump(0.05)
            if spec.progress is not None:
                spec.progress(min(bridge.sim.time, spec.duration_s), spec.duration_s)
        if name not in live.returncodes:  # its nodes are still in the graph
            return check_live_graph(bridge, executor, outputs, prepared.node_params,
                                    spec.setpoint)
        code = live.returncodes[name]
        ended = (f'{name} ended (exit status {code}) at {bridge.sim.time:g} s of '
                 f'its {spec.duration_s:g} s')
        if code:
            outputs.node_errors.append(process_error(
                target_name(target), ended, tail, Path(module_file(split_target(target)[0])),
                bridge.sim.lidar_config))
        else:  # its own rclpy.shutdown() ended it: the run ends there
            outputs.ended_by = ended
            outputs.warnings.append(ended)
    return spec.setpoint


def run_as_process(spec: RunSpec, prepared: PreparedRun, target: str,
                   mode: Decision) -> RunResult:
    """
    Run the node file ``target`` as its own process against the simulator run live here.

    The file's own ``main()`` runs (:func:`node_spec`), on a ROS domain private to the run;
    the SimBridge node runs in this process at real time (``real_time_factor`` 1) on its own
    timer. The process is stopped (SIGINT, then SIGTERM, then SIGKILL, as launch does) after
    ``spec.duration_s`` of simulated time. Outputs as a stepped run's; what the node prints is
    the run's console output, each line kept at the sim time it arrived. The drive segments
    drive the robot as in a stepped run (:class:`Teleop`). ``mode`` says why the file is not
    stepped. Ctrl-C and RunStopped end it as they end a stepped run: the node stopped, the
    outputs written.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    path = Path(module_file(split_target(target)[0]))
    outputs, setpoint = RunOutputs(spec.record), spec.setpoint
    domain = DomainReservation()
    env = process_environment(os.environ, domain.domain_id)
    env['ROS_PYTHON_CHECK_FIELDS'] = '1' if spec.field_checks else ''
    to_terminal(f'{target_name(target)} runs as its own process: {mode.reason}\n')
    wall_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        params_file, bridge_params_file = write_params_files(Path(scratch), prepared.node_params)
        process = node_spec(path, ['--ros-args', '--params-file', str(params_file),
                                   '-p', 'use_sim_time:=true',
                                   *(argument for rule in prepared.remap
                                     for argument in ('-r', rule)),
                                   *spec.ros_args])
        context = Context()
        with private_ros_environment(domain.domain_id):
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        executor = None
        try:
            with outputs:
                try:
                    bridge, executor = start_live_bridge(context, bridge_params_file)
                    outputs.watch(LiveGraph(bridge, executor), bridge, prepared.world,
                                  prepared.segments)
                    outputs.start(prepared.out_dir, params_file)
                    setpoint = run_node_process(spec, prepared, target, process, env, bridge,
                                                executor, outputs)
                finally:
                    if executor is not None:
                        executor.shutdown()
        finally:
            for node in executor.get_nodes() if executor is not None else ():
                node.destroy_node()
            context.try_shutdown()
            domain.release()
    return outputs.write(
        prepared.out_dir, prepared.world, plot=spec.plot,
        title=f'{prepared.world.name}: {target_name(target)}', setpoint=setpoint,
        printed=spec.printed, wall_start=wall_start,
        run_mode={'mode': 'process', 'reason': mode.reason},
        commands=node_commands([target], prepared.remap, spec.ros_args))


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
