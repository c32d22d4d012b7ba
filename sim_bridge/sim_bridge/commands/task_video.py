"""
The handout's video of a lab task in one command: ``./lab video TASK --names "..."``.

``python -m sim_bridge.commands.task_video TASK --node FILE --names "Ada Lovelace 123, ..."
[--speed N] [--out DIR]`` runs the student's node FILE (without ``--node``, the kit's example)
in the first seed of the task's shipped scenario (sim_bridge.live.lab_tasks.TASK_SCENARIOS, with
its ``drive:`` segments where it has them, as the grader runs it), its outputs in ``--out``
(default ``out/video/<task>``), and writes its video (sim_bridge.media.video) named as the
handout names it, ``labscan_task1.mp4`` ... ``labscan_task4.mp4``, in the current folder (or
``-o FILE``). It lasts at most MAX_VIDEO_S (sped up, the speed shown on every frame) unless
``--speed`` says otherwise.
"""

import argparse
from pathlib import Path
import sys
from typing import Sequence

from sim_bridge.common.paths import scenarios_dir
from sim_bridge.grading.runs import run_scenario
from sim_bridge.grading.scenario import load_scenario
from sim_bridge.live.lab_tasks import HANDOUT_NUMBERS, TASK_SCENARIOS, video_name
from sim_bridge.media.video import failure_line, render_video, VideoError

#: The longest video (s) a TA watches without ``--speed``: a longer run is sped up to fit.
MAX_VIDEO_S = 120.0


def video_speed(duration_s: float, speed: float | None) -> float:
    """Return ``speed``, or the least of 1 and faster that fits ``duration_s`` in MAX_VIDEO_S."""
    if speed is not None:
        return speed
    return max(1.0, duration_s / MAX_VIDEO_S)


def task_name(text: str) -> str:
    """Return the lab task ``text`` names: a task (``wall_follow``) or a handout number (4)."""
    numbers = {str(number): task for task, number in HANDOUT_NUMBERS.items()}
    task = numbers.get(text.removeprefix('task'), text)
    if task not in TASK_SCENARIOS:
        raise argparse.ArgumentTypeError(
            f"'{text}': a lab task is one of {', '.join(TASK_SCENARIOS)} or the handout's "
            f"number {', '.join(sorted(numbers))}")
    return task


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line."""
    parser = argparse.ArgumentParser(prog='./lab video',
                                     description=__doc__.strip().splitlines()[0])
    parser.add_argument('task', type=task_name, metavar='TASK',
                        help=f"{', '.join(TASK_SCENARIOS)}, or the handout's task number")
    parser.add_argument('--names', required=True, help="the students' names, on every frame")
    parser.add_argument('--node', type=Path, metavar='FILE',
                        help="the student's node file to run (default: the kit's example node)")
    parser.add_argument('--speed', type=float, metavar='N',
                        help='simulated seconds per second of video (default: real time, faster '
                        f'for a run that would last more than {MAX_VIDEO_S:g} s of video)')
    parser.add_argument('--out', type=Path, metavar='DIR',
                        help="the run's output folder (default out/video/TASK)")
    parser.add_argument('-o', '--output', type=Path, metavar='FILE.mp4',
                        help="the video file (default: the handout's name, labscan_taskN.mp4)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run a task's scenario and write its video: 0, 1 when the run failed, 2 when no video."""
    args = parse_args(argv)
    try:
        scenarios = scenarios_dir()
    except FileNotFoundError as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    out_dir = args.out or Path('out') / 'video' / args.task
    output = args.output or Path(video_name(args.task))
    try:
        scenario = load_scenario(scenarios / TASK_SCENARIOS[args.task])
        if args.node is not None:
            if not args.node.is_file():
                raise ValueError(f'--node {args.node}: no such file')
            scenario = scenario.with_node_override(str(args.node.resolve()))
        run = scenario.runs()[0]
        print(f'{args.task}: {scenario.description or scenario.name} (seed {run.seed}, '
              f'{scenario.duration_s:g} s simulated)', file=sys.stderr)
        report = run_scenario(run, out_dir, quiet=False)
        if report.metrics is None:
            print(f'error: {report.error}', file=sys.stderr)
            return 2
        speed = video_speed(scenario.duration_s, args.speed)
        info = render_video(out_dir, output, args.names, speed=speed,
                            teleop=bool(scenario.drive), view3d=True)
    except (ValueError, VideoError, OSError) as error:
        print(f'error: {failure_line(error, output)}', file=sys.stderr)
        return 2
    print(f'{info.path}: {info.duration_s:.1f} s of video ({speed:g}x simulated time); '
          f"the run's outputs are in {out_dir}")
    return 0 if report.passed else 1


if __name__ == '__main__':
    sys.exit(main())
