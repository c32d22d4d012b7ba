"""
Benchmark a run's video: wall seconds to render 76.2 s of wall_follow at 1x, against the run.

One sitting: the stepped run of the wall_follow_box_cw scenario (76.2 simulated seconds, with
its recording), timed; then its video at speed 1 (762 frames at 10 fps, 1280x720, H.264),
timed as a whole, then reading the outputs and drawing the frames alone.
Rendering must be no slower than real time: its wall seconds under the 76.2 s of simulated
time. The log lines are what the run wrote (``log.jsonl``: wall_follow's few), then one a scan
as scan_ahead prints them (a terminal scrolling at 10 lines a second).

Run: python test/bench/bench_video.py
"""

import json
from pathlib import Path
import tempfile
import time

from sim_bridge.common.run_environment import keep_dds_in_process
from sim_bridge.media.video import (
    DEFAULT_FPS, frame_times, FrameRenderer, load_footage, LOG_FILE, render_video)
from sim_bridge.runner.run import run_simulation

DURATION_S = 76.2
NAMES = 'Hassan Rizwan 335753, Ada Lovelace 100001'


def main() -> None:
    """Time the run, then its video; print the figures."""
    keep_dds_in_process()
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / 'run'
        start = time.perf_counter()
        run_simulation('wall_follow_box', ['wall_follow'], duration_s=DURATION_S, seed=1,
                       out_dir=out, quiet=True, params={'wall_follow': {'side': 'right'}})
        run_s = time.perf_counter() - start
        start = time.perf_counter()
        info = render_video(out, Path(scratch) / 'video.mp4', NAMES, speed=1.0)
        render_s = time.perf_counter() - start
        # A busy terminal: a line every scan (10 Hz), as scan_ahead prints, instead of the few
        # lines wall_follow prints when its state changes.
        with (out / LOG_FILE).open('w') as stream:
            for k in range(int(DURATION_S * 10)):
                line = f'[INFO] [1795499925.{k:09d}] [wall_follow]: scan {k}: 0.50 m ahead'
                stream.write(json.dumps({'t': k / 10, 'node': 'wall_follow', 'level': 'INFO',
                                         'text': line, 'line': line}) + '\n')
        start = time.perf_counter()
        render_video(out, Path(scratch) / 'busy.mp4', NAMES, speed=1.0)
        busy_s = time.perf_counter() - start
        # The parts: reading the outputs, and drawing the frames alone (the encoder, FFmpeg in
        # a process of its own, works beside the drawing).
        start = time.perf_counter()
        footage = load_footage(out)
        read_s = time.perf_counter() - start
        renderer = FrameRenderer(footage, NAMES)
        start = time.perf_counter()
        for t in frame_times(footage.duration_s, 1.0, DEFAULT_FPS):
            renderer.frame(t)
        draw_s = time.perf_counter() - start
        size_mb = info.path.stat().st_size / 2 ** 20
    print(f'wall_follow_box, {DURATION_S:g} s simulated; video {info.frames} frames at '
          f'{info.fps:g} fps, {info.size[0]}x{info.size[1]}, {size_mb:.1f} MiB')
    rows = [('the run (stepped, recorded)', run_s),
            ('its video at 1x (render_video)', render_s),
            ('  the same, a log line every scan', busy_s),
            ('  reading the outputs', read_s),
            ('  drawing the frames (no encoding)', draw_s)]
    for name, seconds in rows:
        print(f'  {name:<34} {seconds:7.2f} s wall')
    print(f'  video vs simulated time: {render_s:.1f} s to render {DURATION_S:g} s '
          f'({DURATION_S / render_s:.1f}x faster than real time; '
          f'{DURATION_S / busy_s:.1f}x with a line every scan)')
    print(f"  video vs the run: {render_s / run_s:.1f}x the run's wall time")


if __name__ == '__main__':
    main()
