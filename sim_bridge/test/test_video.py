"""
A run's video: an H.264 MP4 that decodes, at simulated time, with the terminal and the names.

The runs are real (scan_ahead in the obstacles world, a few simulated seconds); the videos are
decoded with the FFmpeg imageio-ffmpeg ships, and their frames compared with frames drawn
without the part under test (the names, a console line). The robot is drawn where it was: the
bag's odometry mapped by the start pose the test computes itself (issue 32: counterclockwise
runs, the world's start turned round, were drawn rotated 180 degrees about their start).
"""

import json
import math
import os
from pathlib import Path
import subprocess
import sys

import imageio_ffmpeg
import numpy as np
import pytest

from sim_bridge.commands import grade
from sim_bridge.commands import task_video as lab_video, video as video_command
from sim_bridge.commands.run import main as run_main
from sim_bridge.live.lab_tasks import video_name
from sim_bridge.media import terminal_text, video
from sim_bridge.media.terminal_text import LogLine, terminal_rows
from sim_bridge.media.video import (
    BANNER_HEIGHT, FRAME_HEIGHT, FRAME_WIDTH, FrameRenderer, load_footage, read_recording,
    render_video, VideoError, WORLD_WIDTH)
from sim_bridge.runner.run import run_simulation
from sim_bridge.simulation.world import World

FIXTURES = Path(__file__).parent / 'fixtures'
DURATION_S = 3.0
#: A console line written at 1.55 s of sim time, the text the test looks for.
KNOWN_T = 1.55
KNOWN_LINE = '[INFO] [1795499925.029450212] [scan_ahead]: KNOWN LINE 4242 Range ahead: 0.87 m'
NAMES = 'Hassan Rizwan 335753, Ada Lovelace 100001'
#: The lab's tasks handed in as videos, by the handout's numbers (issue 18: marks 2, 3, 2, 3).
HANDOUT = {'scan_ahead': 1, 'wanderbot': 2, 'scan_around': 3, 'wall_follow': 4}


def write_log(out_dir: Path, lines: list[tuple[float, str]]) -> None:
    """Write a log.jsonl as the runner writes it: one JSON object a line."""
    with (out_dir / video.LOG_FILE).open('w', encoding='utf-8') as stream:
        for t, line in lines:
            stream.write(json.dumps({'t': t, 'node': 'scan_ahead', 'level': 'INFO',
                                     'text': line.partition(': ')[2], 'line': line}) + '\n')


@pytest.fixture(scope='module')
def run_dir(tmp_path_factory):
    """Return a finished 3 s run, with console lines every 0.5 s and KNOWN_LINE at KNOWN_T."""
    out = tmp_path_factory.mktemp('video') / 'run'
    run_simulation('obstacles', ['scan_ahead'], duration_s=DURATION_S, seed=1, out_dir=out,
                   quiet=True, plot=False)
    lines = [(0.5 * k, f'[INFO] [1795499925.0] [scan_ahead]: Range ahead: {k}.00 m')
             for k in range(1, 6)]
    write_log(out, sorted(lines + [(KNOWN_T, KNOWN_LINE)]))
    return out


def decode(path: Path) -> tuple[dict, list[np.ndarray]]:
    """Return a video's metadata and every frame (H, W, 3 uint8), decoded by FFmpeg."""
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta['size']
    frames = [np.frombuffer(frame, np.uint8).reshape(height, width, 3) for frame in reader]
    return meta, frames


def difference(a: np.ndarray, b: np.ndarray) -> float:
    """Return the mean absolute difference of two images (0 to 255)."""
    return float(np.abs(a.astype(float) - b.astype(float)).mean())


@pytest.mark.parametrize('speed, fps', [(1.0, 10.0), (2.0, 10.0), (0.5, 12.0)])
def test_a_runs_video_decodes_with_its_frames_size_and_simulated_duration(
        run_dir, tmp_path, speed, fps):
    info = render_video(run_dir, tmp_path / 'run.mp4', NAMES, speed=speed, fps=fps)
    meta, frames = decode(info.path)
    assert meta['codec'] == 'h264' and meta['pix_fmt'].startswith('yuv420p')
    assert meta['size'] == (FRAME_WIDTH, FRAME_HEIGHT) and FRAME_WIDTH % 2 == FRAME_HEIGHT % 2 == 0
    assert len(frames) == info.frames == round(DURATION_S / speed * fps)
    assert meta['fps'] == pytest.approx(fps)
    assert meta['duration'] == pytest.approx(DURATION_S / speed, abs=1.0 / fps)


def test_the_video_is_faststart_so_a_browser_plays_it_while_loading(run_dir, tmp_path):
    data = render_video(run_dir, tmp_path / 'run.mp4').path.read_bytes()
    assert data.index(b'moov') < data.index(b'mdat')


def test_a_console_line_appears_in_the_terminal_at_its_simulated_time(run_dir, tmp_path):
    fps = 10.0
    info = render_video(run_dir, tmp_path / 'run.mp4', NAMES, fps=fps)
    _, frames = decode(info.path)
    with_line = FrameRenderer(load_footage(run_dir), NAMES)
    footage = load_footage(run_dir)
    footage.log = [entry for entry in footage.log if entry.line != KNOWN_LINE]
    without = FrameRenderer(footage, NAMES)
    terminal = np.s_[BANNER_HEIGHT:, WORLD_WIDTH:]
    # Frame k shows the run at (k + 1) / fps s: frame 14 at 1.5 s, before the line was
    # written (1.55 s), frame 15 at 1.6 s, after.
    before, after = 14, 15
    assert np.array_equal(with_line.frame(1.5), without.frame(1.5))
    shown, hidden = with_line.frame(1.6)[terminal], without.frame(1.6)[terminal]
    # Where the two differ: the rows of the terminal the line takes (the rest scrolled too).
    rows = np.any(shown != hidden, axis=(1, 2))
    assert rows.any()
    decoded = frames[after][terminal][rows]
    assert difference(decoded, shown[rows]) < difference(decoded, hidden[rows]) / 4
    earlier = frames[before][terminal][rows]
    assert difference(earlier, hidden[rows]) < difference(earlier, shown[rows]) / 4


def test_the_terminal_shows_the_known_line_and_the_nodes_command(run_dir):
    footage = load_footage(run_dir)
    assert footage.commands == ['ros2 run scan_pkg scan_ahead --ros-args --params-file '
                                'params.yaml -p use_sim_time:=true']
    pane = FrameRenderer(footage, NAMES).terminal
    count = pane.count_at(KNOWN_T)
    with_line, before = np.asarray(pane.image(count)), np.asarray(pane.image(count - 1))
    rows = np.flatnonzero(np.any(with_line != before, axis=(1, 2)))
    # The new line is drawn below the command and the earlier lines, in one text row.
    assert rows.min() >= pane.header_height + 3 * terminal_text.TERMINAL_LINE_HEIGHT
    assert rows.max() - rows.min() < terminal_text.TERMINAL_LINE_HEIGHT
    alone = FrameRenderer(footage, NAMES).terminal
    alone.log = [LogLine(KNOWN_T, 'INFO', KNOWN_LINE)]
    alone.times = np.array([KNOWN_T])
    drawn = np.asarray(alone.image(1))
    # The same text drawn alone is the same pixels, one row up (nothing above it but the header).
    top = pane.header_height
    shift = rows.min() - top - (rows.min() - top) % terminal_text.TERMINAL_LINE_HEIGHT
    assert np.array_equal(with_line[top + shift:top + shift + terminal_text.TERMINAL_LINE_HEIGHT],
                          drawn[top:top + terminal_text.TERMINAL_LINE_HEIGHT])


def test_the_terminal_scrolls_and_wraps_as_a_terminal_does():
    assert terminal_rows('ab\tc\x1b[31mred\x1b[0m', 80) == ['ab      cred']
    assert terminal_rows('x' * 25, 10) == ['x' * 10, 'x' * 10, 'x' * 5]
    pane = terminal_text.TerminalPane((400, 200), ['my_node --ros-args'],
                                      [LogLine(k, 'INFO', f'line {k}') for k in range(100)])
    assert pane.capacity < 100
    full, later = np.asarray(pane.image(50)), np.asarray(pane.image(51))
    body = np.s_[pane.header_height:]
    assert not np.array_equal(full[body], later[body])  # everything moved up a row
    assert np.array_equal(full[:pane.header_height - 8], later[:pane.header_height - 8])


def test_the_names_are_on_the_first_and_the_last_frame(run_dir, tmp_path):
    info = render_video(run_dir, tmp_path / 'run.mp4', NAMES)
    _, frames = decode(info.path)
    renderer = FrameRenderer(load_footage(run_dir), NAMES)
    banner = np.s_[:BANNER_HEIGHT, :WORLD_WIDTH]
    times = video.frame_times(DURATION_S, 1.0, video.DEFAULT_FPS)
    for index in (0, len(frames) - 1):
        named = renderer.frame(times[index])[banner]
        unnamed = renderer.frame(times[index], names=False)[banner]
        assert difference(named, unnamed) > 5.0
        assert difference(frames[index][banner], named) < difference(
            frames[index][banner], unnamed) / 4


def test_the_robot_moves_in_the_world_pane(tmp_path):
    out = tmp_path / 'run'
    run_simulation('wall_follow_box', ['wall_follow'], duration_s=4.0, seed=1, out_dir=out,
                   quiet=True, plot=False)
    renderer = FrameRenderer(load_footage(out), NAMES)
    world = np.s_[BANNER_HEIGHT:, :WORLD_WIDTH]
    assert difference(renderer.frame(0.5)[world], renderer.frame(4.0)[world]) > 0.1
    # Drawn in any order, a frame is the same frame.
    assert np.array_equal(renderer.frame(0.5), FrameRenderer(load_footage(out), NAMES).frame(0.5))


def test_a_folder_without_a_run_is_one_line_error(tmp_path, capsys):
    assert video_command.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('error: ') and 'metrics.json' in err and err.count('\n') == 1
    with pytest.raises(VideoError, match=r'log.jsonl:2'):
        (tmp_path / video.LOG_FILE).write_text('{"t": 0, "line": "a"}\nnot json\n')
        video.read_log(tmp_path / video.LOG_FILE)


def test_a_video_that_cannot_be_written_is_one_line_naming_it(run_dir, tmp_path, capsys):
    taken = tmp_path / 'taken.mp4'
    taken.mkdir()
    assert video_command.main([str(run_dir), '-o', str(taken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'error: cannot write {taken}') and err.count('\n') == 1, err


@pytest.mark.parametrize('ffmpeg, reason', [
    ('#!/bin/sh\necho "Unknown encoder \'libx264\'" >&2\nexit 1\n', "Unknown encoder 'libx264'"),
    ('#!/bin/sh\nexit 1\n', 'exit status 1'),
    (None, 'cannot start: No such file or directory')], ids=['says', 'silent', 'missing'])
def test_an_encoder_that_fails_is_one_line_saying_why(run_dir, tmp_path, monkeypatch, capfd,
                                                      ffmpeg, reason):
    executable = tmp_path / 'ffmpeg'
    if ffmpeg is not None:
        executable.write_text(ffmpeg)
        executable.chmod(0o755)
    monkeypatch.setenv('IMAGEIO_FFMPEG_EXE', str(executable))
    target = tmp_path / 'run.mp4'
    assert video_command.main([str(run_dir), '-o', str(target)]) == 2
    err = capfd.readouterr().err
    assert err.startswith('error: the video encoder') and err.count('\n') == 1, err
    assert reason in err and not target.exists()
    assert not list(tmp_path.glob('.*.partial.mp4'))


def test_the_runner_writes_the_video_it_is_asked_for(tmp_path, capfd):
    target = tmp_path / 'labscan_task1.mp4'
    status = run_main(['--world', 'obstacles', '--node', 'scan_ahead', '--duration', '2',
                       '--out', str(tmp_path / 'run'), '--quiet', '--video', str(target),
                       '--names', NAMES, '--speed', '2'])
    assert status == 0
    meta, frames = decode(target)
    assert len(frames) == 10 and meta['duration'] == pytest.approx(1.0, abs=0.1)
    assert run_main(['--world', 'obstacles', '--node', 'scan_ahead', '--no-record',
                     '--video', str(target)]) == 2
    assert '--no-record' in capfd.readouterr().err


def test_the_video_of_a_failing_graded_run_plays_from_its_report(tmp_path):
    scenario = tmp_path / 'raiser.yaml'
    scenario.write_text(
        f"world: obstacles\nnodes: ['{FIXTURES / 'raising_node.py'}']\nduration: 3.0\n"
        'criteria: [len(node_errors) == 0]\n')
    out = tmp_path / 'grade'
    status = grade.main([str(scenario), '--out', str(out), '--quiet', '--video',
                         '--names', NAMES])
    assert status == 1
    page = (out / grade.PAGE_NAME).read_text()
    videos = video_sources(page)
    assert len(videos) == 1
    played = (out / videos[0]).resolve()
    assert played == (out / 'raiser' / 'seed_0' / 'video.mp4').resolve()
    meta, frames = decode(played)
    assert meta['codec'] == 'h264' and len(frames) >= 1
    assert f'href="{videos[0]}"' in page


def video_sources(page: str) -> list[str]:
    """Return the ``src`` of each ``<video>`` of a page."""
    from html.parser import HTMLParser

    class Videos(HTMLParser):

        def __init__(self):
            super().__init__()
            self.sources = []

        def handle_starttag(self, tag, attrs):
            if tag == 'video':
                self.sources += [value for name, value in attrs if name == 'src']
    parser = Videos()
    parser.feed(page)
    return parser.sources


def test_ffmpeg_is_the_one_imageio_ffmpeg_ships():
    version = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), '-hide_banner', '-encoders'],
                             capture_output=True, text=True, check=True).stdout
    assert 'libx264' in version


def test_a_recorded_live_session_has_a_runs_outputs_and_its_video(tmp_path):
    """``./lab live TASK --record OUT`` (two ROS 2 processes on a domain of this test's own)."""
    out = tmp_path / 'live'
    env = dict(os.environ, ROS_DOMAIN_ID=str(200 + os.getpid() % 30))
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    result = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.commands.live', 'scan_ahead', '--duration', '6',
         '--record', str(out)], env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['sim_time_s'] > 0 and metrics['run_mode']['mode'] == 'live'
    assert (out / 'trajectory.png').is_file() and (out / 'params.yaml').is_file()
    log = video.read_log(out / video.LOG_FILE)
    ranges = [entry for entry in log if 'Range ahead' in entry.line]
    # In the order printed, at the sim time then (before this process hears the first /clock,
    # while DDS discovery completes, told from the wall clock).
    times = [entry.t for entry in ranges]
    assert times == sorted(times) and 0 < times[-1] <= metrics['sim_time_s']
    # A line is stamped when it reaches this process: lines a busy machine delivers together
    # share a stamp, but scan_ahead logs every 0.1 s of a 6 s session: they spread over it.
    assert times[-1] - times[0] > 1.0
    # The node's lines, as the terminal showed them (launch's prefix aside); not the simulator's.
    assert all(f'[scan_ahead-2] {entry.line}' in result.stdout for entry in log)
    assert not any('[sim_bridge]' in entry.line for entry in log)
    info = render_video(out, tmp_path / 'live.mp4', NAMES)
    meta, frames = decode(info.path)
    assert len(frames) == round(metrics['sim_time_s'] * video.DEFAULT_FPS)
    footage = load_footage(out)
    assert len(footage.scans) > 10 and footage.commands[0].startswith('ros2 run scan_pkg')


@pytest.mark.parametrize('text, task', [('scan_ahead', 'scan_ahead'), ('1', 'scan_ahead'),
                                        ('task2', 'wanderbot'), ('3', 'scan_around'),
                                        ('4', 'wall_follow')])
def test_a_lab_task_is_named_or_numbered_as_the_handout_numbers_it(text, task):
    assert lab_video.task_name(text) == task
    assert video_name(task) == f'labscan_task{HANDOUT[task]}.mp4'


def test_lab_video_of_the_kits_node_says_so_in_the_picture_and_carries_no_names(
        tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)
    assert lab_video.main(['1', '--speed', '2']) == 0
    meta, frames = decode(tmp_path / 'labscan_task1.mp4')
    out = tmp_path / 'out' / 'video' / 'scan_ahead'
    metrics = json.loads((out / 'metrics.json').read_text())
    assert len(frames) == round(metrics['sim_time_s'] / 2 * video.DEFAULT_FPS)
    assert 'labscan_task1.mp4' in capfd.readouterr().out
    # Every frame's banner says whose node it is: the kit's label, not a student's names.
    renderer = FrameRenderer(load_footage(out, teleop=True), lab_video.KIT_BANNER, speed=2.0)
    banner = np.s_[:BANNER_HEIGHT, :WORLD_WIDTH]
    times = video.frame_times(metrics['sim_time_s'], 2.0, video.DEFAULT_FPS)
    for index in (0, len(frames) - 1):
        labelled = renderer.frame(times[index])[banner]
        unlabelled = renderer.frame(times[index], names=False)[banner]
        assert difference(frames[index][banner], labelled) < difference(
            frames[index][banner], unlabelled) / 4
    # Students' names on a video of the kit's node are refused, in one line, before any run.
    with pytest.raises(SystemExit) as exited:
        lab_video.main(['1', '--names', NAMES, '--out', str(tmp_path / 'refused')])
    err = capfd.readouterr().err
    assert exited.value.code == 2 and err.count('\n') == 1
    assert err.startswith("error: --names without --node: a video of the kit's reference node")
    assert not (tmp_path / 'refused').exists()


def test_names_too_long_for_one_line_are_made_smaller_or_wrapped_never_cut():
    names = ', '.join(f'Student Number{index} With A Long Name 10000{index}' for index in range(5))
    banner = video.names_banner(names, 800)
    assert banner.size == (800, BANNER_HEIGHT)
    # The last name is drawn: the banner without it differs.
    without_last = video.names_banner(names.rpartition(', ')[0] + ',', 800)
    assert not np.array_equal(np.asarray(banner), np.asarray(without_last))
    # Two lines: ink in the top and the bottom half.
    ink = np.any(np.asarray(banner) != video.BANNER_BACKGROUND, axis=(1, 2))
    assert ink[:BANNER_HEIGHT // 2].any() and ink[BANNER_HEIGHT // 2:].any()


def test_a_real_runs_console_lines_reach_its_video_at_their_time(tmp_path):
    """End to end: the lines the runner kept (log.jsonl) in the decoded video, when written."""
    out = tmp_path / 'run'
    run_simulation('obstacles', ['scan_ahead'], duration_s=2.0, seed=1, out_dir=out,
                   quiet=True, plot=False)
    footage = load_footage(out)
    lines = [entry for entry in footage.log if 'Range ahead' in entry.line]
    assert lines and lines[0].line.startswith('[INFO] [') and 0 < lines[0].t < 2.0
    fps = 10.0
    _, frames = decode(render_video(out, tmp_path / 'run.mp4', NAMES, fps=fps).path)
    first = lines[0]
    index = int(np.ceil(first.t * fps - 1e-9)) - 1  # the first frame at or after it
    footage.log = [entry for entry in footage.log if entry is not first]
    without = FrameRenderer(footage, NAMES).frame((index + 1) / fps)
    shown = FrameRenderer(load_footage(out), NAMES).frame((index + 1) / fps)
    terminal = np.s_[BANNER_HEIGHT:, WORLD_WIDTH:]
    rows = np.any(shown[terminal] != without[terminal], axis=(1, 2))
    assert rows.any()
    decoded = frames[index][terminal][rows]
    assert difference(decoded, shown[terminal][rows]) < difference(
        decoded, without[terminal][rows]) / 4


STUDENT_NODE = """
import rclpy
from rclpy.node import Node
from sensor_msgs.msg import LaserScan


class ZedsReader(Node):

    def __init__(self):
        super().__init__('zeds_reader')
        self.create_subscription(LaserScan, 'scan', self.on_scan, 10)

    def on_scan(self, msg):
        self.get_logger().info(f'ZED SAYS ahead: {min(msg.ranges[17:19]):.2f}')


def main(args=None):
    rclpy.init(args=args)
    rclpy.spin(ZedsReader())


if __name__ == '__main__':
    main()
"""


def test_the_handouts_video_of_a_students_own_node(tmp_path, monkeypatch, capfd):
    """``./lab video 1 --node FILE``: the student's node, driven, its lines, 3-D, the teleop."""
    node = tmp_path / 'my_scan_ahead.py'
    node.write_text(STUDENT_NODE)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / 'out'
    assert lab_video.main(['1', '--node', str(node), '--names', NAMES, '--out', str(out)]) == 0
    meta, frames = decode(tmp_path / 'labscan_task1.mp4')
    metrics = json.loads((out / 'metrics.json').read_text())
    # Real time: a 26 s run is 26 s of video, no longer than 2 minutes.
    assert meta['duration'] == pytest.approx(metrics['sim_time_s'], abs=0.2)
    footage = load_footage(out, teleop=True)
    said = [entry for entry in footage.log if 'ZED SAYS ahead' in entry.line]
    assert len(said) > 200  # a line a scan, 10 scans a second
    # Stamped as a live run prints them: a scan's 0.1 s apart, whatever the stepped run took.
    stamps = [float(entry.line.split('] [')[1]) for entry in said[:11]]
    assert stamps[10] - stamps[0] == pytest.approx(said[10].t - said[0].t, abs=1e-6)
    # The teleop drove the robot: its keys, forward first; its terminal is in the frames.
    assert footage.teleop and "key 'i'" in footage.teleop[1].line
    renderer = FrameRenderer(footage, NAMES, view3d=True)
    teleop = np.s_[FRAME_HEIGHT - video.TELEOP_HEIGHT:, WORLD_WIDTH:]
    index = len(frames) - 1
    shown = renderer.frame((index + 1) / video.DEFAULT_FPS)
    assert difference(frames[index][teleop], shown[teleop]) < 8
    # The 3-D view under the top view: the robot in its world, drawn and moving.
    view = np.s_[BANNER_HEIGHT + video.TOP_VIEW_HEIGHT:, :WORLD_WIDTH]
    assert difference(frames[10][view], frames[-1][view]) > 5
    assert 'labscan_task1.mp4' in capfd.readouterr().out


def test_a_long_run_is_sped_up_to_a_video_of_two_minutes_unless_told():
    assert lab_video.video_speed(76.2, None) == 1.0
    assert lab_video.video_speed(180.0, None) == 1.5
    assert lab_video.video_speed(180.0, 4.0) == 4.0


PATH_DURATION_S = 6.0
PATH_WORLD = 'wall_follow_box'
#: The world's own start (x m, y m, yaw rad), turned round: the counterclockwise start.
PATH_WORLD_START = World.load(PATH_WORLD).robot_start
MIRRORED = (PATH_WORLD_START[0], PATH_WORLD_START[1], PATH_WORLD_START[2] + math.pi)


def odometry_in_world(out_dir: Path, start: tuple[float, float, float]) -> np.ndarray:
    """Return the bag's /odom (N, 2: x m, y m) mapped into the world by ``start``."""
    (_, odometry), _, _ = read_recording(out_dir / 'run')
    x0, y0, yaw0 = start
    cos_yaw, sin_yaw = math.cos(yaw0), math.sin(yaw0)
    return np.column_stack((x0 + cos_yaw * odometry[:, 0] - sin_yaw * odometry[:, 1],
                            y0 + sin_yaw * odometry[:, 0] + cos_yaw * odometry[:, 1]))


def drawn_robot_centre(frame: np.ndarray, tolerance: int = 2) -> np.ndarray:
    """
    Return the centre (column, row px of the world pane) of the robot drawn in a frame.

    ``tolerance``: how far (0-255 a channel) a pixel's colour may be from ROBOT_COLOUR (a
    decoded video's colours are the encoder's approximation).
    """
    pane = frame[BANNER_HEIGHT:, :WORLD_WIDTH].astype(int)
    robot = np.all(np.abs(pane - video.ROBOT_COLOUR) <= tolerance, axis=2)
    rows, columns = np.nonzero(robot)
    assert len(rows) > 20, 'no robot drawn'
    return np.array([columns.mean(), rows.mean()])


def assert_drawn_where_it_was(out_dir: Path, footage: video.Footage,
                              start: tuple[float, float, float]) -> None:
    """Check the path and the robot drawn against the odometry mapped by ``start``."""
    expected = odometry_in_world(out_dir, start)
    assert np.hypot(*(expected[-1] - expected[0])) > 1.0  # the robot went somewhere
    np.testing.assert_allclose(footage.poses[:, :2], expected, atol=1e-6)
    renderer = FrameRenderer(footage, 'Ada Lovelace 100001')
    for t in (1.0, PATH_DURATION_S / 2, PATH_DURATION_S):
        index = max(int(np.searchsorted(footage.pose_t, t, side='right')) - 1, 0)
        (column, row), = renderer.world.pixels(expected[index:index + 1])
        centre = drawn_robot_centre(renderer.frame(t))
        # Within a few pixels (the white nose line covers part of the outline's fill).
        assert np.hypot(centre[0] - column, centre[1] - row) < 4.0, (t, centre, column, row)


@pytest.mark.parametrize('start, pose', [('mirrored', MIRRORED),
                                         ((0.0, 1.1, 2.5), (0.0, 1.1, 2.5))],
                         ids=['counterclockwise', 'any_yaw'])
def test_a_runs_video_draws_the_robot_where_its_odometry_says_it_was(tmp_path, start, pose):
    out = tmp_path / 'run'
    run_simulation(PATH_WORLD, ['wall_follow'], duration_s=PATH_DURATION_S, seed=1, out_dir=out,
                   quiet=True, plot=False, start=start,
                   params={'wall_follow': {'side': 'left', 'speed': 0.3}})
    assert_drawn_where_it_was(out, load_footage(out), pose)


def test_the_graders_video_of_a_counterclockwise_scenario_draws_the_robot_where_it_was(
        tmp_path):
    scenario = tmp_path / 'ccw.yaml'
    scenario.write_text(
        f'world: {PATH_WORLD}\nnodes: [wall_follow]\nparams:\n  wall_follow: {{side: left}}\n'
        f'start: mirrored\nduration: {PATH_DURATION_S}\ncriteria: [len(node_errors) == 0]\n')
    out = tmp_path / 'grade'
    grade.main([str(scenario), '--out', str(out), '--quiet', '--video', '--names', 'A B'])
    run_dir = out / 'ccw' / 'seed_0'
    _, frames = decode(run_dir / video.VIDEO_NAME)
    expected = odometry_in_world(run_dir, MIRRORED)
    footage = load_footage(run_dir)
    # The last frame (the run's end) as the grader's video drew it, decoded.
    (column, row), = FrameRenderer(footage, '').world.pixels(expected[-1:])
    centre = drawn_robot_centre(frames[-1], tolerance=40)
    assert np.hypot(centre[0] - column, centre[1] - row) < 6.0, (centre, column, row)


@pytest.mark.parametrize('task', ['4', 'task4', 'wall_follow'])
def test_lab_video_takes_a_task_first_and_a_run_folder_otherwise(task, tmp_path, capsys):
    """``./lab video`` (the console script lab_video too) is one command for both videos."""
    with pytest.raises(SystemExit) as exited:  # a task: the handout's video, its rules
        video_command.main([task, '--names', NAMES, '--out', str(tmp_path / 'refused')])
    assert exited.value.code == 2
    assert capsys.readouterr().err.startswith('error: --names without --node')
    assert video_command.main([str(tmp_path)]) == 2  # a folder: a finished run's video
    assert 'metrics.json' in capsys.readouterr().err
