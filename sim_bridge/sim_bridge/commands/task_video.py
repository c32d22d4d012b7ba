"""
The handout's video of a lab task in one command: ``./lab video TASK --node FILE --names "..."``.

``./lab video TASK --node FILE --names "Ada Lovelace 123, ..."
[--direction cw|ccw] [--speed N] [--out DIR] [-o FILE]`` runs the student's node FILE in the
first seed of the task's shipped scenario (sim_bridge.live.lab_tasks.TASK_SCENARIOS, with its
``drive:`` segments where it has them, as the grader runs it), its outputs in ``--out`` (default
``out/video/<task>``), and writes its video (sim_bridge.media.video) named as the handout names
it, ``labscan_task1.mp4`` ... ``labscan_task4.mp4``, in the current folder (or ``-o FILE``).

A task whose node loops either way round its object (lab_tasks.LOOP_SCENARIOS: wall_follow) is
filmed from the start of the direction the node follows: ``--direction``, else the one it went
further round the object from in a TRIAL_S trial from each start (the winding the grader
measures on the ground truth). Without ``--node`` the video films the kit's reference node
and says so on every frame (KIT_BANNER) where the names would be: ``--names`` without
``--node`` is refused, a video of the kit's node is no student's work. It lasts at most
MAX_VIDEO_S (sped up, the speed shown on every frame) unless ``--speed`` says otherwise.

Every failure is one line on stderr: exit status 2 when no video was made, 1 when the video
shows a run that failed (the line says how), 0 otherwise.
"""

import argparse
from dataclasses import replace
import math
from pathlib import Path
import sys
import tempfile
from typing import Sequence

from sim_bridge.common.paths import scenarios_dir
from sim_bridge.common.text import first_line
from sim_bridge.grading.runs import run_scenario, RunReport
from sim_bridge.grading.scenario import load_scenario, Scenario
from sim_bridge.live.lab_tasks import (
    HANDOUT_NUMBERS, LOOP_SCENARIOS, TASK_SCENARIOS, video_name)
from sim_bridge.media.video import failure_line, render_video, VideoError
from sim_bridge.scoring.motion_evidence import DIRECTIONS

#: The longest video (s) a TA watches without ``--speed``: a longer run is sped up to fit.
MAX_VIDEO_S = 120.0
#: What a video of the kit's own node shows where a student's video shows the names.
KIT_BANNER = "the kit's reference node, not a student's"
#: ``--direction``'s words for the loop directions.
DIRECTION_FLAGS = {'cw': 'clockwise', 'ccw': 'counterclockwise'}
#: The simulated length (s) of the trial from each start that finds the direction a node loops.
TRIAL_S = 20.0
#: The sign of a winding (turns round the object, + counterclockwise) in each direction.
WINDING_SIGNS = {direction: sign for sign, direction in DIRECTIONS.items()}
#: The longest line (characters) that says how a run failed: a terminal's few lines, not a page.
LINE_CHARS = 400


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose every error is one line on stderr (exit status 2)."""

    def error(self, message: str):
        """Print ``message`` as one line and exit with status 2."""
        self.exit(2, f'error: {message} (see {self.prog} --help)\n')


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
    """Parse the command line; a bad one is one line on stderr (exit status 2)."""
    parser = OneLineParser(prog='./lab video', description=__doc__.strip().splitlines()[0],
                           epilog='./lab video OUT_DIR --names "..." [-o FILE.mp4] [--speed N]: '
                           "the video of a finished run's output folder instead (./lab video "
                           'OUT_DIR --help)')
    parser.add_argument('task', type=task_name, metavar='TASK',
                        help=f"{', '.join(TASK_SCENARIOS)}, or the handout's task number")
    parser.add_argument('--node', type=Path, metavar='FILE',
                        help="the student's node file to run (without it: the kit's reference "
                        'node, labelled so on every frame)')
    parser.add_argument('--names', help="the students' names, on every frame (with --node)")
    parser.add_argument('--direction', choices=DIRECTION_FLAGS,
                        help='the loop to film for a task that loops round an object (default: '
                        f'the one the node follows in a {TRIAL_S:g} s trial from each start)')
    parser.add_argument('--speed', type=float, metavar='N',
                        help='simulated seconds per second of video (default: real time, faster '
                        f'for a run that would last more than {MAX_VIDEO_S:g} s of video)')
    parser.add_argument('--out', type=Path, metavar='DIR',
                        help="the run's output folder (default out/video/TASK)")
    parser.add_argument('-o', '--output', type=Path, metavar='FILE.mp4',
                        help="the video file (default: the handout's name, labscan_taskN.mp4)")
    args = parser.parse_args(argv)
    problem = argument_problem(args)
    if problem is not None:
        parser.error(problem)
    return args


def argument_problem(args: argparse.Namespace) -> str | None:
    """Return what is wrong with a parsed command line, or None."""
    if args.node is None and args.names is not None:
        return ("--names without --node: a video of the kit's reference node is no student's "
                'work; film your own node with --node FILE --names "..."')
    if args.node is not None and not (args.names or '').strip():
        return "--node needs --names: the students' names, shown on every frame"
    if args.direction is not None and args.task not in LOOP_SCENARIOS:
        loops = ', '.join(LOOP_SCENARIOS)
        return f'--direction: {args.task} does not loop round an object (only {loops} does)'
    if args.speed is not None and not (math.isfinite(args.speed) and args.speed > 0):
        return f'--speed must be a positive number of simulated seconds, got {args.speed}'
    return None


def filmed_scenario(args: argparse.Namespace, scenarios: Path) -> Scenario:
    """
    Return the scenario the video films: the task's, with the student's node when given.

    For a task that loops round an object, the scenario of ``--direction``, else of the
    direction the student's node follows (:func:`followed_direction`), else (the kit's node)
    the kit's. ValueError names a missing node file or a scenario that cannot be used.
    """
    node = None
    if args.node is not None:
        if not args.node.is_file():
            raise ValueError(f'--node {args.node}: no such file')
        node = str(args.node.resolve())
    loops = LOOP_SCENARIOS.get(args.task)
    if loops is None:
        name = TASK_SCENARIOS[args.task]
    elif args.direction is not None:
        name = loops[DIRECTION_FLAGS[args.direction]]
    elif node is not None:
        name = loops[followed_direction(loops, scenarios, node)]
    else:
        name = TASK_SCENARIOS[args.task]
    scenario = load_scenario(scenarios / name)
    return scenario if node is None else scenario.with_node_override(node)


def followed_direction(loops: dict[str, str], scenarios: Path, node: str) -> str:
    """
    Return the direction the node file ``node`` loops in, and say so on stderr.

    ``loops`` maps each direction to its scenario file in ``scenarios``. The node runs for
    TRIAL_S from each of their starts (unrecorded, in a scratch folder); the direction is the
    one whose start it went further round the object from, in that direction: the winding the
    grader measures on the ground truth (a tie: the first, the kit's). ValueError when a trial
    cannot run.
    """
    progress = {}
    with tempfile.TemporaryDirectory(prefix='lab-video-trial-') as scratch:
        for direction, name in loops.items():
            scenario = load_scenario(scenarios / name).with_node_override(node)
            run = replace(scenario, duration_s=TRIAL_S).runs()[0]
            report = run_scenario(run, Path(scratch) / direction, quiet=True, record=False,
                                  plot=False)
            if report.metrics is None:
                raise ValueError(f'{Path(node).name}: {run_failure(report)}')
            evidence = report.metrics.get('wall_follow') or {}
            progress[direction] = float(evidence.get('winding') or 0.0) * WINDING_SIGNS[direction]
    chosen = max(progress, key=progress.get)
    went = ', '.join(f'{turns:+.2f} of a loop from the {direction} start'
                     for direction, turns in progress.items())
    print(f'filming {chosen}: in a {TRIAL_S:g} s trial the node went {went} '
          '(--direction cw|ccw to choose)', file=sys.stderr)
    return chosen


def run_failure(report: RunReport) -> str:
    """Return one line saying how a run failed: its error, a node's error or its criteria."""
    if report.error is not None:
        return first_line(report.error, LINE_CHARS)
    node_errors = (report.metrics or {}).get('node_errors') or []
    if node_errors:  # its text names the node: "node 'raiser' raised ZeroDivisionError: ..."
        return first_line(str(node_errors[0].get('error')), LINE_CHARS)
    failed = [result.shown or result.criterion for result in report.results if not result.passed]
    return first_line(f"not every criterion held: {', '.join(failed)}", LINE_CHARS)


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
        scenario = filmed_scenario(args, scenarios)
        run = scenario.runs()[0]
        print(f'{args.task}: {scenario.description or scenario.name} (seed {run.seed}, '
              f'{scenario.duration_s:g} s simulated)', file=sys.stderr)
        report = run_scenario(run, out_dir, quiet=False)
        if report.metrics is None:
            raise ValueError(run_failure(report))
        speed = video_speed(scenario.duration_s, args.speed)
        banner = KIT_BANNER if args.node is None else args.names
        info = render_video(out_dir, output, banner, speed=speed,
                            teleop=bool(scenario.drive), view3d=True)
    except (ValueError, VideoError, OSError) as error:
        print(f'error: {failure_line(error, output)}', file=sys.stderr)
        return 2
    print(f'{info.path}: {info.duration_s:.1f} s of video ({speed:g}x simulated time); '
          f"the run's outputs are in {out_dir}")
    if report.passed:
        return 0
    print(f'error: the run failed, as the video shows: {run_failure(report)}', file=sys.stderr)
    return 1


if __name__ == '__main__':
    sys.exit(main())
