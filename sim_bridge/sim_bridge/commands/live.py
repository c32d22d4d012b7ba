"""
Run a lab task live: the simulator and the task's node as two ROS 2 processes, as launch does.

``python -m sim_bridge.commands.live TASK [--node FILE] [--world W] [--robot NAME [--robot-pose
X Y YAW]] [--duration S] [--gui] [--rtf F]`` (``./lab live``)
starts what ``ros2 launch sim_bridge lab.launch.py task:=TASK`` starts on a ROS 2 machine, on a
machine that has only Python (launch and launch_ros are not on PyPI):

- ``sim_bridge-1``: ``python -m sim_bridge.ros.bridge --ros-args --params-file <sim.yaml>
  -p world:=W -p gui:=... -p real_time_factor:=F [-p robot:=NAME -p robot_pose:=[X, Y, YAW]]``,
  the simulator (with the robot model NAME spawned at the pose) stepping its physics on its
  own steady-clock timer, publishing /scan, /odom and /clock;
- ``<node>-2``: the task's scan_pkg node (the console script's module, ``python -m
  scan_pkg.<node>``) with ``--ros-args --params-file <params/<node>.yaml> -p
  use_sim_time:=true`` (the params file where scan_pkg ships one); with ``--node FILE``, the
  student's own node file instead (``<FILE's name>-2``: ``python FILE --ros-args -p
  use_sim_time:=true``), such as ``~/ros2_ws/src/scan_pkg/scan_pkg/wall_follow.py``, run
  as ``ros2 run`` runs it: as the student, not sandboxed (nothing is graded).

The task table (node and world of each task) is sim_bridge.live.lab_tasks, the one the launch file
reads. The two processes talk over DDS like any two ROS 2 processes: each gets this
environment with ``PYTHONUNBUFFERED=1`` and ``RCUTILS_LOGGING_BUFFERED_STREAM=1`` (every
line is written when it ends), the user's ``ROS_DOMAIN_ID``, and automatic discovery on:
``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` (which hides a process from every other) becomes
``LOCALHOST``, with a warning.
"""

import argparse
import math
import os
from pathlib import Path
import sys
from typing import Sequence

from sim_bridge.common import paths
from sim_bridge.common.errors import RunError
from sim_bridge.live.lab_tasks import LAB_TASKS
from sim_bridge.live.live import shown_command, task_specs
from sim_bridge.live.live_record import LiveRecorder
from sim_bridge.runner.options import split_param
from sim_bridge.runner.processes import (
    child_environment, log_line, LOGGER, print_line, process_names, run_live)


def positive_float(text: str) -> float:
    """Return ``text`` as a positive finite float (argparse type)."""
    value = float(text)
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f'must be positive and finite, got {text}')
    return value


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line of ``./lab live``."""
    parser = argparse.ArgumentParser(
        prog='./lab live', description=__doc__.strip().splitlines()[0],
        epilog='Stop with Ctrl-C: the node first, then the simulator.')
    parser.add_argument('task', choices=list(LAB_TASKS), help='lab task')
    parser.add_argument('--node', type=Path, metavar='FILE',
                        help="your own node file to run as the task's node, e.g. "
                             '~/ros2_ws/src/scan_pkg/scan_pkg/wall_follow.py (default: the '
                             "kit's scan_pkg node)")
    parser.add_argument('--world', help="world name or path instead of the task's")
    parser.add_argument('--robot', metavar='NAME',
                        help="robot model to spawn instead of the world's (a model folder, "
                             'also from GZ_SIM_RESOURCE_PATH / GAZEBO_MODEL_PATH)')
    parser.add_argument('--robot-pose', type=float, nargs=3, metavar=('X', 'Y', 'YAW'),
                        help="the robot's start pose (m, m, rad; default: the world's)")
    parser.add_argument('--duration', type=positive_float, metavar='S',
                        help='stop after this many wall seconds (default: at Ctrl-C)')
    parser.add_argument('--gui', action='store_true', help='open the pybullet window')
    parser.add_argument('--rtf', type=positive_float, default=1.0, metavar='F',
                        help='real-time factor of the simulator (default 1.0)')
    parser.add_argument('--param', action='append', default=[], metavar='NODE:NAME=VALUE',
                        help='parameter override for the node NODE (sim_bridge or the '
                             "task's), typed as --ros-args -p types it (repeatable)")
    parser.add_argument('--record', type=Path, metavar='OUT_DIR',
                        help="keep a stepped run's outputs in OUT_DIR (recording, log lines "
                             'with their sim time, metrics, plot): ./lab video OUT_DIR '
                             'makes its video')
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run a lab task live from the command line; return the exit status."""
    args = parse_args(argv)
    try:
        params: dict[str, dict[str, str]] = {}
        for text in args.param:
            node, name, value = split_param(text)  # typed by the child's --ros-args
            params.setdefault(node, {})[name] = value
        if args.world is not None:
            paths.find_world(args.world)
        if args.robot is not None:
            paths.find_model(args.robot)
        specs = task_specs(args.task, world=args.world, gui=args.gui,
                           real_time_factor=args.rtf, robot=args.robot,
                           robot_pose=args.robot_pose, params=params, node_file=args.node)
    except (ValueError, FileNotFoundError) as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    duration = f'for {args.duration:g} s' if args.duration else 'until Ctrl-C'
    print_line(log_line('INFO', LOGGER, f'task {args.task} live, {duration}: '
                                        f"{', '.join(process_names(specs))}"))
    if args.record is None:
        return run_live(specs, args.duration)
    env, _ = child_environment(os.environ)
    try:
        recorder = LiveRecorder(
            args.record, env, world=args.world or LAB_TASKS[args.task].world, robot=args.robot,
            robot_pose=args.robot_pose, commands=[shown_command(specs[-1])], params=params,
            real_time_factor=args.rtf)
    except (RunError, OSError) as error:
        print(f'error: --record {args.record}: {error}', file=sys.stderr)
        return 2
    node = len(specs) - 1  # the task's node: the simulator's lines are not kept, as in a run

    def keep(index: int, stream: str, line: str) -> None:
        if index == node:
            recorder.line(stream, line)
    with recorder:
        status = run_live(specs, args.duration, on_line=keep)
    print_line(log_line('INFO', LOGGER, f'recorded in {args.record}: ./lab video '
                                        f'{args.record} --names "..." makes its video'))
    return status


if __name__ == '__main__':
    sys.exit(main())
