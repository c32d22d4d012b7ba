"""
The stepped runner (run.py) on real rclpy: outputs, TARGET forms, start errors, failing nodes.

Runs are short (a few simulated seconds take a tenth of a wall second); a run is shared by
several tests where they only read its outputs. The nodes' log lines are written by rcutils to
file descriptor 2, so tests read them with ``capfd``.
"""

from dataclasses import replace
import importlib.util
import json
import math
import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores
from sim_bridge.commands.run import main
from sim_bridge.common.errors import RunError, UserInterrupt
from sim_bridge.grading.scenario import scenario_from_dict
from sim_bridge.runner.boundary.outside.node_sandbox import node_limits
from sim_bridge.runner.run import run_simulation
from sim_bridge.simulation.geometry import signed_distance
from sim_bridge.simulation.world import World
import yaml

FIXTURES = Path(__file__).parent / 'fixtures'
#: The tests' robot models (little_bot: 360 beams at 5 Hz in frame base_scan).
MODELS = FIXTURES / 'models'
SCAN_AHEAD_SOURCE = Path(__file__).parents[2] / 'scan_pkg' / 'scan_pkg' / 'scan_ahead.py'
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
NANOSECONDS_PER_SECOND = 10 ** 9
# Issue 4 §2: the keys metrics.json must have at least.
REQUIRED_METRICS = ('sim_time_s', 'wall_time_s', 'real_time_factor', 'collisions',
                    'min_clearance_m', 'distance_m', 'laps', 'wall_distance_m', 'turns_deg',
                    'max_stationary_s', 'coverage', 'node_errors')
REQUIRED_WALL_DISTANCE = ('mean', 'mae', 'rms', 'setpoint')
# The bridge's rates with its default parameters and the lab robot's lidar (Hz).
PHYSICS_RATE, ODOM_RATE, SCAN_RATE = 100, 50, 10
LOG_LINE = re.compile(r'^\[(?P<level>[A-Z]+)\] \[(?P<sec>\d+)\.(?P<nsec>\d{9})\] '
                      r'\[(?P<name>[\w.]+)\]: (?P<text>.*)$')
# TF is published where tf2_ros is installed (a ROS 2 machine), not from the PyPI wheels.
HAS_TF = importlib.util.find_spec('tf2_ros') is not None
TF_TOPICS = {'/tf', '/tf_static'}


@pytest.fixture
def run_main(capfd):
    """Call the runner's ``main``; return its exit status, stdout and stderr (fd level)."""
    def call(*argv: str) -> tuple[int, str, str]:
        capfd.readouterr()
        status = main(list(argv))
        out, err = capfd.readouterr()
        return status, out, err
    return call


def log_lines(text: str, name: str) -> list[str]:
    """Return the texts of the ROS log lines of node ``name`` in console output."""
    return [match['text'] for match in map(LOG_LINE.match, text.splitlines())
            if match and match['name'] == name]


def without_tf(counts: dict) -> dict:
    """Return message counts per topic without TF topics (absent where tf2_ros is)."""
    return {topic: count for topic, count in counts.items() if topic not in TF_TOPICS}


def run_in_subprocess(*argv: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run ``python -m sim_bridge.run ARGV`` as its own process; bounded to 120 s."""
    return subprocess.run([sys.executable, '-m', 'sim_bridge.run', *argv], env=env,
                          capture_output=True, text=True, timeout=120)


def read_bag(path: Path) -> dict[str, list[tuple[int, object]]]:
    """Return every message of a rosbag2 bag, decoded with rosbags: topic → [(t ns, msg)]."""
    messages: dict[str, list[tuple[int, object]]] = {}
    with Reader(path) as reader:
        for connection, timestamp, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (timestamp, TYPESTORE.deserialize_cdr(raw, connection.msgtype)))
    return messages


def recorded(path: Path) -> list[tuple]:
    """
    Return what a run's bag holds that the run decides: (topic, t ns, bytes) in storage order.

    A /rosout message is its fields but the stamp: rcl stamps it with the wall clock.
    """
    messages = []
    with Reader(path) as reader:
        for connection, timestamp, raw in reader.messages():
            if connection.topic == '/rosout':
                log = TYPESTORE.deserialize_cdr(raw, connection.msgtype)
                raw = (log.level, log.name, log.msg, log.file, log.function, log.line)
            messages.append((connection.topic, timestamp, bytes(raw) if
                             isinstance(raw, memoryview) else raw))
    return messages


def stamp_ns(stamp) -> int:
    """Return a builtin_interfaces/Time as ns."""
    return stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec


def load_metrics(out_dir: Path) -> dict:
    """Return the metrics.json of a run."""
    return json.loads((out_dir / 'metrics.json').read_text())


def yaw_of(quaternion) -> float:
    """Return the yaw (rad) of a rotation about z."""
    return 2.0 * math.atan2(quaternion.z, quaternion.w)


@pytest.fixture(scope='module')
def scan_ahead_run(tmp_path_factory):
    """Run scan_ahead in `obstacles` for 2 s in its own process; return status, out, err, dir."""
    out_dir = tmp_path_factory.mktemp('scan_ahead') / 'out'
    done = run_in_subprocess('--world', 'obstacles', '--node', 'scan_ahead', '--duration', '2',
                             '--out', str(out_dir))
    return done.returncode, done.stdout, done.stderr, out_dir


@pytest.fixture(scope='module')
def wall_follow_runs(tmp_path_factory):
    """Run wall_follow for 20 s twice with seed 3, once with seed 4; return the folders."""
    base = tmp_path_factory.mktemp('wall_follow')
    folders = {}
    for label, seed in (('first', 3), ('again', 3), ('other_seed', 4)):
        folders[label] = base / label
        run_simulation('wall_follow_box', ['wall_follow'], duration_s=20.0, seed=seed,
                       out_dir=folders[label], quiet=True, plot=label == 'first')
    return folders


@pytest.fixture(scope='module')
def wanderbot_runs(tmp_path_factory):
    """Run wanderbot in `obstacles` for 20 s twice with seed 5; return the folders."""
    base = tmp_path_factory.mktemp('wanderbot')
    for label in ('first', 'again'):
        run_simulation('obstacles', ['wanderbot'], duration_s=20.0, seed=5,
                       out_dir=base / label, quiet=True, plot=False)
    return base / 'first', base / 'again'


# --- a complete run: console, metrics.json, trajectory.png, run/ -----------------------------

def test_run_prints_the_nodes_log_lines(scan_ahead_run):
    status, stdout, stderr, _ = scan_ahead_run
    assert status == 0
    lines = log_lines(stderr, 'scan_ahead')
    # One line per scan: every scan of the 2 s reached the node, none twice.
    assert len(lines) == 2 * SCAN_RATE
    world = World.load('obstacles')
    cube = world.obstacle('cube').footprints[0]
    # The cube's face straight ahead of the robot, which starts at the origin facing +x.
    face_x = cube.x - cube.half_x
    for text in lines:
        match = re.fullmatch(r'Range ahead: (\d+\.\d\d) m', text)
        assert match, text
        assert float(match[1]) == pytest.approx(face_x - world.robot.lidar.pose[0], abs=0.05)
    assert 'Run summary' in stdout


def test_quiet_run_prints_no_log_lines(tmp_path, run_main):
    status, _, stderr = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--duration',
                                 '0.5', '--quiet', '--out', str(tmp_path / 'out'))
    assert status == 0
    assert not log_lines(stderr, 'scan_ahead')


def test_run_writes_metrics_with_every_required_key(scan_ahead_run):
    *_, out_dir = scan_ahead_run
    metrics = load_metrics(out_dir)
    assert set(REQUIRED_METRICS) <= set(metrics)
    assert set(REQUIRED_WALL_DISTANCE) <= set(metrics['wall_distance_m'])
    assert metrics['sim_time_s'] == pytest.approx(2.0)
    assert metrics['wall_time_s'] > 0.0
    assert metrics['real_time_factor'] == pytest.approx(
        metrics['sim_time_s'] / metrics['wall_time_s'])
    assert metrics['collisions'] == 0
    assert metrics['distance_m'] == 0.0       # scan_ahead does not drive
    assert metrics['laps'] == 0                # `obstacles` has no target
    assert metrics['wall_distance_m']['mean'] is None
    assert metrics['node_errors'] == []
    world = World.load('obstacles')
    obstacles = [f for obstacle in world.obstacles for f in obstacle.footprints]
    start = np.array([world.robot_start[:2]])
    clearance = signed_distance(start, obstacles)[0] - world.robot.radius
    assert metrics['min_clearance_m'] == pytest.approx(clearance, abs=1e-6)


def test_a_run_scores_what_its_node_prints_against_every_scan(tmp_path):
    result = run_simulation('obstacles', ['scan_ahead'], duration_s=2.0, out_dir=tmp_path,
                            printed=('range_ahead',), quiet=True, record=False, plot=False)
    scored = result.metrics['printed']
    assert list(scored) == ['range_ahead']
    # The lidar's 10 Hz over 2 s, each scan with its 'Range ahead: 2.00 m' line.
    assert (scored['range_ahead']['scans'], scored['range_ahead']['lines'],
            scored['range_ahead']['missed']) == (20, 20, 0)
    assert scored['range_ahead']['worst_error_m'] <= 0.005 + 1e-6  # printed to the cm


def test_run_writes_a_trajectory_plot(scan_ahead_run):
    *_, out_dir = scan_ahead_run
    assert (out_dir / 'trajectory.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_run_records_a_bag_rosbags_reads_back(scan_ahead_run):
    *_, out_dir = scan_ahead_run
    assert (out_dir / 'run' / 'metadata.yaml').is_file()
    assert (out_dir / 'run' / 'run_0.mcap').is_file()
    messages = read_bag(out_dir / 'run')
    duration_s = 2
    counts = {topic: len(items) for topic, items in messages.items()}
    # /clock at the start and at each recorded message's time: the odometry's (record.py);
    # /rosout: scan_ahead's line for each scan, at the scan's time.
    assert without_tf(counts) == {'/clock': 1 + ODOM_RATE * duration_s,
                                  '/odom': ODOM_RATE * duration_s,
                                  '/scan': SCAN_RATE * duration_s,
                                  '/rosout': SCAN_RATE * duration_s}
    assert [time for time, _ in messages['/rosout']] == [time for time, _ in messages['/scan']]
    assert all(log.name == 'scan_ahead' and log.msg.startswith('Range ahead: ')
               for _, log in messages['/rosout'])
    if HAS_TF:
        assert (counts['/tf'], counts['/tf_static']) == (ODOM_RATE * duration_s, 1)
    for timestamp, clock in messages['/clock']:
        assert stamp_ns(clock.clock) == timestamp
    for timestamp, scan in messages['/scan']:
        assert stamp_ns(scan.header.stamp) == timestamp
        assert scan.header.frame_id == 'laser'
        assert len(scan.ranges) == 36
    for timestamp, odom in messages['/odom']:
        assert stamp_ns(odom.header.stamp) == timestamp
        assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
        assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (0.0, 0.0)
    if HAS_TF:
        (_, static), = messages['/tf_static']
        assert [(t.header.frame_id, t.child_frame_id) for t in static.transforms] == [
            ('base_link', 'laser')]


def test_driving_node_run_records_its_commands(wall_follow_runs):
    messages = read_bag(wall_follow_runs['first'] / 'run')
    # wall_follow answers every scan with one command.
    assert len(messages['/cmd_vel']) == len(messages['/scan']) == 20 * SCAN_RATE
    assert len(messages['/clock']) == 1 + 20 * ODOM_RATE
    # Each command is recorded at the sim time of the scan it answers.
    assert [t for t, _ in messages['/cmd_vel']] == [t for t, _ in messages['/scan']]
    speeds = [twist.linear.x for _, twist in messages['/cmd_vel']]
    assert 0.0 < max(speeds) <= 0.3 + 1e-9
    # Odometry from (0, 0) in odom, the spawn pose's frame, as Gazebo's DiffDrive gives it.
    _, first_odom = messages['/odom'][0]
    assert World.load('wall_follow_box').robot_start[:2] != (0.0, 0.0)
    assert first_odom.pose.pose.position.x == pytest.approx(0.0, abs=0.01)
    assert first_odom.pose.pose.position.y == pytest.approx(0.0, abs=1e-6)


# --- TARGET forms ----------------------------------------------------------------------------

@pytest.mark.parametrize('target, node_name', [
    ('scan_ahead', 'scan_ahead'),
    ('scan_pkg.scan_ahead', 'scan_ahead'),
    (str(FIXTURES / 'two_nodes.py') + ':Listener', 'listener'),
], ids=['console script', 'module', 'file:Class'])
def test_target_forms_run_the_named_node(target, node_name, tmp_path, capfd):
    result = run_simulation('obstacles', [target], duration_s=0.3, out_dir=tmp_path,
                            record=False, plot=False)
    assert result.ok
    assert len(log_lines(capfd.readouterr().err, node_name)) == 3


def test_target_can_be_a_copy_of_a_node_file_anywhere(tmp_path, capfd):
    student_file = tmp_path / 'elsewhere' / 'my_scan_ahead.py'
    student_file.parent.mkdir()
    shutil.copy(SCAN_AHEAD_SOURCE, student_file)
    result = run_simulation('obstacles', [str(student_file)], duration_s=0.3,
                            out_dir=tmp_path / 'out', record=False, plot=False)
    assert result.ok
    assert len(log_lines(capfd.readouterr().err, 'scan_ahead')) == 3


@pytest.mark.parametrize('suffix', ['', ':ScanAhead'])
def test_a_node_file_in_a_folder_with_a_colon_is_a_path(suffix, tmp_path, capfd):
    student_file = tmp_path / 'col:on' / 'my_scan_ahead.py'
    student_file.parent.mkdir()
    shutil.copy(SCAN_AHEAD_SOURCE, student_file)
    result = run_simulation('obstacles', [f'{student_file}{suffix}'], duration_s=0.3,
                            out_dir=tmp_path / 'out', record=False, plot=False)
    assert result.ok
    assert len(log_lines(capfd.readouterr().err, 'scan_ahead')) == 3


def test_file_target_with_class_name_picks_that_class(tmp_path):
    result = run_simulation('obstacles', [f"{FIXTURES / 'two_nodes.py'}:Driver"],
                            duration_s=1.0, out_dir=tmp_path, record=False, plot=False)
    assert result.ok
    assert result.metrics['distance_m'] > 0.05


# --- runs that cannot start ------------------------------------------------------------------

@pytest.mark.parametrize('args, mentions', [
    (['--node', 'no_such_node'], "'no_such_node' is neither a console script"),
    (['--node', 'missing_dir/missing.py'], 'not found: missing_dir/missing.py'),
    (['--node', str(FIXTURES / 'no_node.py')], 'exactly one rclpy Node subclass (none)'),
    (['--node', str(FIXTURES / 'two_nodes.py')], 'several: Listener, Driver'),
    (['--node', str(FIXTURES / 'two_nodes.py') + ':Talker'], "no Node subclass 'Talker'"),
    (['--node', 'scan_ahead', '--world', 'no_such_world'], "unknown world 'no_such_world'"),
    (['--node', 'wall_follow', '--param', 'wall_follow:distance=1'],
     "parameter 'distance' to '1' of type 'INTEGER', expecting type 'DOUBLE'"),
    (['--node', 'scan_ahead', '--param', 'distance=0.6'], 'expected NODE:NAME=VALUE'),
    (['--node', 'scan_ahead', '--param', 'sim_bridge:seed=3'], 'sim_bridge:seed'),
    (['--node', 'scan_ahead', '--param', 'sim_bridge:physics_rate=0.0'],
     "'physics_rate' must be positive"),
    (['--node', 'scan_ahead', '--param', 'sim_bridge:lidar_samples=-3'],
     'samples must be a positive integer'),
    (['--node', 'scan_ahead', '--robot', 'no_such_bot'],
     "model 'no_such_bot' not found"),
    (['--node', 'scan_ahead', '--param', 'sim_bridge:robot_pose=[0.0, 0.0, 0.0]'],
     'sim_bridge:robot_pose: the runner sets it (use --world, --robot, --robot-pose'),
    (['--node', 'scan_ahead', '--duration', '0'], 'duration must be a positive number'),
    (['--node', 'scan_ahead', '--duration', 'inf'], 'duration must be a positive number'),
    (['--node', 'scan_ahead', '--seed', '-1'], 'seed must be a non-negative integer'),
    (['--node', 'scan_ahead', '--remap', '/scan'],
     "--remap '/scan' is not a remapping rule: expected FROM:=TO or NODE:FROM:=TO"),
    (['--node', 'scan_ahead', '--remap', '/a b:=/c'],
     "rcl cannot read the nodes' arguments: Couldn't parse remap rule: '-r /a b:=/c'"),
    (['--node', 'scan_ahead', '--seed', str(2 ** 63)],
     'seed must be a non-negative integer up to 9223372036854775807 (a ROS integer parameter '
     'is int64), got 9223372036854775808'),
], ids=['unknown target', 'missing file', 'no Node subclass', 'two Node subclasses',
        'unknown class', 'unknown world', 'param type', 'malformed param',
        'param the runner sets', 'bad simulator param', 'bad lidar param', 'unknown robot',
        'robot pose as a param', 'zero duration',
        'infinite duration', 'negative seed', 'remap without :=', 'remap rcl refuses',
        'seed beyond int64'])
def test_start_error_is_one_line_exit_2_and_writes_nothing(args, mentions, tmp_path, run_main):
    out_dir = tmp_path / 'out'
    argv = ['--world', 'wall_follow_box', '--duration', '1', *args, '--out', str(out_dir)]
    status, stdout, stderr = run_main(*argv)
    assert status == 2
    assert stdout == ''
    (error,) = [line for line in stderr.splitlines() if line.startswith('error: ')]
    assert mentions in error and 'Traceback' not in stderr
    assert not out_dir.exists()


def test_a_simulator_that_cannot_start_says_nothing_of_node_processes(tmp_path, run_main):
    """No node process started: no warning about how node processes run (was 'runs ')."""
    status, _, stderr = run_main('--world', 'wall_follow_box', '--node', 'scan_ahead',
                                 '--param', 'sim_bridge:physics_rate=0.0', '--duration', '1',
                                 '--out', str(tmp_path / 'out'))
    assert status == 2
    said = [line for line in stderr.splitlines() if line.startswith(('warning: ', 'error: '))]
    # What was wrong, not where the simulator's code raised it (was '... at bridge.py:291: ...').
    assert said == ["error: sim_bridge: parameter 'physics_rate' must be positive and finite, "
                    'got 0.0']


def test_a_robot_without_a_lidar_is_one_start_error_naming_the_model(tmp_path, run_main):
    """Not a crash line with the kit's source (was 'ValueError: ... at simulator.py:89: ...')."""
    model = tmp_path / 'blind_robot'
    model.mkdir()
    lab_robot = Path(__file__).parents[2] / 'models' / 'lab_robot' / 'model.sdf'
    (model / 'model.sdf').write_text(
        lab_robot.read_text().split('<sensor name=')[0] + '</link></model></sdf>')
    status, stdout, stderr = run_main('--world', 'obstacles', '--robot', str(model), '--node',
                                      'scan_ahead', '--duration', '1',
                                      '--out', str(tmp_path / 'out'))
    assert (status, stdout) == (2, '')
    said = [line for line in stderr.splitlines() if line.startswith(('warning: ', 'error: '))]
    assert len(said) == 1 and said[0].startswith('error: robot model ')
    assert f"({model / 'model.sdf'}) has no lidar <sensor>" in said[0]
    assert '.py:' not in said[0] and 'Traceback' not in stderr
    assert not (tmp_path / 'out').exists()


def test_a_missing_node_file_is_the_only_line_said_and_nothing_starts():
    """No pybullet banner, no simulator log: the command says what is wrong, alone."""
    done = subprocess.run([sys.executable, '-m', 'sim_bridge.commands.run', '--world',
                           'obstacles', '--node', 'missing_dir/missing.py'],
                          capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stdout) == (2, '')
    assert done.stderr == 'error: node file not found: missing_dir/missing.py\n'


def test_a_machine_no_node_can_run_on_is_one_start_error_not_a_traceback(
        tmp_path, monkeypatch, run_main):
    """A Python the sandbox's uid cannot reach (PARTLY sandboxed, /root closed): one line."""
    from sim_bridge.runner.boundary.outside.sandbox import Sandbox, SandboxError

    def closed(sandbox, program):
        raise SandboxError(f'PARTLY sandboxed: uid 1 (no namespaces) cannot reach {program}')
    monkeypatch.setattr(Sandbox, 'check_reachable', closed)
    status, _, stderr = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--duration',
                                 '0.2', '--quiet', '--out', str(tmp_path / 'out'))
    assert status == 2 and 'Traceback' not in stderr
    (error,) = [line for line in stderr.splitlines() if line.startswith('error: ')]
    assert error.startswith('error: PARTLY sandboxed: uid 1 (no namespaces) cannot reach ')


def test_output_folder_that_cannot_be_created_is_a_start_error(tmp_path, run_main):
    not_a_folder = tmp_path / 'file'
    not_a_folder.write_text('')
    status, _, stderr = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--out',
                                 str(not_a_folder / 'out'))
    assert status == 2
    assert f"error: cannot write to {not_a_folder / 'out'}: " in stderr


@pytest.mark.parametrize('output', ['metrics.json', 'trajectory.png'])
def test_an_output_that_cannot_be_written_is_named_in_one_line(output, tmp_path, run_main):
    (tmp_path / 'out' / output).mkdir(parents=True)  # left there by hand, say
    status, _, stderr = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--duration',
                                 '0.2', '--quiet', '--no-record', '--out', str(tmp_path / 'out'))
    assert status == 2 and 'Traceback' not in stderr
    assert f"error: cannot write {tmp_path / 'out' / output}: Is a directory" in stderr


def test_an_output_folder_with_spaces_unicode_and_a_newline_gets_every_output(tmp_path, run_main):
    out_dir = tmp_path / 'séance 1\nrun'
    status, _, stderr = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--duration',
                                 '0.3', '--quiet', '--out', str(out_dir))
    assert status == 0, stderr
    assert {path.name for path in out_dir.iterdir()} == {
        'metrics.json', 'log.jsonl', 'params.yaml', 'trajectory.png', 'run'}


def test_start_error_leaves_a_previous_run_in_the_folder_untouched(tmp_path, run_main):
    out_dir = tmp_path / 'out'
    assert run_main('--world', 'wall_follow_box', '--node', 'wall_follow', '--duration', '0.5',
                    '--out', str(out_dir))[0] == 0
    before = {path: path.read_bytes() for path in out_dir.rglob('*') if path.is_file()}
    status, _, _ = run_main('--world', 'wall_follow_box', '--node', 'wall_follow',
                            '--param', 'wall_follow:distance=1', '--out', str(out_dir))
    assert status == 2
    assert {path: path.read_bytes() for path in out_dir.rglob('*') if path.is_file()} == before


# --- nodes that fail during the run -----------------------------------------------------------

def test_int_in_a_float_twist_field_fails_the_run_and_keeps_its_outputs(tmp_path, run_main):
    out_dir = tmp_path / 'out'
    status, _, stderr = run_main('--world', 'obstacles', '--node',
                                 str(FIXTURES / 'int_twist.py'), '--duration', '3',
                                 '--out', str(out_dir))
    assert status == 1
    metrics = load_metrics(out_dir)
    (error,) = metrics['node_errors']
    assert error['node'] == 'int_twist'
    # Node, field and type, where it happened, and what Jazzy's default would have done.
    assert "node 'int_twist' raised AssertionError: The 'z' field must be of type 'float'" \
        in error['error']
    assert 'int_twist.py:22: twist.angular.z = 0' in error['error']
    assert 'ROS_PYTHON_CHECK_FIELDS=1' in error['error'] and 'garbage' in error['error']
    assert 'Traceback' in stderr and 'int_twist.py' in stderr
    # The node puts its int in the field at the first scan from t = 1 s: the run ends there.
    assert metrics['sim_time_s'] == pytest.approx(1.0)
    assert metrics['distance_m'] > 0.0
    assert (out_dir / 'trajectory.png').is_file()
    messages = read_bag(out_dir / 'run')
    assert len(messages['/scan']) == SCAN_RATE
    assert len(messages['/cmd_vel']) == SCAN_RATE - 1
    assert all(twist.linear.x == 0.1 for _, twist in messages['/cmd_vel'])


def test_without_field_checks_the_int_goes_out_as_jazzy_sends_it(tmp_path, run_main):
    status, _, _ = run_main('--world', 'obstacles', '--node', str(FIXTURES / 'int_twist.py'),
                            '--duration', '2', '--no-field-checks', '--quiet', '--no-plot',
                            '--out', str(tmp_path))
    assert status == 0
    commands = read_bag(tmp_path / 'run')['/cmd_vel']
    assert len(commands) == 2 * SCAN_RATE
    # The int 0 is sent as the double whose bits are 0: 0.0 (5 would be 5e-324: docs/students.md,
    # Field checks).
    assert [twist.angular.z for _, twist in commands] == [0.0] * len(commands)
    assert os.environ.get('ROS_PYTHON_CHECK_FIELDS') is None


def test_node_raising_in_its_callback_fails_the_run(tmp_path, run_main):
    out_dir = tmp_path / 'out'
    status, stdout, stderr = run_main('--world', 'obstacles', '--node',
                                      str(FIXTURES / 'raising_node.py'), '--duration', '3',
                                      '--out', str(out_dir))
    assert status == 1
    (error,) = load_metrics(out_dir)['node_errors']
    assert error['node'] == 'raiser'
    assert error['error'].startswith(
        "node 'raiser' raised ZeroDivisionError: no valid beam to average at ")
    assert "raising_node.py:19: raise ZeroDivisionError('no valid beam to average')" in \
        error['error']
    assert 'ZeroDivisionError: no valid beam to average' in stderr
    assert 'raiser' in stdout      # the summary's node errors
    # It raises on its fifth scan, at 0.5 s.
    assert load_metrics(out_dir)['sim_time_s'] == pytest.approx(0.5)
    assert len(read_bag(out_dir / 'run')['/scan']) == 5


def test_an_exception_whose_str_raises_fails_the_run_at_the_students_line(tmp_path, run_main):
    out_dir = tmp_path / 'out'
    status, _, stderr = run_main('--world', 'obstacles', '--node',
                                 str(FIXTURES / 'broken_str_error_node.py'), '--duration', '1',
                                 '--no-record', '--no-plot', '--out', str(out_dir))
    assert status == 1
    (error,) = load_metrics(out_dir)['node_errors']
    assert error['error'].startswith(
        "node 'checker' raised ScanError: <exception str() failed> at ")
    assert 'broken_str_error_node.py:27: raise ScanError(msg)' in error['error']
    assert 'targets.py' not in stderr  # no traceback of the runner's own


def test_a_world_too_small_for_a_coverage_cell_runs_and_says_coverage_n_a(tmp_path, run_main):
    world = tmp_path / 'speck.yaml'
    world.write_text('bounds: [0, 0, 0.001, 0.001]\n')
    status, stdout, stderr = run_main('--world', str(world), '--node', 'scan_ahead',
                                      '--duration', '0.2', '--quiet', '--no-record',
                                      '--no-plot', '--out', str(tmp_path / 'out'))
    assert (status, 'Traceback' in stderr) == (0, False)
    assert load_metrics(tmp_path / 'out')['coverage'] is None
    assert re.search(r'coverage +n/a', stdout)


@pytest.mark.parametrize('how, says', [
    ('sys.exit', "node 'misbehaver' raised SystemExit (sys.exit(3)) at "),
    ('KeyboardInterrupt', "node 'misbehaver' raised KeyboardInterrupt at "),
])
def test_node_ending_its_process_in_a_callback_fails_the_run_with_outputs(how, says, tmp_path):
    out_dir = tmp_path / 'out'
    done = run_in_subprocess('--world', 'obstacles', '--node',
                             str(FIXTURES / 'misbehaving_node.py'), '--param',
                             f'misbehaver:how={how}', '--duration', '3', '--out', str(out_dir))
    assert done.returncode == 1, done.stderr
    (error,) = load_metrics(out_dir)['node_errors']
    assert error['error'].startswith(says) and 'misbehaving_node.py' in error['error']
    assert 'Run summary' in done.stdout
    assert load_metrics(out_dir)['sim_time_s'] == pytest.approx(0.5)
    assert len(read_bag(out_dir / 'run')['/scan']) == 5
    assert (out_dir / 'trajectory.png').is_file()


def test_an_error_in_the_standard_library_is_reported_at_the_students_line(tmp_path, run_main):
    node_file = FIXTURES / 'near_average.py'
    status, _, stderr = run_main('--world', 'obstacles', '--node', str(node_file), '--duration',
                                 '1', '--no-record', '--no-plot', '--out', str(tmp_path))
    assert status == 1
    (error,) = load_metrics(tmp_path)['node_errors']
    # statistics.mean raised it, on the student's call: their line, not statistics.py's.
    assert error['error'] == (
        "node 'near_average' raised StatisticsError: mean requires at least one data point at "
        f"{node_file}:20: self.get_logger().info(f'mean near reading: "
        "{statistics.mean(near):.2f} m')")
    # The traceback kept and printed is the student's part: their frames (from the __main__
    # block, as `python3 near_average.py` prints it), then the error.
    lines = error['traceback'].splitlines()
    frames = [line for line in lines if line.startswith('  File ')]
    assert [lines[0], frames[-1], lines[-1]] == [
        'Traceback (most recent call last):', f'  File "{node_file}", line 20, in on_scan',
        'statistics.StatisticsError: mean requires at least one data point']
    assert [frame.split(', in ')[-1] for frame in frames] == ['<module>', 'main', 'on_scan']
    assert error['traceback'] in stderr and '/rclpy/' not in stderr.split('[near_average]')[-1]


def test_node_raising_in_its_constructor_fails_the_run(tmp_path, run_main):
    out_dir = tmp_path / 'out'
    status, _, _ = run_main('--world', 'wall_follow_box', '--node', 'wall_follow', '--param',
                            'wall_follow:side=middle', '--out', str(out_dir))
    assert status == 1
    (error,) = load_metrics(out_dir)['node_errors']
    assert error['node'] == 'wall_follow' and 'side must be one of' in error['error']
    messages = read_bag(out_dir / 'run')
    assert set(messages) <= {'/clock', '/tf_static', '/rosout'}
    # /rosout: the node's traceback, its own process's last lines.
    assert messages['/rosout'][-1][1].msg.startswith('ValueError: ')


def test_rclpy_spin_once_inside_a_callback_works_as_in_the_nodes_own_process(tmp_path, capfd):
    """rclpy.spin_once(self) spins the global executor, the one main's rclpy.spin spins."""
    status = main(['--world', 'obstacles', '--node', str(FIXTURES / 'spin_in_callback.py'),
                   '--duration', '2', '--no-record', '--no-plot', '--out', str(tmp_path)])
    assert status == 0
    # Its 20 Hz timer ran all 2 s (and its scans with it): the node stayed on the executor.
    assert len(log_lines(capfd.readouterr().err, 'spinner')) == 40
    assert load_metrics(tmp_path)['distance_m'] == pytest.approx(0.2 * 2.0, abs=0.05)


def test_a_node_spinning_its_own_executor_in_a_callback_leaves_mains_spin_as_on_a_robot(
        tmp_path, run_main):
    node_file = FIXTURES / 'spin_in_callback.py'
    status, _, _ = run_main('--world', 'obstacles', '--node', str(node_file), '--param',
                            'spinner:executor=own', '--duration', '2', '--no-record',
                            '--no-plot', '--out', str(tmp_path))
    assert status == 0
    metrics = load_metrics(tmp_path)
    assert metrics['node_errors'] == [] and metrics['sim_time_s'] == pytest.approx(2.0)
    # Its own executor took it off main's rclpy.spin: its timer ran once, then never again.
    lines = (tmp_path / 'log.jsonl').read_text()
    assert 'timer call 1' in lines and 'timer call 2' not in lines


def assert_warned(out_dir, stderr, warnings, run_warnings):
    """Check a run's warnings: in metrics.json and as ``warning:`` lines on stderr, in order."""
    assert run_warnings(load_metrics(out_dir)['warnings']) == warnings
    assert run_warnings(warned(stderr)) == warnings


def warned(stderr: str) -> list[str]:
    """Return the ``warning:`` lines of a run's stderr, without their prefix."""
    return [line[len('warning: '):] for line in stderr.splitlines()
            if line.startswith('warning: ')]


def test_a_parameter_no_node_declared_is_a_warning(tmp_path, run_main, run_warnings):
    status, _, stderr = run_main(
        '--world', 'wall_follow_box', '--node', 'wall_follow', '--param', 'wall_follow:nosuch=1',
        '--param', 'wall_follow:distance=0.6', '--param', 'sim_bridge:nosuch_either=true',
        '--duration', '0.5', '--no-record', '--no-plot', '--out', str(tmp_path))
    assert status == 0
    warnings = [
        "node 'wall_follow' did not declare parameter 'nosuch' (given by --param or the params "
        'file); it was ignored',
        "node 'sim_bridge' did not declare parameter 'nosuch_either' (given by --param or the "
        'params file); it was ignored']
    assert_warned(tmp_path, stderr, warnings, run_warnings)


def test_parameters_for_a_node_that_is_not_running_are_a_warning_as_ros_ignores_them(
        tmp_path, run_main, run_warnings):
    status, _, _ = run_main('--world', 'wall_follow_box', '--node', 'scan_ahead', '--param',
                            'wall_follow:distance=0.6', '--duration', '0.2', '--no-record',
                            '--no-plot', '--out', str(tmp_path))
    assert status == 0
    assert run_warnings(load_metrics(tmp_path)['warnings']) == [
        'parameters given for node(s) wall_follow, but the nodes are sim_bridge, scan_ahead; '
        'they were ignored']


HUSKY_FOLLOWER = str(FIXTURES / 'husky_wall_follower.py')
HUSKY_REMAPS = ('--remap', '/robot/scan:=/scan', '--remap', '/husky/cmd_vel:=/cmd_vel')


def test_a_node_on_other_topics_drives_with_remapping_rules(tmp_path, run_main, run_warnings):
    status, _, stderr = run_main(
        '--world', 'wall_follow_box', '--node', HUSKY_FOLLOWER, *HUSKY_REMAPS,
        '--duration', '10', '--quiet', '--no-plot', '--out', str(tmp_path))
    assert status == 0
    metrics = load_metrics(tmp_path)
    assert metrics['distance_m'] > 1.0 and run_warnings(metrics['warnings']) == []
    assert run_warnings(warned(stderr)) == []
    # Recorded under the simulator's name: the runner's own nodes are not remapped.
    assert len(read_bag(tmp_path / 'run')['/cmd_vel']) > 10


def test_a_remapping_rule_can_name_the_node(tmp_path, run_main):
    status, _, _ = run_main(
        '--world', 'wall_follow_box', '--node', HUSKY_FOLLOWER, '--remap',
        'wall_follower_node:/robot/scan:=/scan', '--remap', 'other_node:/husky/cmd_vel:=/x',
        '--remap', 'wall_follower_node:/husky/cmd_vel:=/cmd_vel', '--duration', '5',
        '--quiet', '--no-record', '--no-plot', '--out', str(tmp_path))
    assert status == 0
    assert load_metrics(tmp_path)['distance_m'] > 0.5


def test_topics_nothing_is_at_the_other_end_of_are_warned_with_the_rule_to_fix_them(
        tmp_path, run_main, run_warnings):
    status, _, stderr = run_main(
        '--world', 'wall_follow_box', '--node', HUSKY_FOLLOWER, '--duration', '1',
        '--no-record', '--no-plot', '--out', str(tmp_path))
    assert status == 0
    warnings = [
        'wall_follower_node subscribes to /robot/scan: nothing publishes it (the simulator '
        'publishes /scan: --remap /robot/scan:=/scan)',
        'wall_follower_node publishes /husky/cmd_vel: nothing subscribes to it (the simulator '
        'subscribes to /cmd_vel: --remap /husky/cmd_vel:=/cmd_vel)']
    assert_warned(tmp_path, stderr, warnings, run_warnings)


def test_the_simulator_is_not_remapped(tmp_path, run_main, run_warnings):
    status, _, _ = run_main(
        '--world', 'wall_follow_box', '--node', 'wall_follow', '--remap',
        '/cmd_vel:=/wall_follow/cmd_vel', '--duration', '3', '--quiet', '--no-record',
        '--no-plot', '--out', str(tmp_path))
    assert status == 0
    metrics = load_metrics(tmp_path)
    assert metrics['distance_m'] < 0.01
    assert run_warnings(metrics['warnings']) == [
        'wall_follow publishes /wall_follow/cmd_vel: nothing subscribes to it (the simulator '
        'subscribes to /cmd_vel: --remap /wall_follow/cmd_vel:=/cmd_vel)']


def test_a_students_wall_follower_is_graded_by_the_scenarios_params_remaps_and_setpoint(
        tmp_path, run_warnings):
    from sim_bridge.grading.runs import run_scenario
    scenario = scenario_from_dict({
        'world': 'wall_follow_box', 'nodes': ['wall_follow'], 'duration': 30,
        # The scenario's parameters for its own node: the student's node names itself
        # wall_follower_node, declares target_distance but no distance.
        'params': {'wall_follow': {'target_distance': 0.5, 'distance': 0.5}},
        'remap': ['/robot/scan:=/scan', '/husky/cmd_vel:=/cmd_vel'],
        'setpoint': {'wall_distance_m': 0.5},
        'criteria': ['collisions == 0', 'wall_distance_m.mae < 0.2']}, 'husky')
    scenario = scenario.with_node_override(f'wall_follow={HUSKY_FOLLOWER}')
    report = run_scenario(scenario.runs()[0], tmp_path, record=False, plot=False)
    assert report.error is None
    wall = report.metrics['wall_distance_m']
    assert wall['setpoint'] == 0.5 and isinstance(wall['mae'], float)
    # target_distance reached the node (its default is 0.8 m).
    assert wall['mean'] == pytest.approx(0.5, abs=0.1)
    assert run_warnings(report.metrics['warnings']) == [
        "no node declared parameter 'distance' (given for every node, /**); it was ignored"]
    assert report.passed


def test_a_run_with_only_declared_parameters_has_no_warnings(wall_follow_runs, run_warnings):
    assert run_warnings(load_metrics(wall_follow_runs['first'])['warnings']) == []


def test_a_node_that_shuts_ros_down_ends_the_run_with_every_output(
        tmp_path, run_main, run_warnings):
    node_file = FIXTURES / 'quitter.py'
    status, stdout, stderr = run_main('--world', 'obstacles', '--node', str(node_file),
                                      '--duration', '3', '--out', str(tmp_path))
    # A node ending ROS ends its own process normally: the run ends there, not as a failure.
    assert status == 0, stderr
    metrics = load_metrics(tmp_path)
    ended_by = ("node 'quitter' shut ROS down (rclpy.shutdown()) in its timer callback at "
                f'{node_file}:26: rclpy.shutdown()')
    assert metrics['ended_by'] == ended_by and metrics['node_errors'] == []
    assert run_warnings(metrics['warnings']) == [f'{ended_by}: the run ended at 1 s of its 3 s']
    assert f'warning: {ended_by}' in stderr and ended_by in stdout
    assert metrics['sim_time_s'] == pytest.approx(1.0)
    assert metrics['distance_m'] == pytest.approx(0.2 * 0.9, abs=0.03)
    assert (tmp_path / 'trajectory.png').is_file()
    assert len(read_bag(tmp_path / 'run')['/scan']) == SCAN_RATE


def test_a_run_to_its_duration_was_ended_by_nothing(wall_follow_runs):
    assert load_metrics(wall_follow_runs['first'])['ended_by'] is None


def test_same_seed_gives_identical_metrics_and_recordings(wall_follow_runs):
    first, again = (load_metrics(wall_follow_runs[label]) for label in ('first', 'again'))
    for varying in ('wall_time_s', 'real_time_factor'):
        del first[varying], again[varying]
    assert first == again
    assert first['distance_m'] > 1.0
    first_bag, again_bag = (read_bag(wall_follow_runs[label] / 'run')
                            for label in ('first', 'again'))
    assert {topic: len(items) for topic, items in first_bag.items()} == \
        {topic: len(items) for topic, items in again_bag.items()}
    assert recorded(wall_follow_runs['first'] / 'run') == \
        recorded(wall_follow_runs['again'] / 'run')
    assert (wall_follow_runs['first'] / 'run' / 'metadata.yaml').read_bytes() == \
        (wall_follow_runs['again'] / 'run' / 'metadata.yaml').read_bytes()


def test_wanderbot_same_seed_gives_identical_metrics_and_recordings(wanderbot_runs):
    first, again = (load_metrics(folder) for folder in wanderbot_runs)
    for varying in ('wall_time_s', 'real_time_factor'):
        del first[varying], again[varying]
    assert first == again
    assert first['distance_m'] > 1.0 and first['turns_deg']
    assert recorded(wanderbot_runs[0] / 'run') == recorded(wanderbot_runs[1] / 'run')
    # wanderbot's timer (20 Hz) gets /clock of its own between the messages it hears.
    assert len(read_bag(wanderbot_runs[0] / 'run')['/cmd_vel']) == 20 * 20


def test_another_seed_gives_another_recording(wall_follow_runs):
    assert recorded(wall_follow_runs['first'] / 'run') != \
        recorded(wall_follow_runs['other_seed'] / 'run')


def test_param_reaches_the_node(tmp_path, run_main):
    status, _, _ = run_main('--world', 'wall_follow_box', '--node', 'wall_follow', '--param',
                            'wall_follow:distance=0.6', '--duration', '20', '--quiet',
                            '--out', str(tmp_path))
    assert status == 0
    wall_distance = load_metrics(tmp_path)['wall_distance_m']
    assert wall_distance['setpoint'] == 0.6
    # The follower holds the new distance, not its default of 0.5 m.
    assert wall_distance['mean'] == pytest.approx(0.6, abs=0.03)
    assert 'distance: 0.6' in (tmp_path / 'params.yaml').read_text()


def test_simulator_param_reaches_the_bridge(tmp_path, run_main):
    status, _, _ = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--param',
                            'sim_bridge:lidar_samples=360', '--duration', '0.2', '--quiet',
                            '--out', str(tmp_path))
    assert status == 0
    assert [len(scan.ranges) for _, scan in read_bag(tmp_path / 'run')['/scan']] == [360, 360]


def test_robot_and_robot_pose_spawn_a_model_the_run_is_scored_with(tmp_path, run_main,
                                                                   monkeypatch):
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(MODELS))
    status, _, _ = run_main('--world', 'obstacles', '--robot', 'little_bot', '--robot-pose',
                            '0.5', '-1.0', '1.5', '--node', 'scan_ahead', '--duration', '0.4',
                            '--quiet', '--out', str(tmp_path))
    assert status == 0
    bag = read_bag(tmp_path / 'run')
    assert [(scan.header.frame_id, len(scan.ranges)) for _, scan in bag['/scan']] == \
        [('base_scan', 360)] * 2                                  # 5 Hz for 0.4 s
    _, odom = bag['/odom'][0]
    position = odom.pose.pose.position  # from the spawn pose, as Gazebo's DiffDrive
    assert (position.x, position.y, yaw_of(odom.pose.pose.orientation)) == \
        pytest.approx((0.0, 0.0, 0.0))
    bridge_params = yaml.safe_load((tmp_path / 'params.yaml').read_text())['sim_bridge']
    assert bridge_params['ros__parameters']['robot'] == 'little_bot'
    assert bridge_params['ros__parameters']['robot_pose'] == [0.5, -1.0, 1.5]
    # Scored with the spawned robot's outline, a 0.2 m square turned 1.5 rad, not a circle:
    # nearest is the 1 m cube's corner at (2.0, -0.5).
    corners = np.array([[0.1, 0.1], [-0.1, 0.1], [-0.1, -0.1], [0.1, -0.1]])
    turned = corners @ np.array([[math.cos(1.5), math.sin(1.5)],
                                 [-math.sin(1.5), math.cos(1.5)]]) + (0.5, -1.0)
    clearance = min(math.dist(corner, (2.0, -0.5)) for corner in turned)
    assert load_metrics(tmp_path)['min_clearance_m'] == pytest.approx(clearance, abs=1e-6)


def test_what_the_world_does_not_simulate_is_said_once_and_kept_in_the_metrics(
        tmp_path, run_main, monkeypatch, run_warnings):
    world = replace(World.load('obstacles'), ignored='ignored: 1 light')
    monkeypatch.setattr(World, 'load', lambda *args, **kwargs: world)
    status, _, stderr = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--duration',
                                 '0.2', '--out', str(tmp_path))
    assert status == 0
    assert stderr.count('ignored: 1 light') == 1
    metrics = load_metrics(tmp_path)
    assert metrics['ignored'] == 'ignored: 1 light'
    assert run_warnings(metrics['warnings']) == []


def test_start_pose_inside_an_obstacle_cannot_start(tmp_path):
    with pytest.raises(RunError, match=r'start pose \[0.0, 0.0, 0.0\]'):
        run_simulation('wall_follow_box', ['wall_follow'], start=[0.0, 0.0, 0.0],
                       out_dir=tmp_path / 'out')
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('side, start, direction', [('right', None, -1), ('left', 'mirrored', 1)])
def test_mirrored_start_puts_the_target_on_the_left(side, start, direction, tmp_path):
    result = run_simulation('wall_follow_box', ['wall_follow'], duration_s=40.0,
                            params={'wall_follow': {'side': side}}, start=start,
                            out_dir=tmp_path, quiet=True, plot=False)
    assert result.metrics['collisions'] == 0
    assert result.metrics['laps'] == direction
    spawn = yaml.safe_load((tmp_path / 'params.yaml').read_text())['sim_bridge'][
        'ros__parameters'].get('robot_pose')
    x, y, yaw = World.load('wall_follow_box').robot_start
    mirrored_yaw = yaw + (math.pi if start == 'mirrored' else 0.0)
    spawn_yaw = yaw if spawn is None else spawn[2]
    assert math.cos(spawn_yaw - mirrored_yaw) == pytest.approx(1.0, abs=1e-3)


# --- the runner leaves nothing behind in the process -----------------------------------------

def test_gui_off_run_never_sleeps(monkeypatch, tmp_path):
    real_sleep = time.sleep

    def no_sleep(seconds):
        caller = sys._getframe(1).f_globals['__name__']
        if caller == 'sim_bridge.runner.boundary.outside.sandbox_host':
            return real_sleep(seconds)  # the sandbox's sweep of a run's ended processes
        raise AssertionError(f'time.sleep({seconds}) in a gui-off run')

    monkeypatch.setattr(time, 'sleep', no_sleep)
    result = run_simulation('obstacles', ['scan_ahead'], duration_s=2.0, out_dir=tmp_path,
                            quiet=True, record=False, plot=False)
    assert result.ok


def broken_import_target(tmp_path: Path) -> str:
    path = tmp_path / 'broken.py'
    path.write_text('import rclpy\n\nraise ImportError("no module named scan_utils")\n')
    return str(path)


@pytest.mark.parametrize('make_target, outcome', [
    (lambda tmp_path: 'scan_ahead', 'completes'),
    (lambda tmp_path: str(FIXTURES / 'raising_node.py'), 'node error'),
    (lambda tmp_path: str(FIXTURES / 'quitter.py'), 'completes'),
    (lambda tmp_path: 'no_such_node', RunError),
    (broken_import_target, RunError),
], ids=['completed', 'node raised', 'node shut ROS down', 'start error',
        'target import fails'])
def test_runner_leaves_rclpy_shut_down_and_the_environment_as_it_was(
        make_target, outcome, tmp_path, monkeypatch):
    import rclpy
    monkeypatch.setenv('ROS_PYTHON_CHECK_FIELDS', '')
    before = {name: os.environ.get(name) for name in
              ('ROS_PYTHON_CHECK_FIELDS', 'ROS_AUTOMATIC_DISCOVERY_RANGE')}
    target = make_target(tmp_path)
    if isinstance(outcome, type):
        with pytest.raises(outcome):
            run_simulation('obstacles', [target], duration_s=1.0, out_dir=tmp_path / 'out',
                           quiet=True, record=False, plot=False)
    else:
        result = run_simulation('obstacles', [target], duration_s=1.0,
                                out_dir=tmp_path / 'out', quiet=True, plot=False)
        assert result.ok == (outcome == 'completes')
    assert not rclpy.ok()
    assert {name: os.environ.get(name) for name in before} == before
    from geometry_msgs.msg import Twist
    Twist().linear.x = 1   # no field check outside a run: Jazzy's default


def test_no_record_and_no_plot_leave_only_the_metrics(tmp_path, run_main):
    out_dir = tmp_path / 'out'
    status, stdout, _ = run_main('--world', 'obstacles', '--node', 'scan_ahead', '--duration',
                                 '0.5', '--quiet', '--no-record', '--no-plot',
                                 '--out', str(out_dir))
    assert status == 0
    assert sorted(path.name for path in out_dir.iterdir()) == [
        'log.jsonl', 'metrics.json', 'params.yaml']
    assert f'outputs: {out_dir}/metrics.json, log.jsonl\n' in stdout


@pytest.mark.parametrize('source, mentions', [
    ('import rclpy\n\nraise ImportError("no module named scan_utils")\n',
     'ImportError: no module named scan_utils at {path}:3: raise ImportError('),
    ('x = 1\ndef broken(:\n', 'SyntaxError: invalid syntax at {path}:2: def broken(:'),
    ('import sys\n\nsys.exit("run me with ros2 run")\n',
     "SystemExit (sys.exit('run me with ros2 run')) at {path}:3: sys.exit("),
    ('if True:\n        x = 1\n\ty = 2\n',
     'TabError: inconsistent use of tabs and spaces in indentation at {path}:3'),
    ('class ScanError(Exception):\n    def __str__(self):\n        return self.typo\n\n\n'
     'raise ScanError()\n', 'ScanError: <exception str() failed> at {path}:6: raise ScanError()'),
], ids=['import error', 'syntax error', 'exit at import', 'tabs and spaces', 'str that raises'])
def test_a_target_that_fails_to_import_is_a_one_line_start_error(
        source, mentions, tmp_path, run_main):
    path = tmp_path / 'broken.py'
    path.write_text(source)
    status, stdout, stderr = run_main('--world', 'obstacles', '--node', str(path),
                                      '--out', str(tmp_path / 'out'))
    assert status == 2 and stdout == ''
    (error,) = [line for line in stderr.splitlines() if line.startswith('error: ')]
    assert error.startswith(f"error: '{path}' fails to import: ")
    assert mentions.format(path=path) in error
    # Above it, the student's part of the traceback, as `python3 broken.py` shows it: their
    # file and line, not the runner's frames.
    assert f'File "{path}", line ' in stderr and 'sim_bridge/' not in stderr


def test_a_node_file_of_null_bytes_is_a_one_line_start_error(tmp_path, run_main):
    path = tmp_path / 'scan_ahead.py'
    path.write_bytes(bytes(range(256)))  # a .pyc or a zip saved under the node's name
    status, _, stderr = run_main('--world', 'obstacles', '--node', str(path),
                                 '--out', str(tmp_path / 'out'))
    assert status == 2 and 'Traceback' not in stderr
    # Python 3.11.4 and later say SyntaxError, earlier ones (Debian 12's 3.11.2) ValueError.
    assert re.search(re.escape(f"error: '{path}' fails to import: ") + '(SyntaxError|ValueError)'
                     ': source code string cannot contain null bytes', stderr), stderr


def test_a_node_file_saved_on_windows_with_a_bom_and_crlf_runs(tmp_path, run_main):
    path = tmp_path / 'scan_ahead.py'
    path.write_bytes(b'\xef\xbb\xbf' + SCAN_AHEAD_SOURCE.read_bytes().replace(b'\n', b'\r\n'))
    status, _, stderr = run_main('--world', 'obstacles', '--node', str(path), '--duration',
                                 '0.3', '--no-record', '--no-plot', '--out', str(tmp_path / 'o'))
    assert status == 0, stderr
    assert log_lines(stderr, 'scan_ahead')


def test_a_syntax_error_is_reported_at_the_students_line_in_the_grade_report(tmp_path):
    from sim_bridge.grading.runs import run_scenario
    path = tmp_path / 'wall_follow.py'
    path.write_text('import rclpy\n\n\ndef on_scan(self, msg)\n    pass\n')
    scenario = scenario_from_dict({'world': 'obstacles', 'nodes': [str(path)], 'duration': 1,
                                   'criteria': ['collisions == 0']}, 'syntax')
    report = run_scenario(scenario.runs()[0], tmp_path / 'out', record=False, plot=False)
    assert report.error.endswith(f"SyntaxError: expected ':' at {path}:4: def on_scan(self, msg)")
    # The traceback kept is the student's: their file, line, code and caret; no grader frame.
    assert report.traceback.splitlines() == [
        f'  File "{path}", line 4', '    def on_scan(self, msg)', ' ' * 26 + '^',
        "SyntaxError: expected ':'"]


def test_a_memory_error_while_importing_names_the_memory_limit_and_the_file(tmp_path):
    import resource
    path = tmp_path / 'lookup_node.py'
    path.write_text('# A precomputed table far beyond the memory limit.\n'
                    'TABLE = bytearray(2 ** 37)\n')
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    # 64 GiB: far above what this process uses, far below the table (128 GiB).
    resource.setrlimit(resource.RLIMIT_AS, (2 ** 36, hard))
    try:
        with pytest.raises(RunError) as error:
            run_simulation('obstacles', [str(path)], duration_s=1.0, out_dir=tmp_path / 'out')
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    # The node's limit, which node_limits derives from this process's hard limit.
    limit = node_limits(1.0).memory_bytes
    assert str(error.value) == (
        f"'{path}' fails to import: MemoryError at {path}:2: TABLE = bytearray(2 ** 37) "
        f'(memory limit {limit / 2 ** 30:g} GiB reached while importing {path})')


def test_a_node_file_imports_modules_beside_it(tmp_path, run_main):
    (tmp_path / 'scan_utils.py').write_text('GREETING = "hello from a helper module"\n')
    node_file = tmp_path / 'greeter.py'
    node_file.write_text(
        'from rclpy.node import Node\n\nimport scan_utils\n\n\n'
        'class Greeter(Node):\n\n    def __init__(self):\n'
        "        super().__init__('greeter')\n"
        '        self.get_logger().info(scan_utils.GREETING)\n')
    status, _, stderr = run_main('--world', 'obstacles', '--node', str(node_file), '--duration',
                                 '0.1', '--no-record', '--no-plot', '--out', str(tmp_path / 'o'))
    assert status == 0
    assert 'hello from a helper module' in stderr
    assert str(tmp_path) not in sys.path


# --- real ROS 2 details: the lab's node files, sim time, isolation ----------------------------

def test_a_lab_node_file_runs_unmodified(tmp_path, capfd):
    """The lab's style: std_msgs Int32, a 0.5 s timer, rclpy.spin in main (not called)."""
    result = run_simulation('obstacles', [str(FIXTURES / 'scan_counter.py')], duration_s=2.0,
                            out_dir=tmp_path, plot=False)
    assert result.ok
    lines = log_lines(capfd.readouterr().err, 'scan_counter')
    # The timer runs on sim time, at 0.5, 1.0, 1.5 and 2.0 s. The /clock and the scan of that
    # step are taken in one wait; the timer, due by that clock, in the next: after the scan.
    assert [line for line in lines if line.startswith('Publishing')] == [
        'Publishing: "5"', 'Publishing: "10"', 'Publishing: "15"', 'Publishing: "20"']
    assert sum(line.startswith('Closest reading') for line in lines) == 20


def test_nodes_run_on_sim_time_with_the_params_file(tmp_path):
    result = run_simulation('wall_follow_box', ['wall_follow'], duration_s=0.5, out_dir=tmp_path,
                            quiet=True, plot=False, params={'wall_follow': {'distance': 0.55}})
    assert result.ok
    params = yaml.safe_load((tmp_path / 'params.yaml').read_text())
    assert params['wall_follow']['ros__parameters'] == {'distance': 0.55}
    # The commands' stamps would be wall time without use_sim_time; the bag's times are sim.
    assert read_bag(tmp_path / 'run')['/cmd_vel'][0][0] == NANOSECONDS_PER_SECOND // SCAN_RATE


def private_domain_env() -> dict:
    """Return this environment with a ROS_DOMAIN_ID of this test process's own, discovery on."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(100 + os.getpid() % 100))
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    return env


def test_two_runs_at_once_and_a_live_bridge_beside_them_do_not_hear_each_other(tmp_path):
    env = private_domain_env()
    alone = tmp_path / 'alone'
    assert run_in_subprocess('--world', 'wall_follow_box', '--node', 'wall_follow', '--duration',
                             '5', '--quiet', '--no-plot', '--out', str(alone),
                             env=env).returncode == 0
    # A live simulator on the same domain, with discovery on, and a listener counting what
    # reaches /cmd_vel there: the runs' commands must not.
    live = subprocess.Popen(
        [sys.executable, '-m', 'sim_bridge.ros.bridge', '--ros-args',
         '-p', 'world:=wall_follow_box', '-p', 'real_time_factor:=2.0'],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    listener = subprocess.Popen([sys.executable, str(FIXTURES / 'topic_counter.py'), '8'],
                                env=env, stdout=subprocess.PIPE, text=True)
    try:
        runs = [subprocess.Popen(
            [sys.executable, '-m', 'sim_bridge.run', '--world', 'wall_follow_box', '--node',
             'wall_follow', '--duration', '5', '--quiet', '--no-plot', '--out',
             str(tmp_path / name)], env=env, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL) for name in ('one', 'two')]
        assert [run.wait(timeout=120) for run in runs] == [0, 0]
        counts = json.loads(listener.communicate(timeout=60)[0])
    finally:
        for process in (live, listener):
            process.kill()
            process.wait()
    # The listener heard the live simulator (so the domain works), and no run's /cmd_vel.
    assert counts['/scan'] > 0 and counts['/cmd_vel'] == 0
    # Each run is byte for byte the run made alone: nothing reached it from the others.
    for name in ('one', 'two'):
        assert recorded(tmp_path / name / 'run') == recorded(alone / 'run')


def test_ctrl_c_ends_a_run_with_its_outputs_written(tmp_path):
    out_dir = tmp_path / 'out'
    process = subprocess.Popen(
        [sys.executable, '-m', 'sim_bridge.run', '--world', 'obstacles', '--node', 'wanderbot',
         '--duration', '3600', '--quiet', '--no-plot', '--out', str(out_dir)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (out_dir / 'run' / 'run_0.mcap').exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)  # well into the run
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, stderr
    assert 'run interrupted at ' in stderr and 'Traceback' not in stderr
    metrics = load_metrics(out_dir)
    assert 0.0 < metrics['sim_time_s'] < 3600 and metrics['node_errors'] == []
    messages = read_bag(out_dir / 'run')
    assert len(messages['/scan']) == pytest.approx(metrics['sim_time_s'] * SCAN_RATE, abs=1)


def test_a_second_ctrl_c_while_the_outputs_are_written_does_not_cut_them_short():
    before = signal.getsignal(signal.SIGINT)
    interrupt = UserInterrupt()
    with pytest.raises(KeyboardInterrupt):
        with interrupt:
            os.kill(os.getpid(), signal.SIGINT)  # the user's Ctrl-C during the run
            pytest.fail('Ctrl-C did not interrupt the run')
    assert interrupt.pressed
    os.kill(os.getpid(), signal.SIGINT)  # pressed again while metrics.json, the plot, the bag
    interrupt.restore()                  # are written: nothing happens until they are
    assert signal.getsignal(signal.SIGINT) is before


# --- issue 17: hints for TurtleBot3 scan code and for modules of a ROS installation ----------

LAB_SCAN = ('this scan has 36 ranges from -1.57 rad (index 0, right) to +1.57 rad (index 35, '
            'left); `--robot turtlebot3_burger` has 360 ranges from 0 rad (index 0, ahead) to '
            '+6.28 rad (index 359, ahead)')
ROS_MODULE_HINT = 'comes with a ROS 2 Jazzy installation (apt package ros-jazzy-'


@pytest.mark.parametrize('fixture, node, raised, line, code', [
    ('tb3_obstacle_stop', 'obstacle_stop', 'IndexError: array index out of range', 19,
     'left = msg.ranges[90]'),
    # Raised by min() in the student's helper: its line, the deepest of the student's frames.
    ('tb3_right_gap', 'right_gap', 'ValueError: min() arg is an empty sequence', 10,
     'return min(ranges[first:last])'),
    # Raised in numpy, in a timer reading the scan the node kept.
    ('tb3_timer_left', 'left_watch', 'ValueError: zero-size array to reduction operation '
     'minimum which has no identity', 25, 'left = ranges[80:100].min()'),
], ids=['index', 'empty slice in a helper', 'numpy empty slice in a timer'])
def test_turtlebot3_scan_code_on_the_lab_robot_fails_with_the_scans_geometry(
        fixture, node, raised, line, code, tmp_path, run_main):
    node_file = FIXTURES / f'{fixture}.py'
    status, stdout, _ = run_main('--world', 'obstacles', '--node', str(node_file),
                                 '--duration', '1', '--no-record', '--no-plot',
                                 '--out', str(tmp_path))
    assert status == 1
    (error,) = load_metrics(tmp_path)['node_errors']
    assert error['error'] == f"node '{node}' raised {raised} at {node_file}:{line}: {code} " \
                             f'({LAB_SCAN})'
    assert LAB_SCAN in stdout      # the summary's node errors


def test_the_scan_hint_gives_the_geometry_of_the_scan_the_node_received(tmp_path, run_main):
    node_file = FIXTURES / 'tb3_obstacle_stop.py'
    status, _, _ = run_main('--world', 'obstacles', '--node', str(node_file), '--param',
                            'sim_bridge:lidar_samples=72', '--duration', '1', '--no-record',
                            '--no-plot', '--out', str(tmp_path))
    assert status == 1
    (error,) = load_metrics(tmp_path)['node_errors']
    assert error['error'].endswith(
        'left = msg.ranges[90] (this scan has 72 ranges from -1.57 rad (index 0, right) to '
        '+1.57 rad (index 71, left); `--robot turtlebot3_burger` has 360 ranges from 0 rad '
        '(index 0, ahead) to +6.28 rad (index 359, ahead))')


def test_a_turtlebot3_scan_read_past_its_end_gets_its_own_geometry_only(tmp_path, run_main):
    node_file = tmp_path / 'behind.py'
    node_file.write_text(
        'import rclpy\nfrom rclpy.node import Node\n'
        'from rclpy.qos import qos_profile_sensor_data\nfrom sensor_msgs.msg import LaserScan\n'
        '\n\nclass Behind(Node):\n\n    def __init__(self):\n'
        "        super().__init__('behind')\n"
        "        self.create_subscription(LaserScan, 'scan', self.scan_callback,\n"
        '                                 qos_profile_sensor_data)\n\n'
        '    def scan_callback(self, msg):\n'
        "        self.get_logger().info(f'{msg.ranges[180]} {msg.ranges[360]}')\n")
    status, _, _ = run_main('--world', 'obstacles', '--robot', 'turtlebot3_burger', '--node',
                            str(node_file), '--duration', '1', '--no-record', '--no-plot',
                            '--out', str(tmp_path / 'out'))
    assert status == 1
    (error,) = load_metrics(tmp_path / 'out')['node_errors']
    assert error['error'].endswith(
        '(this scan has 360 ranges from 0 rad (index 0, ahead) to +6.28 rad (index 359, '
        'ahead))')


def test_an_index_error_away_from_any_scan_gets_no_scan_hint(tmp_path, run_main):
    node_file = tmp_path / 'waypoints.py'
    node_file.write_text(
        'from rclpy.node import Node\n\n\nclass Waypoints(Node):\n\n'
        "    def __init__(self):\n        super().__init__('waypoints')\n"
        '        self.waypoints = [(1.0, 0.0)]\n        self.next = 1\n'
        '        self.create_timer(0.1, self.timer_callback)\n\n'
        '    def timer_callback(self):\n        x, y = self.waypoints[self.next]\n')
    status, _, _ = run_main('--world', 'obstacles', '--node', str(node_file), '--duration', '1',
                            '--no-record', '--no-plot', '--out', str(tmp_path / 'out'))
    assert status == 1
    (error,) = load_metrics(tmp_path / 'out')['node_errors']
    assert error['error'].endswith(': x, y = self.waypoints[self.next]')


@pytest.mark.skipif(importlib.util.find_spec('tf_transformations') is not None,
                    reason='tf_transformations is installed')
def test_a_node_file_importing_tf_transformations_says_it_comes_with_ros(
        tmp_path, run_main, monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    node_file = FIXTURES / 'tf_yaw_node.py'
    status, stdout, stderr = run_main('--world', 'obstacles', '--node', str(node_file),
                                      '--out', str(tmp_path))
    assert status == 2 and stdout == ''
    (error,) = [line for line in stderr.splitlines() if line.startswith('error: ')]
    assert error.startswith(
        f"error: '{node_file}' fails to import: ModuleNotFoundError: No module named "
        f"'tf_transformations' at {node_file}:6: from tf_transformations import "
        'euler_from_quaternion (tf_transformations comes with a ROS 2 Jazzy installation '
        '(apt package ros-jazzy-tf-transformations), not with the ROS wheels from PyPI; ')
    assert 'transforms3d' in error


@pytest.mark.skipif(importlib.util.find_spec('tf2_ros') is not None,
                    reason='tf2_ros is installed')
def test_a_callback_importing_tf2_ros_says_it_comes_with_ros(tmp_path, run_main, monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    node_file = FIXTURES / 'tf_lookup_in_callback.py'
    status, _, _ = run_main('--world', 'obstacles', '--node', str(node_file), '--duration', '1',
                            '--no-record', '--no-plot', '--out', str(tmp_path))
    assert status == 1
    (error,) = load_metrics(tmp_path)['node_errors']
    assert error['error'] == (
        "node 'where_am_i' raised ModuleNotFoundError: No module named 'tf2_ros' at "
        f'{node_file}:18: from tf2_ros import Buffer, TransformListener (tf2_ros '
        f'{ROS_MODULE_HINT}tf2-ros), not with the ROS wheels from PyPI; without TF here, read '
        'the robot pose from /odom (nav_msgs/Odometry))')


def test_a_module_neither_ros_nor_installed_keeps_the_plain_message(tmp_path):
    node_file = FIXTURES / 'missing_import_node.py'
    with pytest.raises(RunError) as error:
        run_simulation('obstacles', [str(node_file)], duration_s=1.0, out_dir=tmp_path)
    assert str(error.value) == (
        f"'{node_file}' fails to import: ModuleNotFoundError: No module named 'turtle_magic' at "
        f'{node_file}:4: import turtle_magic  # noqa: F401')


@pytest.mark.skipif(importlib.util.find_spec('tf_transformations') is not None,
                    reason='tf_transformations is installed')
def test_a_ros_module_imported_by_a_module_beside_the_node_is_reported_at_that_import(
        tmp_path, run_main, monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    (tmp_path / 'geometry_utils.py').write_text(
        '"""Helpers for the pose."""\n\nfrom tf_transformations import euler_from_quaternion\n')
    node_file = tmp_path / 'heading.py'
    node_file.write_text('from rclpy.node import Node\n\nimport geometry_utils\n\n\n'
                         'class Heading(Node):\n    pass\n')
    status, _, stderr = run_main('--world', 'obstacles', '--node', str(node_file),
                                 '--out', str(tmp_path / 'out'))
    assert status == 2
    (error,) = [line for line in stderr.splitlines() if line.startswith('error: ')]
    # The deepest line of the student's own files: the helper's import, not the node's.
    assert f"No module named 'tf_transformations' at {tmp_path / 'geometry_utils.py'}:3: " \
           'from tf_transformations import euler_from_quaternion (tf_transformations ' \
           f'{ROS_MODULE_HINT}tf-transformations)' in error
