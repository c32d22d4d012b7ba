"""
Render a finished run as a video: the robot in its world beside the nodes' terminal.

``./lab video OUT_DIR --names "Ada Lovelace 123, ..." [-o labscan_task4.mp4] [--speed N]
[--fps F]`` (sim_bridge.commands.video hands it a finished run's folder) reads what a run left
in its output folder and writes an H.264 MP4 (yuv420p, faststart: it plays in a browser and in
common players):

- ``params.yaml``: the simulator's world, robot model and start pose (the ``sim_bridge`` entry);
- ``run/``: the rosbag2 recording, its ``/odom`` (the robot's pose, the simulator's ground
  truth) and ``/scan`` (every lidar scan);
- ``log.jsonl``: the nodes' console lines with the simulated time each was written;
- ``metrics.json``: the run's simulated length, its collisions and the command of each node.

Frames are at simulated time: a 76 s run is a 76 s video at ``speed`` 1, 19 s at 4. Each frame
shows the world from above as the robot could hit it (drawn once by sim_bridge.plot, then the
moving parts drawn on a copy), the path so far, the robot's outline, the beams of the last scan
and the simulated clock; beside it a terminal with the node's command at its top and the console
lines that were written by then, scrolling as a terminal does; the names on a banner over both.
Rendering uses matplotlib's Agg canvas and Pillow (no display), the encoder is the FFmpeg that
imageio-ffmpeg ships on PyPI. Pure: no rclpy.
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
