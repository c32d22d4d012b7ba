"""
Render a finished run as a video: the robot in its world beside the nodes' terminal.

``python -m sim_bridge.commands.video OUT_DIR --names "Ada Lovelace 123, ..." [-o
labscan_task4.mp4] [--speed N] [--fps F]`` reads what a run left in its output folder and writes an
H.264 MP4 (yuv420p, faststart: it plays in a browser and in common players):

- ``params.yaml``: the simulator's world, robot model and start pose (the ``sim_bridge`` entry);
- ``run/``: the rosbag2 recording, its ``/odom`` (the robot's pose, the simulator's ground
  truth) and ``/scan`` (every lidar scan);
- ``log.jsonl``: the nodes' console lines with the simulated time each was written;
- ``metrics.json``: the run's simulated length, its collisions and the command of each node.

Frames are at simulated time: a 76 s run is a 76 s video at ``speed`` 1, 19 s at 4. Each frame
shows the world from above as the robot could hit it (drawn once by sim_bridge.media.plot, then the
moving parts drawn on a copy), the path so far, the robot's outline, the beams of the last scan
and the simulated clock (with the speed when it is not real time); under it, when asked, the
robot in 3-D as a simulator's window shows it (media.view3d, rendered on the CPU); beside them a
terminal with the node's command at its top and the console lines that were written by then,
at the pace a live run prints them and stamped as it stamps them (media.terminal_text), scrolling
as a terminal does, and for a teleoperated run the teleop's terminal under it, with the keys
held; the names on a banner over all.
Rendering uses matplotlib's Agg canvas and Pillow (no display), the encoder is the FFmpeg that
imageio-ffmpeg ships on PyPI. Pure: no rclpy.
"""

from dataclasses import dataclass, field
from fractions import Fraction
import json
import math
import os
from pathlib import Path
import subprocess
import tempfile
from typing import Iterator

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np
from PIL import Image, ImageDraw
from sim_bridge.common.text import first_line
from sim_bridge.media.plot import _draw_world
from sim_bridge.media.terminal_text import (
    font, live_stamped, LogLine, teleop_lines, TerminalPane)
from sim_bridge.media.view3d import View3D
from sim_bridge.simulation.geometry import point_in_world
from sim_bridge.simulation.robot import pose_in_world
from sim_bridge.simulation.sdf_lidar import LidarConfig
from sim_bridge.simulation.world import World, WorldError
import yaml

#: Frame size (px): 720p, both even (yuv420p) and multiples of 16 (no rescaling by FFmpeg).
FRAME_WIDTH, FRAME_HEIGHT = 1280, 720
BANNER_HEIGHT = 40
WORLD_WIDTH = 640
DEFAULT_FPS = 10.0
BANNER_FONT_SIZE = 18
MIN_NAMES_FONT_SIZE = 12
BANNER_BACKGROUND = (21, 57, 110)
PATH_COLOUR = (21, 101, 192)
ROBOT_COLOUR = (46, 125, 50)
BEAM_COLOUR = (229, 115, 115)
#: A beam with no return, drawn to the lidar's range_max.
MISS_COLOUR = (225, 225, 225)
HIT_COLOUR = (198, 40, 40)
COLLISION_COLOUR = (213, 0, 0)
#: Bag topics the video reads.
ODOM_TOPIC, SCAN_TOPIC, CMD_VEL_TOPIC = '/odom', '/scan', '/cmd_vel'
#: The command the teleop's terminal shows, and its height (px) under the node's terminal.
TELEOP_COMMAND = 'ros2 run teleop_twist_keyboard teleop_twist_keyboard'
TELEOP_HEIGHT = 200
#: The height (px) of the top view when the 3-D view is under it, and the 3-D view's image
#: size (px), rendered smaller and scaled up: TinyRenderer's cost grows with the pixels.
TOP_VIEW_HEIGHT = 400
RENDERED_3D = (400, 175)
LOG_FILE = 'log.jsonl'
#: The video's file in a run's folder, when no other is named.
VIDEO_NAME = 'video.mp4'


class VideoError(Exception):
    """A run's outputs from which no video can be made; the text names the file and why."""


def failure_line(error: Exception, path: os.PathLike) -> str:
    """Return the one line a command prints when the video ``path`` could not be made."""
    if isinstance(error, OSError):  # a rename names its target second
        target = error.filename2 or error.filename or path
        return f'cannot write {target}: {error.strerror or error}'
    return str(error)


@dataclass
class Footage:
    """
    What a video shows of a run, read from its outputs.

    ``pose_t`` (s) and ``poses`` (N, 3: x m, y m, yaw rad) sample the robot's ground truth;
    ``scan_t`` (s) and ``scans`` each scan's ranges (m, +inf no return) with ``angle_min`` and
    ``angle_increment`` (rad) of the laser frame, mounted at ``lidar_mount`` (x m, y m, yaw rad)
    on the robot, returns up to ``range_max`` (m); ``duration_s`` the run's simulated length;
    ``collisions`` (t s, x m, y m).
    """

    world: object
    duration_s: float
    pose_t: np.ndarray
    poses: np.ndarray
    scan_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scans: list = field(default_factory=list)
    angle_min: float = 0.0
    angle_increment: float = 0.0
    range_max: float = 0.0
    lidar_mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    log: list[LogLine] = field(default_factory=list)
    commands: list[str] = field(default_factory=list)
    collisions: list[tuple[float, float, float]] = field(default_factory=list)
    title: str = ''
    #: The teleop's lines (keys held), when the run was teleoperated (a scenario's drive:).
    teleop: list[LogLine] = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# Reading a run's outputs.

def read_log(path: Path, restamp: bool = False) -> list[LogLine]:
    """
    Return the console lines of a ``log.jsonl`` in time order; [] when there is none.

    One JSON object a line: ``t`` (sim s), ``node``, ``level``, ``text`` and ``line`` (what the
    terminal showed); with ``restamp`` (a run faster than real time), its rcutils stamp made
    the one a live run at real time prints (terminal_text.live_stamped). VideoError names the
    line that is not such an object.
    """
    if not path.is_file():
        return []
    lines = []
    with path.open(encoding='utf-8', errors='replace') as stream:
        for number, text in enumerate(stream, start=1):
            if not text.strip():
                continue
            try:
                entry = json.loads(text)
                lines.append(LogLine(float(entry['t']), str(entry.get('level', '')),
                                     str(entry['line'])))
            except (ValueError, TypeError, KeyError) as error:
                raise VideoError(f'{path}:{number}: not a log line ({error!r})') from None
    lines.sort(key=lambda entry: entry.t)  # stable: lines of one time keep their order
    if not restamp:
        return lines
    stamped = live_stamped([(entry.t, entry.line) for entry in lines])
    return [LogLine(entry.t, entry.level, line) for entry, line in zip(lines, stamped)]


def _json(path: Path) -> dict:
    try:
        document = json.loads(path.read_text(encoding='utf-8'))
    except FileNotFoundError:
        raise VideoError(f'{path}: no such file (not the output folder of a run?)') from None
    except (OSError, ValueError) as error:
        raise VideoError(f'{path}: cannot read it: {error}') from None
    if not isinstance(document, dict):
        raise VideoError(f'{path}: not a JSON object')
    return document


def simulator_parameters(out_dir: Path) -> dict:
    """Return the simulator's entry of the run's ``params.yaml`` (world, robot, robot_pose)."""
    path = out_dir / 'params.yaml'
    try:
        document = yaml.safe_load(path.read_text(encoding='utf-8'))
        values = document['sim_bridge']['ros__parameters']
        values['world']
    except FileNotFoundError:
        raise VideoError(f'{path}: no such file (not the output folder of a run?)') from None
    except (OSError, yaml.YAMLError, TypeError, KeyError) as error:
        raise VideoError(f'{path}: no simulator world in it ({error!r})') from None
    return values


def read_recording(bag: Path) -> tuple[tuple, tuple, list]:
    """
    Return ((pose times s, poses), (scan times s, ranges, geometry), commands) of a bag.

    ``geometry`` is the scans' (angle_min rad, angle_increment rad, range_max m); ``commands``
    each /cmd_vel message's (time s, linear.x m/s, angular.z rad/s), Twist or TwistStamped.

    Read with mcap's reader (the files ``metadata.yaml`` names), the messages deserialised by
    rclpy as the installed packages define them; times are the messages' bag stamps (sim
    time: the runner stamps each message with the step that sent it).
    """
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message
    from sim_bridge.common.message_types import message_class
    pose_t, poses, scan_t, scans, commands = [], [], [], [], []
    geometry = (0.0, 0.0, 0.0)
    try:
        info = yaml.safe_load((bag / 'metadata.yaml').read_text('utf-8'))
        for name in info['rosbag2_bagfile_information']['relative_file_paths']:
            with open(bag / name, 'rb') as stream:
                messages = make_reader(stream).iter_messages(
                    topics=[ODOM_TOPIC, SCAN_TOPIC, CMD_VEL_TOPIC])
                for schema, channel, message in messages:
                    msg = deserialize_message(message.data, message_class(schema.name))
                    stamp_s = message.log_time * 1e-9
                    if channel.topic == CMD_VEL_TOPIC:
                        twist = getattr(msg, 'twist', msg)
                        commands.append((stamp_s, twist.linear.x, twist.angular.z))
                    elif channel.topic == ODOM_TOPIC:
                        pose = msg.pose.pose
                        yaw = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
                        pose_t.append(stamp_s)
                        poses.append((pose.position.x, pose.position.y, yaw))
                    else:
                        scan_t.append(stamp_s)
                        scans.append(np.asarray(msg.ranges, dtype=float))
                        geometry = (msg.angle_min, msg.angle_increment, msg.range_max)
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError, McapError) as error:
        raise VideoError(f'{bag}: cannot read the recording: {error}') from None
    if not poses:
        raise VideoError(f"{bag}: the recording has no {ODOM_TOPIC} (the robot's pose)")
    return ((np.array(pose_t), np.array(poses).reshape(-1, 3)),
            (np.array(scan_t), scans, tuple(map(float, geometry))), commands)


def _run_mode(metrics: dict) -> str | None:
    """Return how the run went ('stepped', 'process', 'live'), or None when not said."""
    mode = metrics.get('run_mode')
    return mode.get('mode') if isinstance(mode, dict) else None


def load_footage(out_dir: str | os.PathLike, teleop: bool = False, world: World | None = None,
                 duration_s: float | None = None) -> Footage:
    """
    Read what the video of the run in ``out_dir`` shows; VideoError when it cannot.

    ``teleop``: the run was teleoperated (a scenario's ``drive:``), its /cmd_vel the teleop's:
    the keys held are the teleop terminal's lines. ``world`` and ``duration_s`` (s), when
    given, are the run's from records no run could write (the grader's scenario and report),
    instead of its ``params.yaml`` and ``metrics.json``: the world a video loads and the
    frames it draws are then the grader's.
    """
    out_dir = Path(out_dir)
    metrics = _json(out_dir / 'metrics.json')
    if world is None:
        sim = simulator_parameters(out_dir)
        try:
            world = World.load(sim['world'], robot=sim.get('robot'),
                               robot_pose=sim.get('robot_pose'))
        except (FileNotFoundError, WorldError) as error:
            raise VideoError(f"{out_dir / 'params.yaml'}: world: {error}") from None
    bag = out_dir / 'run'
    if not bag.is_dir():
        raise VideoError(f'{bag}: no recording (was the run made with --no-record?)')
    (pose_t, odometry), (scan_t, scans, geometry), commands = read_recording(bag)
    # Odometry starts at 0 in odom, the spawn pose's frame (see SimBridge.odometry).
    poses = np.column_stack(pose_in_world(world.robot_start, odometry.T))
    lidar = world.robot.lidar or LidarConfig()
    mount = (lidar.pose[0], lidar.pose[1], lidar.pose[5])
    duration = metrics.get('sim_time_s') if duration_s is None else duration_s
    if not isinstance(duration, (int, float)) or not duration > 0:
        duration = float(max(pose_t[-1], scan_t[-1] if len(scan_t) else 0.0))
    collisions = [(event['time'], event['x'], event['y'])
                  for event in metrics.get('collision_events') or []]
    keys = [LogLine(t, 'INFO', text) for t, text in teleop_lines(commands)] if teleop else []
    return Footage(world, float(duration), pose_t, poses, scan_t, scans, *geometry, mount,
                   read_log(out_dir / LOG_FILE, restamp=_run_mode(metrics) != 'live'),
                   list(metrics.get('commands') or []),
                   collisions, title=getattr(world, 'name', ''), teleop=keys)


# ---------------------------------------------------------------------------------------------
# Drawing frames.

class WorldPane:
    """
    The world from above: drawn once by sim_bridge.media.plot's world drawing, the rest per frame.

    World coordinates (m) map to pixels through the axes' transform of that drawing; the path
    is drawn on a copy kept from frame to frame, the robot and the scan on a copy of that.
    """

    def __init__(self, size: tuple[int, int], footage: Footage):
        self.size = size
        self.footage = footage
        dpi = 100
        figure = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
        axes = figure.add_axes((0.08, 0.05, 0.9, 0.9))
        _draw_world(axes, footage.world)
        xmin, ymin, xmax, ymax = footage.world.bounds
        xs, ys = footage.poses[:, 0], footage.poses[:, 1]
        margin = 0.3
        axes.set_xlim(min(xmin, xs.min()) - margin, max(xmax, xs.max()) + margin)
        axes.set_ylim(min(ymin, ys.min()) - margin, max(ymax, ys.max()) + margin)
        axes.set_aspect('equal', adjustable='box')
        axes.grid(True, linewidth=0.4, alpha=0.5)
        axes.tick_params(labelsize=8)
        axes.set_title(footage.title, fontsize=10)
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        self.transform = axes.transData
        # The map's box (px: left, top, right, bottom): beams reaching beyond it are cut there.
        box = axes.get_window_extent()
        self.box = (math.floor(box.x0), math.floor(size[1] - box.y1),
                    math.ceil(box.x1), math.ceil(size[1] - box.y0))
        self.background = Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3])
        outlines = footage.world.floor_slice.robot_outlines((0.0, 0.0, 0.0))
        self.robot_rings = [np.asarray(ring)[:, :2] for ring in outlines]
        self.robot_size = max(float(np.abs(ring).max()) for ring in self.robot_rings)
        self._path = self.background.copy()
        self._path_drawn = 0

    def pixels(self, points: np.ndarray) -> np.ndarray:
        """Return the (K, 2) pixel positions (column, row) of world points (K, 2) in m."""
        display = self.transform.transform(np.asarray(points, dtype=float).reshape(-1, 2))
        return np.column_stack((display[:, 0], self.size[1] - display[:, 1]))

    def image(self, t: float) -> Image.Image:
        """Return the pane at sim time ``t`` (s)."""
        footage = self.footage
        index = int(np.searchsorted(footage.pose_t, t, side='right'))
        if index < self._path_drawn:  # an earlier time than the last frame: start over
            self._path, self._path_drawn = self.background.copy(), 0
        if index > self._path_drawn:
            first = max(0, self._path_drawn - 1)
            points = self.pixels(footage.poses[first:index, :2])
            if len(points) > 1:
                ImageDraw.Draw(self._path).line([tuple(p) for p in points], fill=PATH_COLOUR,
                                                width=3, joint='curve')
            self._path_drawn = index
        frame = self._path.copy()
        draw = ImageDraw.Draw(frame)
        pose = footage.poses[max(index - 1, 0)]
        self._draw_scan(draw, t, pose)
        self._draw_robot(draw, pose)
        for _, x, y in [event for event in footage.collisions if event[0] <= t]:
            (column, row), = self.pixels([(x, y)])
            for sign in (-1, 1):
                draw.line((column - 7, row - 7 * sign, column + 7, row + 7 * sign),
                          fill=COLLISION_COLOUR, width=3)
        framed = self.background.copy()
        framed.paste(frame.crop(self.box), self.box[:2])
        return framed

    def _draw_scan(self, draw: ImageDraw.ImageDraw, t: float, robot: np.ndarray) -> None:
        footage = self.footage
        index = int(np.searchsorted(footage.scan_t, t, side='right')) - 1
        if index < 0:
            return
        # The robot's pose when the scan was taken, and the laser's on it.
        at = max(int(np.searchsorted(footage.pose_t, footage.scan_t[index], side='right')) - 1, 0)
        x, y, yaw = footage.poses[at]
        mx, my, myaw = footage.lidar_mount
        origin = point_in_world((x, y, yaw), (mx, my))
        ranges = footage.scans[index]
        angles = yaw + myaw + footage.angle_min + footage.angle_increment * np.arange(len(ranges))
        hit = np.isfinite(ranges)
        # A beam with no return shows the lidar's reach; one that hit, where it hit.
        reach = np.where(hit, ranges, footage.range_max)
        ends = self.pixels(np.column_stack((origin[0] + reach * np.cos(angles),
                                            origin[1] + reach * np.sin(angles))))
        (ox, oy), = self.pixels([origin])
        for returned, colour in ((False, MISS_COLOUR), (True, BEAM_COLOUR)):
            for column, row in ends[hit == returned]:
                draw.line((ox, oy, column, row), fill=colour)
        for column, row in ends[hit]:
            draw.ellipse((column - 3, row - 3, column + 3, row + 3), fill=HIT_COLOUR)

    def _draw_robot(self, draw: ImageDraw.ImageDraw, pose: np.ndarray) -> None:
        x, y, yaw = pose
        rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        for ring in self.robot_rings:
            points = self.pixels(ring @ rotation.T + (x, y))
            draw.polygon([tuple(p) for p in points], fill=ROBOT_COLOUR, outline=(20, 60, 20))
        nose = (x + self.robot_size * math.cos(yaw), y + self.robot_size * math.sin(yaw))
        (cx, cy), (nx, ny) = self.pixels([(x, y), nose])
        draw.line((cx, cy, nx, ny), fill=(255, 255, 255), width=2)


class FrameRenderer:
    """
    Draw a run's frames (FRAME_WIDTH x FRAME_HEIGHT, RGB) at any sim time.

    The banner holds ``names`` and the simulated clock (and the speed, when not real time), the
    left the world from above and, with ``view3d``, under it the robot in 3-D as a simulator's
    window shows it (media.view3d); the right the node's terminal and, for a teleoperated run,
    the teleop's terminal under it. Frames are quickest drawn in time order (the path grows on
    a kept copy).
    """

    def __init__(self, footage: Footage, names: str, speed: float = 1.0, view3d: bool = False):
        self.footage = footage
        self.names = names
        self.speed = speed
        body = FRAME_HEIGHT - BANNER_HEIGHT
        top = TOP_VIEW_HEIGHT if view3d else body
        self.world = WorldPane((WORLD_WIDTH, top), footage)
        self.view3d = View3D(footage.world, RENDERED_3D) if view3d else None
        self.view3d_size = (WORLD_WIDTH, body - top)
        node_height = body - (TELEOP_HEIGHT if footage.teleop else 0)
        self.terminal = TerminalPane((FRAME_WIDTH - WORLD_WIDTH, node_height),
                                     footage.commands, footage.log)
        self.teleop = TerminalPane((FRAME_WIDTH - WORLD_WIDTH, TELEOP_HEIGHT),
                                   [TELEOP_COMMAND], footage.teleop) if footage.teleop else None
        self.clock_font = font('DejaVu Sans Mono', BANNER_FONT_SIZE)
        longest = self.clock(footage.duration_s)
        self.names_image = names_banner(
            names, FRAME_WIDTH - 40 - int(self.clock_font.getlength(longest)))

    def clock(self, t: float) -> str:
        """Return the banner's clock at sim time ``t`` (s)."""
        speed = '' if self.speed == 1 else f'  ({self.speed:g}x)'
        return f'sim time {t:7.1f} s / {self.footage.duration_s:.1f} s{speed}'

    def frame(self, t: float, *, names: bool = True, log: bool = True) -> np.ndarray:
        """
        Return the frame at sim time ``t`` (s) as an (H, W, 3) uint8 array.

        ``names`` and ``log`` False leave the names or the console lines out (to compare with).
        """
        frame = Image.new('RGB', (FRAME_WIDTH, FRAME_HEIGHT), BANNER_BACKGROUND)
        frame.paste(self.world.image(t), (0, BANNER_HEIGHT))
        if self.view3d is not None:
            index = int(np.searchsorted(self.footage.pose_t, t, side='right'))
            pose = tuple(self.footage.poses[max(index - 1, 0)])
            frame.paste(self.view3d.image(pose).resize(self.view3d_size),
                        (0, BANNER_HEIGHT + self.world.size[1]))
        count = self.terminal.count_at(t) if log else 0
        frame.paste(self.terminal.image(count), (WORLD_WIDTH, BANNER_HEIGHT))
        if self.teleop is not None:
            frame.paste(self.teleop.image(self.teleop.count_at(t)),
                        (WORLD_WIDTH, FRAME_HEIGHT - TELEOP_HEIGHT))
        draw = ImageDraw.Draw(frame)
        if names:
            frame.paste(self.names_image, (10, 0))
        draw.text((FRAME_WIDTH - 10, BANNER_HEIGHT // 2), self.clock(t), font=self.clock_font,
                  fill=(255, 255, 255), anchor='rm')
        return np.asarray(frame)


def names_banner(names: str, width: int) -> Image.Image:
    """
    Return ``names`` drawn to fit ``width`` (px) of the banner, whole: never cut off.

    In bold at BANNER_FONT_SIZE, smaller if needed down to MIN_NAMES_FONT_SIZE, then on two
    lines (at commas where it can) at the size that fits.
    """
    image = Image.new('RGB', (width, BANNER_HEIGHT), BANNER_BACKGROUND)
    draw = ImageDraw.Draw(image)
    lines = [names]
    for size in range(BANNER_FONT_SIZE, MIN_NAMES_FONT_SIZE - 1, -1):
        face = font('DejaVu Sans', size, 'bold')
        if face.getlength(names) <= width:
            break
    else:
        middle = len(names) // 2
        commas = [index for index, char in enumerate(names) if char in ', ']
        cut = min(commas, key=lambda index: abs(index - middle)) if commas else middle
        lines = [names[:cut + 1].strip(), names[cut + 1:].strip()]
        for size in range(BANNER_HEIGHT // 2 - 2, 5, -1):
            face = font('DejaVu Sans', size, 'bold')
            if max(face.getlength(line) for line in lines) <= width:
                break
    draw.multiline_text((0, BANNER_HEIGHT // 2), '\n'.join(lines), font=face,
                        fill=(255, 255, 255), anchor='lm', spacing=0)
    return image


def frame_times(duration_s: float, speed: float, fps: float) -> np.ndarray:
    """
    Return the sim time (s) of each frame: one every ``speed / fps`` s, the last at the end.

    ``round(duration_s / speed * fps)`` frames (at least one): the video lasts the run's
    simulated time divided by ``speed``. Frame k shows the run at the end of its interval.
    """
    count = max(1, round(duration_s / speed * fps))
    return np.minimum((np.arange(count) + 1) * speed / fps, duration_s)


@dataclass(frozen=True)
class VideoInfo:
    """A written video: its file, frame count, frame rate (1/s) and size (px)."""

    path: Path
    frames: int
    fps: float
    size: tuple[int, int]

    @property
    def duration_s(self) -> float:
        """Return the video's length (s)."""
        return self.frames / self.fps


def encode(frames: Iterator[np.ndarray], path: Path, fps: float) -> int:
    """
    Write RGB frames as an H.264 MP4 (yuv420p, faststart); return how many were written.

    Encoded by the FFmpeg imageio-ffmpeg ships, to a temporary file beside ``path`` moved there
    when complete: a video cut off (Ctrl-C, a full disk) never replaces a good one. VideoError
    with the first line FFmpeg printed (its own reason: a full disk, a missing encoder) when it
    fails.
    """
    import imageio_ffmpeg
    try:
        ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as error:  # neither its wheel's binary nor IMAGEIO_FFMPEG_EXE
        raise VideoError(f'no video encoder: {first_line(str(error))}') from None
    partial = path.with_name(f'.{path.name}.partial.mp4')
    rate = Fraction(fps).limit_denominator(1001)
    command = [ffmpeg, '-y', '-v', 'error', '-f', 'rawvideo',
               '-pix_fmt', 'rgb24', '-s', f'{FRAME_WIDTH}x{FRAME_HEIGHT}', '-r', str(rate),
               '-i', '-', '-an', '-c:v', 'libx264', '-pix_fmt', 'yuv420p', '-crf', '23',
               '-preset', 'veryfast', '-movflags', '+faststart', str(partial)]
    count = 0
    with tempfile.TemporaryFile() as said:
        try:
            encoder = subprocess.Popen(command, stdin=subprocess.PIPE,
                                       stdout=subprocess.DEVNULL, stderr=said)
        except OSError as error:
            raise VideoError(f'the video encoder {command[0]} cannot start: '
                             f'{error.strerror or error}') from None
        try:
            for frame in frames:
                encoder.stdin.write(np.ascontiguousarray(frame, dtype=np.uint8).tobytes())
                count += 1
            encoder.stdin.close()
            status = encoder.wait()
        except BrokenPipeError:  # it stopped reading: it failed, and says why below
            status = encoder.wait()
        except BaseException:
            encoder.kill()
            encoder.wait()
            partial.unlink(missing_ok=True)
            raise
        if status != 0:
            partial.unlink(missing_ok=True)
            said.seek(0)
            why = first_line(said.read().decode('utf-8', 'replace')) or f'exit status {status}'
            raise VideoError(f'the video encoder (FFmpeg) failed: {why}')
    os.replace(partial, path)
    return count


def render_video(out_dir: str | os.PathLike, path: str | os.PathLike, names: str = '', *,
                 speed: float = 1.0, fps: float = DEFAULT_FPS, teleop: bool = False,
                 view3d: bool = False, world: World | None = None,
                 duration_s: float | None = None) -> VideoInfo:
    """
    Write the video of the run in ``out_dir`` to ``path`` and return what was written.

    ``speed``: simulated seconds per second of video (1: real time); ``fps``: frames per
    second of video; ``teleop``: the run was teleoperated, its terminal is shown;
    ``view3d``: the 3-D view is shown (FrameRenderer); ``world`` and ``duration_s`` (s): the
    trusted run's (see :func:`load_footage`). VideoError when the run's outputs lack what the
    video shows; OSError when ``path`` cannot be written.
    """
    if not (math.isfinite(speed) and speed > 0 and math.isfinite(fps) and fps > 0):
        raise VideoError(f'speed and fps must be positive numbers, got {speed} and {fps}')
    footage = load_footage(out_dir, teleop, world, duration_s)
    renderer = FrameRenderer(footage, names, speed, view3d)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    times = frame_times(footage.duration_s, speed, fps)
    try:
        count = encode((renderer.frame(t) for t in times), path, fps)
    finally:
        if renderer.view3d is not None:
            renderer.view3d.close()
    return VideoInfo(path, count, fps, (FRAME_WIDTH, FRAME_HEIGHT))
