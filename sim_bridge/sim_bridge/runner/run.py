"""
Run unmodified rclpy nodes against the simulator, on simulated time.

``python -m sim_bridge.run --world wall_follow_box --node wall_follow --duration 60`` runs the
SimBridge node here and each named node in a process of its own
(sim_bridge.runner.boundary.inside.agent), in lockstep (sim_bridge.runner.stepped_run): as if each
had been started with ``ros2 run ... --ros-args --params-file <out>/params.yaml -p
use_sim_time:=true``; then writes
``metrics.json``, ``trajectory.png`` and a rosbag2 recording ``run/`` (MCAP) to ``--out``.
"""

import gc
import os
from pathlib import Path
import tempfile
import time
from typing import Any, Callable, Sequence

from sim_bridge.common.run_environment import run_environment
from sim_bridge.common.text import json_safe
from sim_bridge.runner.boundary.outside.node_sandbox import isolation_warning
from sim_bridge.runner.node_output import terminal_colours, to_terminal
from sim_bridge.runner.options import (
    node_commands, prepare_run, PreparedRun, RunResult, RunSpec, write_params_files)
from sim_bridge.runner.outputs import RunOutputs, Scoring
from sim_bridge.runner.ros_graph import NANOSECONDS_PER_SECOND
from sim_bridge.runner.stepped_run import AgentFailure, LockstepRun, node_error
from sim_bridge.runner.targets import target_name
from sim_bridge.scoring.metrics import declared_wall_distance

GUI_FRAME_RATE = 60
#: How every run runs its target nodes (sim_bridge.runner.stepped_run).
STEPPED_REASON = ('its main() runs as ros2 run starts it, in a process of its own, in lockstep '
                  'with the simulator')


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


def run_simulation(world: str, targets: Sequence[str], **options: Any) -> RunResult:
    """Run ``targets`` with the simulator in ``world``; ``options`` are RunSpec's (see there)."""
    return run(RunSpec(world, tuple(targets), **options))


def run(spec: RunSpec) -> RunResult:
    """
    Run ``spec``: its nodes, each file in a process of its own, stepped with the simulator.

    What the world's files hold that the simulator does not simulate (``World.ignored``) is
    logged once by the simulator at start and kept in ``metrics['ignored']``. Raises RunError
    when the run cannot start (a node file that does not import, names no Node class, a
    parameter of the wrong type), before writing anything to ``spec.out_dir``; a node that
    raises (while starting or during the run), or whose process dies or hangs, ends it early,
    is reported in ``metrics['node_errors']`` and, unless ``quiet``, with its traceback on
    stderr, and every output is written up to that point. A node whose main() returns (after
    ``rclpy.shutdown()``, say) ends the run there, as it would end its process: not a node
    error, but ``metrics['ended_by']`` says which node and where. A parameter its node did not
    declare, or given for a node that is not running, is ignored, with a line in
    ``metrics['warnings']`` (one-line texts, also printed on stderr), as is each topic a target
    node uses with nothing at its other end when the run ends
    (:meth:`LockstepRun.unconnected_topics`).
    """
    result = run_stepped(spec, prepare_run(spec))
    # The run's rclpy objects (its context, executor and nodes hold one another) are freed
    # now, not by a later collection: in a process forked from this one (a multiprocessing
    # pool's worker) that would free them without their DDS threads, and crash it.
    gc.collect()
    return result


def keep_node_error(failure: AgentFailure, outputs: RunOutputs, run: LockstepRun,
                    quiet: bool) -> None:
    """
    Report a node's failure: its end (main() returned), or its error, lines and traceback.

    What the node's own process printed before dying, its own part: on the terminal and among
    the node's lines. A Ctrl-C while the node ran is the user's, not the node's.
    """
    now_ns = run.bridge.now_ns
    if failure.returned:
        outputs.ended_by = str(failure)
        outputs.warn(f'{failure}: the run ended at {now_ns / NANOSECONDS_PER_SECOND:g} s of its '
                     f'{run.duration_s:g} s')
        return
    if outputs.interrupt.pressed:
        return
    outputs.node_errors.append(json_safe(node_error(failure, run.bridge.sim.lidar_config)))
    for line in failure.traceback.splitlines():
        outputs.log.add(now_ns, failure.node, 'STDERR', line)
    if not quiet:
        to_terminal(failure.traceback or f'{failure}\n')


def run_stepped(spec: RunSpec, prepared: PreparedRun) -> RunResult:
    """Run ``spec``'s nodes in their processes, stepped with the simulator (see :func:`run`)."""
    outputs, setpoint = RunOutputs(spec.record), spec.setpoint
    wall_start = time.perf_counter()
    with run_environment(spec.field_checks), terminal_colours(), \
            tempfile.TemporaryDirectory() as scratch:
        from sim_bridge.ros.bridge import SimBridge
        os.chmod(scratch, 0o711)  # a run without namespaces (its uid alone) reads params.yaml
        params_file, bridge_params_file = write_params_files(Path(scratch), prepared.node_params)
        run = LockstepRun(params_file, spec.quiet, bridge_params_file=bridge_params_file,
                          remap=prepared.remap, ros_args=spec.ros_args)
        run.duration_s = spec.duration_s
        try:
            with outputs:
                try:
                    bridge = run.start_simulator(SimBridge)
                    outputs.watch(run, bridge, prepared.world, prepared.segments)
                    run.lockstep.meanwhile = outputs.recorder.flush
                    with run.capture_output(outputs.log):
                        start_failure = run.start_nodes(spec.targets, prepared.node_params)
                        if start_failure is None:
                            for warning in run.parameter_warnings(prepared.node_params):
                                outputs.warn(warning)
                        if setpoint is None:
                            setpoint = declared_wall_distance(
                                entry.get('values', {}) for entry in run.target_nodes())
                        outputs.start(prepared.out_dir, params_file)
                        if start_failure is not None:
                            raise start_failure
                        pacing = Pacing(spec.duration_s, spec.gui, spec.progress)
                        pacing(bridge.now_ns)  # the nodes are up: simulated time starts
                        with outputs.interrupt:
                            run.advance(round(spec.duration_s * NANOSECONDS_PER_SECOND),
                                        pacing.step_ns, pacing)
                except AgentFailure as failure:
                    keep_node_error(failure, outputs, run, spec.quiet)
                finally:
                    if isolation_warning(run.isolation):
                        outputs.warn(isolation_warning(run.isolation))
                    for warning in run.stop_warnings:
                        outputs.warn(warning)
                    if outputs.opened:
                        for warning in run.unconnected_topics():
                            outputs.warn(warning)
        finally:
            run.close()
    if spec.on_scoring is not None:
        spec.on_scoring()
    scoring = Scoring(f"{prepared.world.name}: {', '.join(map(target_name, spec.targets))}",
                      wall_start, setpoint, spec.printed, spec.duration_s, spec.plot)
    return outputs.write(
        prepared.out_dir, prepared.world, scoring,
        run_mode={'mode': 'stepped', 'reason': STEPPED_REASON, 'sandbox': run.isolation,
                  **run.notes()},
        commands=node_commands(spec.targets, prepared.remap, spec.ros_args))
