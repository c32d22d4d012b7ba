"""
A run's options: the world and its start pose, node parameters, remap rules, seeds, drive.

The words they are written in (EVERY_NODE, seeds, remap rules) live here, below the runner, so
that the grader's scenarios use them without the runner reading the grader.
"""


from dataclasses import dataclass
import math
import os
from pathlib import Path
import sys
from typing import Any, Callable, Mapping, Sequence

from rclpy.parameter import get_parameter_value, parameter_value_to_python
from sim_bridge.common.errors import RunError
from sim_bridge.common.paths import find_world
from sim_bridge.common.values import described
from sim_bridge.ros.drive import check_obstacles, DriveError, parse_drive, Segment
from sim_bridge.runner.targets import missing_node_file, node_command, target_name
from sim_bridge.simulation.sdf_lidar import LIDAR_SENSOR_TYPES
from sim_bridge.simulation.world import World, WorldError
import yaml


#: The largest seed: a seed is a ROS integer parameter (int64) of the simulator and, through
#: $seed, of a node; the simulator's generator (numpy) takes any non-negative integer.
MAX_SEED = 2 ** 63 - 1
#: The params file key of parameters for every node (ROS's wildcard node name).
EVERY_NODE = '/**'


def remap_problem(rule: Any) -> str | None:
    """
    Return what makes ``rule`` not a ROS remapping rule ``FROM:=TO`` or ``NODE:FROM:=TO``.

    None when it has that form; rcl checks the names themselves when the run starts.
    """
    if not isinstance(rule, str):
        return f'must be a remapping rule text, got {described(rule)}'
    match, _, to = rule.partition(':=')
    if not (match and to) or match.endswith(':') or ':=' in to or match.count(':') > 1:
        return (f"'{rule}' is not a remapping rule: expected FROM:=TO or NODE:FROM:=TO, "
                'e.g. /robot/scan:=/scan')
    return None


def is_seed(value: Any) -> bool:
    """Return True when ``value`` can be a run's seed: an integer from 0 to MAX_SEED."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= MAX_SEED


BRIDGE_NODE = 'sim_bridge'
#: SimBridge parameters the runner alone sets: the world and robot the metrics are scored in,
#: the seed and gui options, the robot's start pose, and the pace (a run is on sim time; --gui
#: paces it).
RUNNER_BRIDGE_PARAMETERS = ('world', 'robot', 'robot_pose', 'seed', 'gui', 'real_time_factor')
Params = dict[str, dict[str, Any]]


@dataclass
class RunResult:
    """What a run measured (``metrics``, as in metrics.json) and where its outputs are."""

    metrics: dict
    out_dir: Path

    @property
    def ok(self) -> bool:
        """Return True when the run completed without a node raising."""
        return not self.metrics['node_errors']


@dataclass(frozen=True)
class RunSpec:
    """
    What a run runs, and how: the options of ``python -m sim_bridge.run``.

    ``targets`` (sim_bridge.runner.targets) run with the simulator in ``world`` for
    ``duration_s`` (s of simulated time). ``params`` maps node names to parameter overrides;
    ``start`` overrides the robot's start pose (x m, y m, yaw rad), or is 'mirrored' to put
    the world's target on the robot's left; ``robot`` names a robot model spawned instead of
    the world's own (see :func:`load_world`); ``remap`` holds ROS remapping rules
    (``FROM:=TO``, ``NODE:FROM:=TO``) for the target nodes; ``ros_args`` (``--ros-args ...``,
    as given after ``ros2 run``'s executable) reach them unchanged; ``setpoint`` is the wall
    distance (m) ``wall_distance_m`` is measured against, by default the wall distance a node
    declares as a parameter (sim_bridge.scoring.metrics.declared_wall_distance), if one does;
    ``printed`` names the values (printed_values.KINDS) whose printed lines are scored
    against the scans. ``gui`` shows the run in the pybullet window at wall-clock pace.
    ``field_checks``: rosidl refuses a value of the wrong type in a message field (see
    sim_bridge.common.run_environment); off, the run behaves as Jazzy's default does on a
    robot. ``drive`` is a list of segments
    (sim_bridge.ros.drive) the runner's teleop node publishes on the simulator's command topic
    while the nodes run. ``progress(sim_s, duration_s)`` is called as simulated time passes;
    ``on_scoring()`` once the nodes are stopped, before the run is scored and its outputs
    written (the trusted side's own time: no node can stall it).
    """

    world: str
    targets: tuple[str, ...]
    duration_s: float = 60.0
    seed: int = 0
    params: Params | None = None
    out_dir: Path | str | None = None
    start: Sequence[float] | str | None = None
    robot: str | None = None
    remap: tuple[str, ...] = ()
    ros_args: tuple[str, ...] = ()
    setpoint: float | None = None
    printed: tuple[str, ...] = ()
    quiet: bool = False
    record: bool = True
    plot: bool = True
    gui: bool = False
    field_checks: bool = True
    drive: Sequence[Any] | None = None
    progress: Callable[[float, float], None] | None = None
    on_scoring: Callable[[], None] | None = None


@dataclass(frozen=True)
class PreparedRun:
    """A RunSpec checked and read: the world, the drive plan, the nodes' parameters, where."""

    world: World
    segments: tuple[Segment, ...]
    node_params: Params
    out_dir: Path
    remap: tuple[str, ...]


def prepare_run(spec: RunSpec) -> PreparedRun:
    """Check ``spec`` and read its world, drive plan and parameters; RunError if they are bad."""
    if not (math.isfinite(spec.duration_s) and spec.duration_s > 0):
        raise RunError(f'duration must be a positive number of seconds, got {spec.duration_s}')
    remap = tuple(check_remap(rule) for rule in spec.remap)
    for target in spec.targets:
        if missing_node_file(target):
            raise RunError(f'node file not found: {missing_node_file(target)}')
    if spec.gui and gui_problem(os.environ):
        raise RunError(gui_problem(os.environ))
    world = load_world(spec.world, spec.robot, spec.start)
    segments = drive_plan(spec.drive, world)
    node_params = node_parameters(world, spec.params, seed=spec.seed, gui=spec.gui,
                                  start=spec.start, robot=spec.robot)
    out_dir = (Path(spec.out_dir) if spec.out_dir is not None
               else default_out_dir(world, spec.targets))
    return PreparedRun(world, segments, node_params, out_dir, remap)


def write_params_files(folder: Path, node_params: Params) -> tuple[Path, Path]:
    """
    Write the nodes' params file and the bridge's own into ``folder``; return both paths.

    The bridge reads its own entry alone: EVERY_NODE's parameters are the targets'.
    """
    params_file = folder / 'params.yaml'
    write_params_file(params_file, node_params)
    bridge_params_file = folder / f'{BRIDGE_NODE}.yaml'
    write_params_file(bridge_params_file, {BRIDGE_NODE: node_params[BRIDGE_NODE]})
    return params_file, bridge_params_file


def split_param(text: str) -> tuple[str, str, str]:
    """Split ``NODE:NAME=VALUE`` into its three texts; ValueError when it is not of that form."""
    node, colon, rest = text.partition(':')
    name, equals, value = rest.partition('=')
    if not (colon and equals and node and name):
        raise ValueError(f"--param '{text}': expected NODE:NAME=VALUE, "
                         'e.g. wall_follow:distance=0.6')
    return node, name, value


def parse_param(text: str) -> tuple[str, str, Any]:
    """
    Split ``NODE:NAME=VALUE`` into node name, parameter name and typed value; RunError if not.

    VALUE is typed as ``--ros-args -p NAME:=VALUE`` types it (YAML: ``1`` is an integer,
    ``1.0`` a double, ``true`` a bool, ``[1.0, 2.0]`` a double array).
    """
    try:
        node, name, value = split_param(text)
    except ValueError as error:
        raise RunError(str(error)) from None
    return node, name, parameter_value_to_python(get_parameter_value(value))


def check_remap(rule: str) -> str:
    """Return ``rule`` when it reads as a ROS remapping rule, else raise a one-line RunError."""
    problem = remap_problem(rule)
    if problem is not None:
        raise RunError(f'--remap {problem}')
    return rule


def gui_problem(environ: Mapping[str, str], platform: str = sys.platform) -> str | None:
    """
    Return why ``--gui`` cannot open the pybullet window here, or None.

    On Linux the window needs an X display (pybullet's GUI speaks X11, XWayland included);
    without one pybullet ends the whole process with 'cannot connect to X server'.
    """
    if platform.startswith('linux') and not environ.get('DISPLAY'):
        return ('--gui needs a display, and DISPLAY is not set (a terminal without one, e.g. '
                'over ssh): run without --gui, or under xvfb-run')
    return None


def load_world(world: str, robot: str | None = None,
               start: Sequence[float] | str | None = None) -> World:
    """
    Load a world by name or path, turning every failure into a one-line RunError.

    ``robot`` names a robot model (a model folder, as the world file's ``robot: model:``)
    spawned in it instead of the world's own robot, at ``start`` when that is a pose (x m, y m,
    yaw rad), else at the world's robot start; as the bridge's ``robot`` parameter does.
    """
    # Without a robot the start is checked and set by start_pose, whose error names it.
    pose = None if start is None or isinstance(start, str) or robot is None else start
    try:
        loaded = World.load(find_world(world), robot=robot, robot_pose=pose)
    except (FileNotFoundError, WorldError) as error:
        raise RunError(str(error)) from None
    if loaded.robot.lidar is None:  # the bridge simulates the robot's own lidar, no other
        raise RunError(f"robot model '{loaded.robot_model}' ({loaded.robot.path}) has no lidar "
                       f"<sensor> (type {', '.join(LIDAR_SENSOR_TYPES)}): a run scans with the "
                       "robot's own")
    return loaded


def start_pose(world: World, start: Sequence[float] | str | None) -> list[float] | None:
    """Return the robot start override (x m, y m, yaw rad); 'mirrored' puts the target left."""
    if start is None:
        return None
    if start == 'mirrored':
        start = world.mirrored_start().robot_start
    try:
        world.with_robot_start(*start)
    except (TypeError, ValueError, WorldError) as error:
        raise RunError(f'start pose {start!r}: {error}') from None
    return [float(value) for value in start]


def started_world(world: World, start: Sequence[float] | str | None) -> World:
    """Return ``world`` with the robot where a run with ``start`` (see start_pose) starts it."""
    pose = start_pose(world, start)
    return world if pose is None else world.with_robot_start(*pose)


def node_parameters(world: World, params: Params | None, *, seed: int, gui: bool,
                    start: Sequence[float] | str | None, robot: str | None = None) -> Params:
    """
    Return every node's parameters: ``params`` plus the simulator's own.

    The simulator's: world, robot, robot pose, seed and gui. RunError when ``params`` sets
    one of the RUNNER_BRIDGE_PARAMETERS.
    """
    if not is_seed(seed):
        raise RunError(f'seed must be a non-negative integer up to {MAX_SEED} (a ROS integer '
                       f'parameter is int64), got {seed!r}')
    bridge_params = {'world': str(world.path), 'seed': seed, 'gui': bool(gui)}
    if robot is not None:
        bridge_params['robot'] = robot
    pose = start_pose(world, start)
    if pose is not None:
        bridge_params['robot_pose'] = pose
    params = dict(params or {})
    clash = [name for name in RUNNER_BRIDGE_PARAMETERS if name in params.get(BRIDGE_NODE, {})]
    if clash:
        raise RunError(f'--param {BRIDGE_NODE}:{clash[0]}: the runner sets it (use --world, '
                       '--robot, --robot-pose, --seed, --gui)')
    params[BRIDGE_NODE] = {**params.get(BRIDGE_NODE, {}), **bridge_params}
    return params


def write_params_file(path: Path, params: Params) -> None:
    """Write per-node parameters as a ROS 2 params file (``node: ros__parameters: ...``)."""
    document = {node: {'ros__parameters': values} for node, values in params.items()}
    path.write_text(yaml.safe_dump(document, sort_keys=False))


def drive_plan(drive: Sequence[Any] | None, world: World) -> tuple[Segment, ...]:
    """Return the validated segments of ``drive`` (see sim_bridge.ros.drive); RunError if bad."""
    if drive is None:
        return ()
    try:
        segments = parse_drive(drive)
        check_obstacles(segments, [obstacle.name for obstacle in world.obstacles], world.name)
    except DriveError as error:
        raise RunError(str(error)) from None
    return segments


def default_out_dir(world: World, targets: Sequence[str]) -> Path:
    """Return ``out/<world>-<node>[+<node>...]``."""
    return Path('out') / f"{world.name}-{'+'.join(target_name(t) for t in targets)}"


def node_commands(targets: Sequence[str], remap: Sequence[str],
                  ros_args: Sequence[str] = ()) -> list[str]:
    """Return the command line that starts each node, as its process gets it (out dir files)."""
    arguments = ['--ros-args', '--params-file', 'params.yaml', '-p', 'use_sim_time:=true',
                 *(argument for rule in remap for argument in ('-r', rule)), *ros_args[1:]]
    return [node_command(target, arguments) for target in targets]
