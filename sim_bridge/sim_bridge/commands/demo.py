"""
The README's demo: every lab task in the simulator, stepped on real rclpy, then the grader.

``python -m sim_bridge.commands.demo`` (``./lab demo``) runs each lab task's node in its world (see
sim_bridge.live.lab_tasks), showing the node's log lines as a student sees them in a terminal and a
summary of the run, then grades the shipped scenarios (scenarios/), then a small class of
four submissions (:func:`make_class`, ``--submissions``: its table shows the runs passed and
the marks of task 1 and task 4), and prints where every plot,
recording and report is. It ends with a short live run of ``wall_follow``
(sim_bridge.commands.live): the simulator and the node as two ROS 2 processes, their lines
interleaved as ros2 launch prints them.
"""

import argparse
import os
from pathlib import Path
import shutil
import sys
from typing import Sequence

from sim_bridge.commands import grade, live as live_command
from sim_bridge.commands.run import summary_table
from sim_bridge.common.errors import RunError
from sim_bridge.common.paths import output_folder, repo_root, scenarios_dir
from sim_bridge.common.run_environment import rclpy_origin
from sim_bridge.grading.scenario import load_scenario
from sim_bridge.live.lab_tasks import LAB_TASKS, TASK_SCENARIOS
from sim_bridge.runner.run import run_simulation

#: Simulated seconds of the tasks that drive themselves: a few loops. The scan readers are
#: driven past the obstacles as their shipped scenario drives them, for its duration.
TASK_DURATION_S = {'wanderbot': 120.0, 'wall_follow': 80.0}
#: A scan reader that ends its own process on its first scan.
SYS_EXIT_NODE = """import sys

from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ScanAhead(Node):

    def __init__(self):
        super().__init__('scan_ahead')
        self.create_subscription(LaserScan, 'scan', self.on_scan, 10)

    def on_scan(self, msg):
        sys.exit(3)
"""
#: The demo's class: each student's files, copied from the workspace (a path relative to its
#: top) or written as given. ``ana`` hands in the project's scan_ahead and a careful wall follower
#: of her own (a student's node may not import the kit's controllers), ``ben`` the lab's naive
#: wall follower, ``cleo`` a node with an int in a float field and no wall follower, ``dev``
#: a wall follower that does not compile and a scan reader that calls sys.exit().
CLASS = {
    'ana': {'scan_ahead.py': Path('scan_pkg/scan_pkg/scan_ahead.py'),
            'wall_follow.py': Path('examples/careful_wall_follow.py')},
    'ben': {'scan_ahead.py': Path('scan_pkg/scan_pkg/scan_ahead.py'),
            'wall_follow.py': Path('examples/naive_wall_follow.py')},
    'cleo': {'scan_ahead.py': Path('examples/int_twist.py')},
    'dev': {'wall_follow.py': 'class WallFollow(Node)\n', 'scan_ahead.py': SYS_EXIT_NODE},
}
#: The scenarios the demo's class is graded on (in scenarios/).
CLASS_SCENARIOS = ('scan_ahead.yaml', 'wall_follow_box_cw.yaml')
#: The live run at the end: its task and its length in wall seconds.
LIVE_TASK, LIVE_DURATION_S = 'wall_follow', 10.0


def run_tasks(out_dir: Path) -> bool:
    """Run every lab task once; return True when no node failed."""
    all_ok = True
    for name, task in LAB_TASKS.items():
        print(f'\n=== Lab task {name}: ros2 run scan_pkg {task.node} in world {task.world} ===',
              flush=True)
        if name in TASK_DURATION_S:
            result = run_simulation(task.world, [task.node], duration_s=TASK_DURATION_S[name],
                                    out_dir=out_dir / name)
        else:  # a scan reader, driven as a person at the teleop would drive the robot
            scenario = load_scenario(scenarios_dir() / TASK_SCENARIOS[name])
            result = run_simulation(task.world, [task.node], duration_s=scenario.duration_s,
                                    start=scenario.start, drive=scenario.drive,
                                    out_dir=out_dir / name)
        print(summary_table(result.metrics))
        print(f'  plot: {result.out_dir / "trajectory.png"}   '
              f'recording: {result.out_dir / "run"} (rosbag2, MCAP)')
        all_ok &= result.ok
    return all_ok


def grade_scenarios(out_dir: Path) -> int:
    """Grade the shipped scenarios into ``out_dir``; return the grader's exit status."""
    print(f'\n=== Grading the scenarios in {scenarios_dir()} ===', flush=True)
    return grade.main([str(scenarios_dir()), '--out', str(out_dir),
                       '--jobs', str(os.cpu_count() or 1)])


def make_class(folder: Path, root: Path) -> Path:
    """Write the submissions of :data:`CLASS` below ``folder`` from workspace ``root``."""
    for student, files in CLASS.items():
        (folder / student).mkdir(parents=True, exist_ok=True)
        for name, source in files.items():
            if isinstance(source, Path):
                shutil.copyfile(root / source, folder / student / name)
            else:
                (folder / student / name).write_text(source)
    return folder


def grade_class(out_dir: Path) -> int:
    """Grade the demo's class into ``out_dir``; return the grader's exit status."""
    root = repo_root()
    if root is None:
        return 0
    print(f'\n=== Grading a class: {", ".join(CLASS)} on {", ".join(CLASS_SCENARIOS)} ===',
          flush=True)
    submissions = make_class(out_dir / 'submissions', root)
    return grade.main([*(str(scenarios_dir() / name) for name in CLASS_SCENARIOS),
                       '--submissions', str(submissions), '--out', str(out_dir / 'graded'),
                       '--jobs', str(os.cpu_count() or 1)])


def run_live_task() -> bool:
    """Run LIVE_TASK live for LIVE_DURATION_S wall seconds; return True when it ended cleanly."""
    print(f'\n=== Live: ./lab live {LIVE_TASK} --duration {LIVE_DURATION_S:g} (the simulator and '
          'the node as two ROS 2 processes) ===', flush=True)
    return live_command.main([LIVE_TASK, '--duration', f'{LIVE_DURATION_S:g}']) == 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; return 0 when every task ran, every scenario passed and live ran cleanly."""
    parser = argparse.ArgumentParser(prog='./lab demo', description=__doc__.strip().split('\n')[0])
    parser.add_argument('--out', type=output_folder, default=Path('out') / 'demo',
                        help='output folder (default out/demo)')
    parser.add_argument('--no-grade', action='store_true',
                        help='only run the lab tasks, not the grading scenarios')
    parser.add_argument('--no-live', action='store_true',
                        help='skip the live run at the end (separate ROS 2 processes)')
    args = parser.parse_args(argv)
    print(f'ROS 2: {rclpy_origin()}', flush=True)
    try:
        tasks_ok = run_tasks(args.out / 'tasks')
    except RunError as error:  # this machine cannot run a node (a Python closed to the sandbox)
        print(f'error: {error}', file=sys.stderr)
        return 2
    status = 0 if args.no_grade else grade_scenarios(args.out / 'grade')
    if not args.no_grade:
        grade_class(args.out / 'class')  # its table shows who failed; that is the demo
    live_ok = args.no_live or run_live_task()
    print(f'\nDemo outputs: {args.out.resolve()} (tasks/<task>/, grade/<scenario>/seed_<n>/: '
          'trajectory.png, metrics.json, run/ rosbag2 recording; grade/report.html; '
          'class/graded/index.html)')
    return status if tasks_ok and live_ok else 1


if __name__ == '__main__':
    sys.exit(main())
