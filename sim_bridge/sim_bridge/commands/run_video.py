"""
Render a finished run as a video: the robot in its world beside the nodes' terminal.

``./lab video OUT_DIR --names "Ada Lovelace 123, ..." [-o labscan_task4.mp4] [--speed N]
[--fps F]`` (sim_bridge.commands.video hands it a finished run's folder) reads what a run left
in its output folder (``params.yaml``, the recording ``run/``, ``log.jsonl``, ``metrics.json``)
and writes an H.264 MP4 that plays in a browser and in common players; what each frame shows,
and from which of those files, is :mod:`sim_bridge.media.video`'s. Pure: no rclpy.
"""

import argparse
from pathlib import Path
import sys
from typing import Sequence

from sim_bridge.media.video import (
    DEFAULT_FPS, failure_line, render_video, VIDEO_NAME, VideoError)


def main(argv: Sequence[str] | None = None) -> int:
    """Write a run's video from the command line; 0 when written, 2 when it cannot be."""
    args = parse_args(argv)
    output = args.output or args.out_dir / VIDEO_NAME
    try:
        info = render_video(args.out_dir, output, args.names, speed=args.speed, fps=args.fps)
    except (VideoError, OSError) as error:
        print(f'error: {failure_line(error, output)}', file=sys.stderr)
        return 2
    print(f'{info.path}: {info.frames} frames, {info.duration_s:.1f} s at {info.fps:g} fps '
          f'({args.speed:g}x simulated time), {info.size[0]}x{info.size[1]}')
    return 0


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line."""
    parser = argparse.ArgumentParser(
        prog='./lab video OUT_DIR', description=__doc__.strip().splitlines()[0])
    parser.add_argument('out_dir', type=Path, metavar='OUT_DIR',
                        help="a run's output folder (./lab run --out, ./lab live --record)")
    parser.add_argument('--names', default='', help="the students' names, shown on every frame")
    parser.add_argument('-o', '--output', type=Path, metavar='FILE.mp4',
                        help='the video file (default OUT_DIR/video.mp4)')
    parser.add_argument('--speed', type=float, default=1.0,
                        help='simulated seconds per second of video (default 1: real time)')
    parser.add_argument('--fps', type=float, default=DEFAULT_FPS,
                        help=f'frames per second (default {DEFAULT_FPS:g})')
    return parser.parse_args(argv)


if __name__ == '__main__':
    sys.exit(main())
