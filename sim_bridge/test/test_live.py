"""
Live runs (sim_bridge.live.live): the simulator and a lab node as separate ROS 2 processes.

The pure parts (command lines, lines printed, environment) are checked without processes; the
process handling with plain Python children; the live runs with the real simulator and node
processes, watched by a third process (fixtures/live_observer.py). The ROS 2 children run on a
ROS_DOMAIN_ID of this test process's own with discovery on (this process keeps its own DDS
traffic to itself: see conftest.py).
"""

from contextlib import contextmanager
import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from sim_bridge.commands import live as live_command
from sim_bridge.live import live
from sim_bridge.live.lab_tasks import LAB_TASKS
from sim_bridge.runner import processes
from sim_bridge.runner.options import split_param
from sim_bridge.simulation.geometry import signed_distance
from sim_bridge.simulation.robot import pose_in_world
from sim_bridge.simulation.world import World

FIXTURES = Path(__file__).parent / 'fixtures'
PACKAGES = Path(__file__).resolve().parents[2]
SCAN_RATE_HZ = 10.0
WALL_DISTANCE_M = 0.5
#: Longest wall time (s) any one wait of these tests may take.
TIMEOUT_S = 60.0
#: Longest wall time (s) a wait for simulated time to pass may take: a busy machine runs the
#: simulator slower than its real-time factor, so the tests wait for sim time, not wall time.
SIM_TIMEOUT_S = 240.0


def live_env() -> dict:
    """Return this environment with a ROS_DOMAIN_ID of this test process's own, discovery on."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(120 + os.getpid() % 80))
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    return env


def python_spec(executable: str, code: str) -> processes.ProcessSpec:
    """Return a process running Python ``code``."""
    return processes.ProcessSpec(executable, (sys.executable, '-c', code))


# ---------------------------------------------------------------------------------------------
# The pure parts.

def test_lines_are_printed_as_ros2_launch_prints_them():
    specs = [python_spec('sim_bridge', ''), python_spec('wall_follow', '')]
    assert processes.process_names(specs) == ['sim_bridge-1', 'wall_follow-2']
    assert processes.prefixed('wall_follow-2', '[INFO] [1.5] [wall_follow]: hi') == \
        '[wall_follow-2] [INFO] [1.5] [wall_follow]: hi'
    assert processes.started_line('sim_bridge-1', 1234) == \
        '[INFO] [sim_bridge-1]: process started with pid [1234]'
    assert processes.ended_line('wall_follow-2', 1235, 0, ['wall_follow']) == \
        '[INFO] [wall_follow-2]: process has finished cleanly [pid 1235]'
    assert processes.ended_line('wall_follow-2', 1235, 1, ['python', '-m', 'x']) == \
        "[ERROR] [wall_follow-2]: process has died [pid 1235, exit code 1, cmd 'python -m x']."
    assert processes.signal_line('sim_bridge-1', 'SIGINT') == \
        "[INFO] [sim_bridge-1]: sending signal 'SIGINT' to process[sim_bridge-1]"
    assert processes.escalation_line('sim_bridge-1', 5.0, 'SIGINT', 'SIGTERM') == (
        "[ERROR] [sim_bridge-1]: process[sim_bridge-1] failed to terminate '5' seconds after "
        "receiving 'SIGINT', escalating to 'SIGTERM'")


def test_children_get_line_buffered_output_and_discovery_across_processes():
    env, warning = processes.child_environment({'ROS_DOMAIN_ID': '42', 'PATH': '/bin'})
    assert env == {'ROS_DOMAIN_ID': '42', 'PATH': '/bin', 'PYTHONUNBUFFERED': '1',
                   'RCUTILS_LOGGING_BUFFERED_STREAM': '1'}
    assert warning is None
    env, warning = processes.child_environment({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'OFF'})
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert 'LOCALHOST' in warning
    env, _ = processes.child_environment({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'})
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SUBNET'


def test_a_task_starts_the_simulator_and_its_node_as_lab_launch_does():
    bridge, node = live.task_specs('wall_follow', real_time_factor=2,
                                   params={'wall_follow': {'distance': '0.6'}},
                                   python='python3')
    assert bridge == processes.ProcessSpec('sim_bridge', (
        'python3', '-m', 'sim_bridge.ros.bridge', '--ros-args',
        '--params-file', str(PACKAGES / 'sim_bridge' / 'params' / 'sim.yaml'),
        '-p', 'world:=wall_follow_box', '-p', 'gui:=false', '-p', 'real_time_factor:=2.0'))
    # The node's overrides come after its params file and use_sim_time: the last one wins.
    assert node == processes.ProcessSpec('wall_follow', (
        'python3', '-m', 'scan_pkg.wall_follow', '--ros-args',
        '--params-file', str(PACKAGES / 'scan_pkg' / 'params' / 'wall_follow.yaml'),
        '-p', 'use_sim_time:=true', '-p', 'distance:=0.6'))


def test_the_world_and_the_window_can_be_chosen_and_a_node_without_params_file_has_none():
    bridge, node = live.task_specs('scan_ahead', world='room', gui=True,
                                   params={'sim_bridge': {'seed': '3'}})
    assert bridge.cmd[-8:] == ('-p', 'world:=room', '-p', 'gui:=true',
                               '-p', 'real_time_factor:=1.0', '-p', 'seed:=3')
    assert node.cmd[1:] == ('-m', 'scan_pkg.scan_ahead', '--ros-args',
                            '-p', 'use_sim_time:=true')


def test_a_robot_and_its_pose_go_to_the_simulator_as_its_parameters():
    bridge, _ = live.task_specs('scan_ahead', robot='little_bot', robot_pose=(0.5, -1, 1.5),
                                params={'sim_bridge': {'seed': '3'}})
    assert bridge.cmd[-6:] == ('-p', 'robot:=little_bot', '-p', 'robot_pose:=[0.5, -1.0, 1.5]',
                               '-p', 'seed:=3')
    # Without them the task's world keeps its own robot, the lab robot.
    assert not any(argument.startswith(('robot:=', 'robot_pose:='))
                   for argument in live.task_specs('scan_ahead')[0].cmd)


@pytest.mark.parametrize('task', sorted(LAB_TASKS))
def test_every_task_runs_its_console_scripts_module(task):
    bridge, node = live.task_specs(task)
    assert bridge.cmd[1:3] == ('-m', 'sim_bridge.ros.bridge')
    assert node.executable == LAB_TASKS[task].node
    assert node.cmd[1:3] == ('-m', f'scan_pkg.{LAB_TASKS[task].node}')
    assert f'world:={LAB_TASKS[task].world}' in bridge.cmd


def test_a_students_own_node_file_is_the_tasks_node_run_as_written(tmp_path):
    # ./lab live wall_follow --node ~/ros2_ws/src/scan_pkg/scan_pkg/wall_follow.py
    mine = tmp_path / 'scan_pkg' / 'wall_follow.py'
    mine.parent.mkdir()
    mine.write_text('print("mine")\n')
    _, node = live.task_specs('wall_follow', params={'wall_follow': {'distance': '0.6'}},
                              python='python3', node_file=mine)
    # Not the kit's module nor its params file (the kit's nodes' parameters).
    assert node == processes.ProcessSpec('wall_follow.py', (
        'python3', str(mine), '--ros-args', '-p', 'use_sim_time:=true', '-p', 'distance:=0.6'))
    assert live.shown_command(node).startswith('python3 wall_follow.py --ros-args')
    with pytest.raises(FileNotFoundError, match='--node .*no_such.py: no such file'):
        live.task_specs('wall_follow', node_file=tmp_path / 'no_such.py')


def test_bad_tasks_and_parameters_are_refused_before_anything_starts(capsys):
    with pytest.raises(ValueError, match="unknown task 'fly'"):
        live.task_specs('fly')
    with pytest.raises(ValueError, match='parameters for wanderbot'):
        live.task_specs('wall_follow', params={'wanderbot': {'speed': '1.0'}})
    assert split_param('wall_follow:distance=0.6') == (
        'wall_follow', 'distance', '0.6')
    assert split_param('sim_bridge:robot_pose=[0.0, 1.0, 0.0]') == \
        ('sim_bridge', 'robot_pose', '[0.0, 1.0, 0.0]')
    for text in ('distance=0.6', 'wall_follow:distance', ':x=1'):
        with pytest.raises(ValueError, match='NODE:NAME=VALUE'):
            split_param(text)
    assert live_command.main(['wall_follow', '--world', 'no_such_world']) == 2
    assert live_command.main(['wall_follow', '--robot', 'no_such_bot']) == 2
    assert live_command.main(['wall_follow', '--param', 'distance=0.6']) == 2
    assert live_command.main(['wall_follow', '--param', 'wanderbot:speed=1.0']) == 2
    assert live_command.main(['wall_follow', '--node', 'no_such_node.py']) == 2
    assert 'error: --node no_such_node.py: no such file' in capsys.readouterr().err
    for argv in (['fly'], ['wall_follow', '--rtf', '0'], ['wall_follow', '--duration', 'nan'],
                 ['wall_follow', '--robot-pose', '1', '2']):
        with pytest.raises(SystemExit) as exit_info:
            live_command.main(argv)
        assert exit_info.value.code == 2


# ---------------------------------------------------------------------------------------------
# Process handling, with plain Python children.

def test_output_of_both_streams_is_prefixed_per_process_in_order():
    lines = []
    code = ('import sys, time\nfor i in range(3):\n'
            "    print('out', i); print('err', i, file=sys.stderr); time.sleep(0.05)")
    with processes.LiveRun([python_spec('one', code), python_spec('two', 'print("hello")')],
                           env=live_env(), out=lines.append) as run:
        run.start()
        deadline = time.monotonic() + TIMEOUT_S
        while run.running() and time.monotonic() < deadline:
            run.pump(0.5)
    assert [line for line in lines if line.startswith('[one-1] ')] == [
        '[one-1] out 0', '[one-1] err 0', '[one-1] out 1', '[one-1] err 1', '[one-1] out 2',
        '[one-1] err 2']
    assert '[two-2] hello' in lines
    pids = [process.pid for process in run.processes]
    assert lines[:2] == [f'[INFO] [one-1]: process started with pid [{pids[0]}]',
                         f'[INFO] [two-2]: process started with pid [{pids[1]}]']
    # The end is reported after the process's last line.
    assert lines.index(f'[INFO] [one-1]: process has finished cleanly [pid {pids[0]}]') > \
        lines.index('[one-1] err 2')
    assert run.returncodes == {'one-1': 0, 'two-2': 0} and run.clean()


def test_a_process_that_ends_early_stops_the_others_and_is_named():
    lines = []
    status = processes.run_live([python_spec('sim', 'import time; time.sleep(60)'),
                                 python_spec('node', 'raise SystemExit(3)')],
                                duration_s=TIMEOUT_S, env=live_env(), out=lines.append)
    assert status == 1
    assert any(line.startswith('[ERROR] [node-2]: process has died [pid ')
               and 'exit code 3, cmd ' in line for line in lines)
    assert "[INFO] [sim-1]: sending signal 'SIGINT' to process[sim-1]" in lines
    assert lines[-1] == ('[ERROR] [live]: node-2 ended before the run did (exit code 3): '
                         'stopped the others')


def test_stopping_goes_last_started_first_and_escalates_as_launch_does():
    lines = []
    ignores_sigint = ('import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
                      "print('ready', flush=True); time.sleep(60)")
    ignores_both = ('import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
                    'signal.signal(signal.SIGTERM, signal.SIG_IGN); '
                    "print('ready', flush=True); time.sleep(60)")
    specs = [python_spec('sim', ignores_sigint), python_spec('node', ignores_both)]
    with processes.LiveRun(specs, env=live_env(), out=lines.append, sigterm_timeout_s=0.3,
                           sigkill_timeout_s=0.3) as run:
        run.start()
        deadline = time.monotonic() + TIMEOUT_S
        while sum(line.endswith('] ready') for line in lines) < 2 and \
                time.monotonic() < deadline:
            run.pump(0.1)
    signals = [line for line in lines if 'sending signal' in line or 'escalating' in line]
    assert signals == [
        "[INFO] [node-2]: sending signal 'SIGINT' to process[node-2]",
        "[ERROR] [node-2]: process[node-2] failed to terminate '0.3' seconds after receiving "
        "'SIGINT', escalating to 'SIGTERM'",
        "[INFO] [node-2]: sending signal 'SIGTERM' to process[node-2]",
        "[ERROR] [node-2]: process[node-2] failed to terminate '0.3' seconds after receiving "
        "'SIGTERM', escalating to 'SIGKILL'",
        "[INFO] [node-2]: sending signal 'SIGKILL' to process[node-2]",
        "[INFO] [sim-1]: sending signal 'SIGINT' to process[sim-1]",
        "[ERROR] [sim-1]: process[sim-1] failed to terminate '0.3' seconds after receiving "
        "'SIGINT', escalating to 'SIGTERM'",
        "[INFO] [sim-1]: sending signal 'SIGTERM' to process[sim-1]"]
    assert run.returncodes == {'node-2': -signal.SIGKILL, 'sim-1': -signal.SIGTERM}
    assert not run.clean()


def test_children_can_be_interrupted_even_when_started_with_sigint_ignored():
    # A command started in the background has SIGINT ignored, and its children inherit that:
    # Python would then install no KeyboardInterrupt handler in them.
    lines = []
    code = 'import signal; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)'
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        run = processes.LiveRun([python_spec('child', code)], env=live_env(), out=lines.append)
        run.start()
    finally:
        signal.signal(signal.SIGINT, previous)
    with run:
        run.wait(TIMEOUT_S)
    assert '[child-1] True' in lines


def test_a_live_run_started_with_sigint_ignored_still_stops_at_ctrl_c():
    # `./lab live wall_follow &` in a script: SIGINT ignored from the start, as launch
    # overrides with a handler of its own.
    code = ('import sys\n'
            'from sim_bridge.runner import processes\n'
            "sys.exit(processes.run_live([processes.ProcessSpec('sleeper', (sys.executable, "
            "'-c', 'import time; time.sleep(60)'))]))\n")
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        parent = subprocess.Popen([sys.executable, '-c', code], env=live_env(),
                                  stdout=subprocess.PIPE, text=True)
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        assert 'process started' in parent.stdout.readline()
        parent.send_signal(signal.SIGINT)
        output = parent.communicate(timeout=TIMEOUT_S)[0]
    finally:
        parent.kill()
    assert 'user interrupted with ctrl-c (SIGINT)' in output


def running(pid: int) -> bool:
    """Tell whether process ``pid`` runs (exists and is no zombie waiting to be reaped)."""
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(')', 1)[1].split()[0] != 'Z'


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='prctl PR_SET_PDEATHSIG')
def test_children_are_interrupted_when_the_live_process_dies():
    code = ('import sys, time\n'
            'from sim_bridge.runner import processes\n'
            "run = processes.LiveRun([processes.ProcessSpec('sleeper', (sys.executable, '-c', "
            "'import time; time.sleep(60)'))])\n"
            'run.start()\n'
            'time.sleep(60)\n')
    parent = subprocess.Popen([sys.executable, '-c', code], env=live_env(),
                              stdout=subprocess.PIPE, text=True)
    try:
        started = parent.stdout.readline()
        child = int(started.rsplit('[', 1)[1].rstrip(']\n'))
        parent.kill()
        parent.wait(timeout=TIMEOUT_S)
        deadline = time.monotonic() + TIMEOUT_S
        while running(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not running(child), started
    finally:
        parent.kill()


# ---------------------------------------------------------------------------------------------
# Live runs of the simulator and the lab's nodes.

class LineReader:
    """Collect a process's stdout lines in a thread, so a test can wait for one."""

    def __init__(self, process: subprocess.Popen):
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, args=(process.stdout,), daemon=True)
        self._thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.lines.append(line.rstrip('\n'))

    def wait_for(self, predicate, timeout_s: float = TIMEOUT_S) -> bool:
        """Wait (bounded) until a line satisfies ``predicate``; tell whether one did."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if any(predicate(line) for line in list(self.lines)):
                return True
            time.sleep(0.05)
        return False

    def join(self) -> list[str]:
        """Return every line, once the process's output has ended (bounded)."""
        self._thread.join(timeout=TIMEOUT_S)
        return self.lines


class Observing:
    """
    fixtures/live_observer.py beside a live run: the sim time and commands it has seen so far.

    :meth:`finish` stops it (SIGINT) and returns what it saw (its JSON); :meth:`kill` ends it
    whatever happened.
    """

    def __init__(self, env: dict):
        self.process = subprocess.Popen(
            [sys.executable, str(FIXTURES / 'live_observer.py'), str(SIM_TIMEOUT_S + 60.0)],
            env=env, stdout=subprocess.PIPE, text=True)
        self.reader = LineReader(self.process)

    def last(self, kind: str) -> list[str] | None:
        """Return the words after ``kind`` of the last progress line of that kind, or None."""
        return next((line.split()[1:] for line in reversed(list(self.reader.lines))
                     if line.startswith(kind + ' ')), None)

    def sim_time(self) -> float:
        """Return the sim time (s) of the odometry received last, 0 before any."""
        words = self.last('sim_time')
        return 0.0 if words is None else float(words[0])

    def has_sim_time(self, seconds: float) -> bool:
        """Tell whether odometry of sim time ``seconds`` or later has been received."""
        return self.sim_time() >= seconds

    def stopped(self) -> bool:
        """Tell whether the last command received is a stop."""
        return self.last('cmd_vel') == ['0.0', '0.0']

    def wait_for(self, condition, timeout_s: float = SIM_TIMEOUT_S) -> bool:
        """Wait (bounded) until ``condition()``; tell whether it came true."""
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)
        return True

    def finish(self) -> dict:
        self.process.send_signal(signal.SIGINT)
        self.process.wait(timeout=TIMEOUT_S)
        return json.loads(self.reader.join()[-1])

    def kill(self) -> None:
        self.process.kill()
        self.process.wait()


@contextmanager
def observing(env: dict):
    """Run fixtures/live_observer.py beside the block (see :class:`Observing`)."""
    observer = Observing(env)
    try:
        yield observer
    finally:
        observer.kill()


def run_until(run: processes.LiveRun, condition, lines: list[str]) -> None:
    """Print a live run's output until ``condition()`` (bounded); no process may end."""
    deadline = time.monotonic() + SIM_TIMEOUT_S
    while not condition():
        assert time.monotonic() < deadline, '\n'.join(lines)
        assert run.wait(0.1) is None, '\n'.join(lines)


def start_live(argv: list[str], env: dict) -> subprocess.Popen:
    """Start ``python -m sim_bridge.commands.live ARGV``, its output in one text pipe."""
    return subprocess.Popen([sys.executable, '-m', 'sim_bridge.commands.live', *argv], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_wall_follow_live_circles_the_box_at_the_set_distance_and_stops_the_robot():
    env = live_env()
    with observing(env) as observer:
        process = start_live(['wall_follow', '--rtf', '2'], env)
        reader = LineReader(process)
        try:
            # More than half a turn round the box, however fast this machine runs it.
            assert observer.wait_for(lambda: observer.has_sim_time(40.0)), reader.lines
            process.send_signal(signal.SIGINT)
            assert process.wait(timeout=TIMEOUT_S) == 0, reader.lines
        finally:
            process.kill()
        assert observer.wait_for(observer.stopped, TIMEOUT_S)  # the node's last command
        seen = observer.finish()
    lines = reader.join()
    output = '\n'.join(lines)
    # Both processes' own lines, with their prefixes, and launch's lines about them.
    assert any(line.startswith('[sim_bridge-1] [WARN] [') and '[sim_bridge]: tf2_ros' in line
               for line in lines), output
    assert any(line.startswith('[wall_follow-2] [INFO] [') and '[wall_follow]: ' in line
               for line in lines), output
    for name in ('sim_bridge-1', 'wall_follow-2'):
        assert any(line.startswith(f'[INFO] [{name}]: process started with pid [')
                   for line in lines)
        assert any(line.startswith(f'[INFO] [{name}]: process has finished cleanly [pid ')
                   for line in lines)
    # The node is stopped first, and has ended before the simulator is asked to.
    node_done = next(index for index, line in enumerate(lines)
                     if line.startswith('[INFO] [wall_follow-2]: process has finished'))
    assert node_done < lines.index(
        "[INFO] [sim_bridge-1]: sending signal 'SIGINT' to process[sim_bridge-1]")
    # One scan per 0.1 s of sim time; sim time never runs ahead of twice the wall clock (a busy
    # machine may run it slower, so no lower bound).
    scans = np.array(seen['scan'])
    assert scans[-1, 1] - scans[0, 1] > 35.0
    assert np.median(np.diff(scans[:, 1])) == pytest.approx(1.0 / SCAN_RATE_HZ)
    assert (scans[-1, 1] - scans[0, 1]) / (scans[-1, 0] - scans[0, 0]) < 2.0 * 1.15
    # odom starts at 0 at the spawn pose (Gazebo's DiffDrive); in the world frame the robot
    # centre keeps the set distance from the box's surface, going clockwise (the box on its
    # right) for more than half a turn.
    odom = np.array(seen['odom'])
    following = odom[odom[:, 0] > 5.0]
    assert following[-1, 0] > 40.0
    world = World.load('wall_follow_box')
    x, y, _ = pose_in_world(world.robot_start, following[:, 1:4].T)
    distance = signed_distance(np.column_stack((x, y)), world.footprints())
    assert np.median(distance) == pytest.approx(WALL_DISTANCE_M, abs=0.1)
    assert np.all(np.abs(distance - WALL_DISTANCE_M) < 0.25)
    heading = np.unwrap(following[:, 3])
    assert heading[0] - heading.min() > math.pi
    # The node's last command, sent when it was interrupted, is a stop.
    assert seen['cmd_vel'][-1][1:] == [0.0, 0.0]
    assert any(abs(linear) > 0.1 for _, linear, _ in seen['cmd_vel'])


def test_live_duration_ends_the_run_after_that_many_wall_seconds():
    """``--duration`` is wall time by definition; nothing here depends on the sim's speed."""
    process = start_live(['scan_ahead', '--duration', '3'], live_env())
    try:
        output = process.communicate(timeout=TIMEOUT_S)[0]
    finally:
        process.kill()
    lines = output.splitlines()
    assert process.returncode == 0, output
    assert not any('user interrupted' in line for line in lines), output
    assert [line.split(']:')[0] + ']' for line in lines if 'process has' in line] == [
        '[INFO] [scan_ahead-2]', '[INFO] [sim_bridge-1]'], output


def test_stopping_the_node_stops_the_robot_while_the_simulator_runs():
    env = live_env()
    lines = []
    with observing(env) as observer:
        specs = [live.bridge_spec('wall_follow_box', real_time_factor=2.0),
                 live.node_spec('wall_follow')]
        with processes.LiveRun(specs, env=env, out=lines.append) as run:
            run.start()
            # Conditions on sim time, not wall time: a busy machine runs the simulator slower.
            run_until(run, lambda: observer.has_sim_time(8.0), lines)
            assert run.stop('wall_follow-2') == 0, '\n'.join(lines)
            stopped_sim_s = observer.sim_time()
            # The observer may lag the simulator: 3 s of margin before the last 3 s.
            run_until(run, lambda: observer.has_sim_time(stopped_sim_s + 6.0), lines)
            assert run.running() == ['sim_bridge-1']
            # The node's last command, sent as it stopped, reaches the observer in its time.
            assert observer.wait_for(observer.stopped, TIMEOUT_S)
            seen = observer.finish()
        assert run.clean(), '\n'.join(lines)
    cmd_vel = np.array(seen['cmd_vel'])
    assert np.abs(cmd_vel[:, 1]).max() > 0.1  # it was driving
    assert list(cmd_vel[-1, 1:]) == [0.0, 0.0]
    # The simulator ran on: its odometry of the last 3 s of sim time has the robot at rest.
    odom = np.array(seen['odom'])
    resting = odom[odom[:, 0] > odom[-1, 0] - 3.0]
    assert resting[-1, 0] - resting[0, 0] > 2.5
    assert np.all(resting[:, 4:6] == 0.0)
    assert np.ptp(resting[:, 1:4], axis=0).max() == 0.0


def test_ctrl_c_stops_the_node_then_the_simulator_cleanly():
    env = live_env()
    process = start_live(['scan_ahead'], env)
    reader = LineReader(process)
    try:
        # scan_ahead logs a range per scan: the scans reach it from the simulator's process.
        assert reader.wait_for(lambda line: line.startswith('[scan_ahead-2] [INFO] [')
                               and '[scan_ahead]: Range ahead: ' in line), reader.lines
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=TIMEOUT_S) == 0, reader.lines
    finally:
        process.kill()
    lines = reader.join()
    assert '[WARNING] [live]: user interrupted with ctrl-c (SIGINT)' in lines
    signals = [line for line in lines if 'sending signal' in line or 'process has' in line]
    assert [line.split(']:')[0] + ']' for line in signals] == [
        '[INFO] [scan_ahead-2]', '[INFO] [scan_ahead-2]', '[INFO] [sim_bridge-1]',
        '[INFO] [sim_bridge-1]']
    assert 'finished cleanly' in signals[1] and 'finished cleanly' in signals[3]


def test_a_students_own_node_file_runs_live_in_place_of_the_kits(tmp_path):
    # A node of the student's own package, as the handout has them write it: its own words.
    mine = tmp_path / 'scan_pkg' / 'scan_ahead.py'
    mine.parent.mkdir()
    mine.write_text(
        'import rclpy\nfrom rclpy.node import Node\nfrom sensor_msgs.msg import LaserScan\n\n\n'
        'class Mine(Node):\n    def __init__(self):\n        super().__init__("my_scan_ahead")\n'
        '        self.create_subscription(LaserScan, "scan", self.on_scan, 10)\n\n'
        '    def on_scan(self, msg):\n'
        '        self.get_logger().info(f"mine: {len(msg.ranges)} beams")\n\n\n'
        'def main():\n    rclpy.init()\n    rclpy.spin(Mine())\n\n\n'
        'if __name__ == "__main__":\n    main()\n')
    process = start_live(['scan_ahead', '--node', str(mine)], live_env())
    reader = LineReader(process)
    try:
        assert reader.wait_for(lambda line: line.startswith('[scan_ahead.py-2] [INFO] [')
                               and '[my_scan_ahead]: mine: 36 beams' in line), reader.lines
        process.send_signal(signal.SIGINT)
        process.wait(timeout=TIMEOUT_S)  # a KeyboardInterrupt of the node's own is its exit 1
    finally:
        process.kill()
    assert not any('Range ahead' in line for line in reader.join())  # the kit's words


def test_a_node_with_a_bad_parameter_ends_the_run_naming_it():
    process = start_live(['wall_follow', '--duration', '60',
                          '--param', 'wall_follow:distance=-1.0'], live_env())
    try:
        output = process.communicate(timeout=TIMEOUT_S)[0]
    finally:
        process.kill()
    lines = output.splitlines()
    assert process.returncode == 1, output
    assert '[wall_follow-2] ValueError: distance must be > 0, got -1.0' in lines
    assert any(line.startswith('[ERROR] [wall_follow-2]: process has died [pid ') and
               "exit code 1, cmd '" in line and 'distance:=-1.0' in line for line in lines), output
    # The simulator is stopped wherever it is: still importing, it ends as any Python program
    # does at Ctrl-C there (exit code -2, as under ros2 launch); once loading the world, cleanly.
    assert any(line.startswith(('[INFO] [sim_bridge-1]: process has finished cleanly',
                                '[ERROR] [sim_bridge-1]: process has died'))
               for line in lines), output
    assert lines[-1] == ('[ERROR] [live]: wall_follow-2 ended before the run did (exit code 1): '
                         'stopped the others'), output


def test_a_node_that_raises_mid_run_ends_the_run_naming_it():
    lines = []
    specs = [live.bridge_spec('obstacles', real_time_factor=2.0),
             processes.ProcessSpec('raiser', (sys.executable, str(FIXTURES / 'raising_node.py')))]
    assert processes.run_live(specs, TIMEOUT_S, env=live_env(), out=lines.append) == 1
    # Four scans crossed from the simulator's process before the fifth made it raise.
    assert sum('[raiser]: scan ' in line for line in lines) == 4, lines
    assert '[raiser-2] ZeroDivisionError: no valid beam to average' in lines
    assert any(line.startswith('[ERROR] [raiser-2]: process has died') for line in lines)
    assert any(line.startswith('[INFO] [sim_bridge-1]: process has finished cleanly')
               for line in lines)
    assert lines[-1].startswith('[ERROR] [live]: raiser-2 ended before the run did')


def test_a_live_recording_traces_the_robot_from_the_pose_it_was_spawned_at(tmp_path):
    """Issue 32: without --robot, --robot-pose was lost, the trace drawn from the world's start."""
    from sim_bridge.live.live_record import LiveRecorder
    pose = (0.0, 1.0, 2.5)
    recorder = LiveRecorder(tmp_path, {}, world='wall_follow_box', robot_pose=pose)
    assert recorder.world.robot_start == pytest.approx(pose)
