"""
The pip-only stand-ins for teleop_twist_keyboard and ``ros2 topic pub /cmd_vel``.

The key logic is tested pure; the programs run as separate processes on a private
ROS_DOMAIN_ID and namespace, with discovery on, the teleop typed into through a
pseudo-terminal, and what reaches ``cmd_vel`` and ``odom`` heard by a listener child.
"""

import json
import os
from pathlib import Path
import queue
import select
import signal
import subprocess
import sys
import termios
import threading
import time

import pytest
from sim_bridge.ros.send_cmd_vel import parse_arguments
from sim_bridge.ros.teleop_keys import BANNER, BANNER_EVERY, CTRL_C, MOVE_BINDINGS, TeleopKeys

FIXTURES = Path(__file__).parent / 'fixtures'
#: Every ROS process of these tests lives in this namespace, on a private domain.
NAMESPACE = f'/teleop_test_{os.getpid()}'
ROS_ARGS = ['--ros-args', '-r', f'__ns:={NAMESPACE}']
STOP = [0.0] * 6

#: teleop_twist_keyboard's layout: key -> (linear x, y, z direction, angular z direction).
LAYOUT = {
    'u': (1, 0, 0, 1), 'i': (1, 0, 0, 0), 'o': (1, 0, 0, -1),
    'j': (0, 0, 0, 1), 'l': (0, 0, 0, -1),
    'm': (-1, 0, 0, -1), ',': (-1, 0, 0, 0), '.': (-1, 0, 0, 1),
    'U': (1, 1, 0, 0), 'I': (1, 0, 0, 0), 'O': (1, -1, 0, 0),
    'J': (0, 1, 0, 0), 'L': (0, -1, 0, 0),
    'M': (-1, 1, 0, 0), '<': (-1, 0, 0, 0), '>': (-1, -1, 0, 0),
    't': (0, 0, 1, 0), 'b': (0, 0, -1, 0),
}


# The key logic.

def test_the_layout_is_teleop_twist_keyboards():
    assert MOVE_BINDINGS == LAYOUT
    for row in ('u    i    o', 'j    k    l', 'm    ,    .', 'U    I    O', 'J    K    L',
                'M    <    >', 't : up (+z)', 'b : down (-z)', 'anything else : stop',
                'q/z : increase/decrease max speeds by 10%', 'CTRL-C to quit'):
        assert row in BANNER


@pytest.mark.parametrize('key', sorted(LAYOUT))
def test_a_move_key_sets_its_direction_at_the_starting_speeds(key):
    keys = TeleopKeys()
    assert keys.press(key) == [] and not keys.done
    x, y, z, th = LAYOUT[key]
    assert keys.velocity == (0.5 * x, 0.5 * y, 0.5 * z, 1.0 * th)
    assert all(type(value) is float for value in keys.velocity)


@pytest.mark.parametrize('key, speed, turn', [
    ('q', 0.55, 1.1), ('z', 0.45, 0.9), ('w', 0.55, 1.0), ('x', 0.45, 1.0), ('e', 0.5, 1.1),
    ('c', 0.5, 0.9)])
def test_a_speed_key_scales_the_speeds_by_ten_percent_and_keeps_the_direction(key, speed, turn):
    keys = TeleopKeys()
    keys.press('u')
    lines = keys.press(key)
    assert (keys.speed, keys.turn) == (pytest.approx(speed), pytest.approx(turn))
    assert keys.velocity == pytest.approx((speed, 0.0, 0.0, turn))
    assert lines == [f'currently:\tspeed {speed}\tturn {turn} ']
    assert all(type(value) is float for value in (keys.speed, keys.turn, *keys.velocity))


def test_speed_steps_compound_and_the_banner_comes_back_every_fifteen():
    keys = TeleopKeys()
    printed = [keys.press('q') for _ in range(2 * BANNER_EVERY)]
    assert keys.speed == pytest.approx(0.5 * 1.1 ** 30) and keys.turn == pytest.approx(1.1 ** 30)
    with_banner = [index for index, lines in enumerate(printed) if BANNER in lines]
    assert with_banner == [BANNER_EVERY - 1, 2 * BANNER_EVERY - 1]


@pytest.mark.parametrize('key', ['k', 'K', ' ', 'a', '1', '\x1b', '\x04', '\r', '\xe9'])
def test_any_other_key_stops(key):
    keys = TeleopKeys()
    keys.press('i')
    assert keys.press(key) == [] and not keys.done
    assert keys.velocity == (0.0, 0.0, 0.0, 0.0)
    assert (keys.speed, keys.turn) == (0.5, 1.0)


def test_ctrl_c_stops_and_quits():
    keys = TeleopKeys()
    keys.press('o')
    keys.press(CTRL_C)
    assert keys.done and keys.velocity == (0.0, 0.0, 0.0, 0.0)


# send_cmd_vel's command line.

@pytest.mark.parametrize('argv, named', [
    (['--linear', 'nan'], '--linear'), (['--linear', 'inf'], '--linear'),
    (['--linear', 'fast'], '--linear'), (['--angular', '-inf'], '--angular'),
    (['--angular', 'abc'], '--angular'), (['--rate', '0'], '--rate'),
    (['--rate', 'nan'], '--rate'), (['--times', '0'], '--times'),
    (['--times', '1.5'], '--times'), (['--wait', '-1'], '--wait'),
    (['--once', '--rate', '5'], '--rate'), (['--once', '--times', '2'], '--times'),
    (['--topic', 'bad topic!'], '--topic'), (['--topic', '/cmd_vel/'], '--topic'),
    (['--topic', 'robot//cmd_vel'], '--topic'),
    (['--rate', '-1e-3'], '--rate')])
def test_send_cmd_vel_refuses_a_bad_argument_by_name(argv, named, capsys):
    with pytest.raises(SystemExit) as exit_info:
        parse_arguments(argv)
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.splitlines()
    assert error[0].startswith('usage: ') and all(line.startswith(' ') for line in error[1:-1])
    assert error[-1].startswith(f'send_cmd_vel: error: argument {named}: ')  # one line


def test_send_cmd_vel_arguments_are_floats_with_defaults():
    arguments = parse_arguments(['--linear', '-0.2', '--angular', '1', '--once'])
    assert (arguments.linear, arguments.angular, arguments.once) == (-0.2, 1.0, True)
    arguments = parse_arguments(['--linear', '-1e-3', '--angular', '-.5E1', '--topic', '~/x'])
    assert (arguments.linear, arguments.angular, arguments.topic) == (-0.001, -5.0, '~/x')
    assert type(arguments.angular) is float
    arguments = parse_arguments([])
    assert (arguments.linear, arguments.angular, arguments.rate, arguments.times,
            arguments.wait, arguments.stamped, arguments.topic) == (
        0.0, 0.0, 10.0, None, 5.0, False, 'cmd_vel')


# The programs, live.

def private_domain_env() -> dict:
    """Return this environment with a ROS_DOMAIN_ID of this test process's own, discovery on."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(150 + os.getpid() % 50), PYTHONUNBUFFERED='1')
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    return env


class Listener:
    """The teleop_listener.py child: the cmd_vel commands and the last odometry it heard."""

    def __init__(self, *arguments: str):
        self.process = subprocess.Popen(
            [sys.executable, str(FIXTURES / 'teleop_listener.py'), *arguments, *ROS_ARGS],
            env=private_domain_env(), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            text=True)
        self.lines = queue.Queue()
        self.commands = []
        self.frame_ids = []
        self.odom = None
        self.odom_count = 0
        threading.Thread(target=self.read, daemon=True).start()

    def read(self):
        for line in self.process.stdout:
            self.lines.put(json.loads(line))

    def wait_for(self, condition, timeout_s: float) -> bool:
        """Take in what the child hears until ``condition()`` holds; False after timeout_s."""
        deadline = time.monotonic() + timeout_s
        while not condition():
            try:
                heard = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                return False
            if 'cmd_vel' in heard:
                self.commands.append(heard['cmd_vel'])
                self.frame_ids.append(heard['frame_id'])
            else:
                self.odom = heard
                self.odom_count += 1
        return True

    def stop(self):
        self.process.kill()
        self.process.wait()


class Terminal:
    """A process whose standard input, output and error are a pseudo-terminal."""

    def __init__(self, *argv: str):
        self.master, self.slave = os.openpty()
        self.settings = termios.tcgetattr(self.slave)
        self.process = subprocess.Popen(argv, stdin=self.slave, stdout=self.slave,
                                        stderr=self.slave, env=private_domain_env())
        self.output = b''
        self.done = threading.Event()
        threading.Thread(target=self.read, daemon=True).start()

    def read(self):
        while not self.done.is_set():
            if select.select([self.master], [], [], 0.05)[0]:
                try:
                    self.output += os.read(self.master, 4096)
                except OSError:
                    return

    def text(self) -> str:
        return self.output.decode(errors='replace')

    def press(self, keys: str):
        os.write(self.master, keys.encode())

    def wait_for_output(self, text: str, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while text not in self.text() and time.monotonic() < deadline:
            time.sleep(0.02)
        return text in self.text()

    def stop(self):
        self.process.kill()
        self.process.wait()
        self.done.set()
        time.sleep(0.1)
        os.close(self.master)
        os.close(self.slave)


def teleop(*ros_args: str) -> Terminal:
    return Terminal(sys.executable, '-m', 'sim_bridge.ros.teleop', *ROS_ARGS, *ros_args)


def test_teleop_drives_the_live_simulator_stops_and_quits_with_a_stop(tmp_path):
    with open(tmp_path / 'bridge.log', 'w') as log:
        bridge = subprocess.Popen(
            [sys.executable, '-m', 'sim_bridge.ros.bridge', *ROS_ARGS, '-p', 'world:=obstacles',
             '-p', 'real_time_factor:=2.0'], env=private_domain_env(), stdout=log, stderr=log)
    listener = Listener()
    keyboard = teleop()
    try:
        assert keyboard.wait_for_output('currently:\tspeed 0.5\tturn 1.0', 20), keyboard.text()
        assert listener.wait_for(lambda: listener.odom is not None, 20), 'no /odom heard'
        start_x = listener.odom['odom'][0]

        # Hold 'i' down (the keyboard repeats it) until the robot has moved 0.2 m forward.
        deadline = time.monotonic() + 20
        while listener.odom['odom'][0] < start_x + 0.2 and time.monotonic() < deadline:
            keyboard.press('i')
            listener.wait_for(lambda: False, 0.1)
        x, y, yaw = listener.odom['odom']
        assert x >= start_x + 0.2, (listener.odom, keyboard.text())
        assert abs(y) < 0.01 and abs(yaw) < 0.01
        assert listener.commands[0] == [0.5, 0.0, 0.0, 0.0, 0.0, 0.0]

        keyboard.press('k')
        assert listener.wait_for(lambda: listener.commands[-1] == STOP, 10)
        assert listener.wait_for(lambda: listener.odom['twist'] == [0.0, 0.0], 10)
        stopped_at, heard = listener.odom['odom'], listener.odom_count
        assert listener.wait_for(lambda: listener.odom_count >= heard + 10, 10)
        assert listener.odom['odom'] == pytest.approx(stopped_at, abs=1e-4)

        # Slower by 10 %, forward again, then Ctrl-C: the last command is a stop.
        keyboard.press('x')
        assert keyboard.wait_for_output('currently:\tspeed 0.45\tturn 1.0', 10)
        keyboard.press('i')
        assert listener.wait_for(lambda: listener.commands[-1][0] > 0.0, 10)
        assert listener.commands[-1] == pytest.approx([0.45, 0.0, 0.0, 0.0, 0.0, 0.0])
        sent = len(listener.commands)
        keyboard.press(CTRL_C)
        assert keyboard.process.wait(timeout=10) == 0, keyboard.text()
        assert listener.wait_for(lambda: len(listener.commands) > sent, 10)
        listener.wait_for(lambda: False, 0.3)
        assert listener.commands[sent:] == [STOP]
        # The terminal is as it was before the teleop made it raw.
        assert termios.tcgetattr(keyboard.slave) == keyboard.settings
        assert 'Traceback' not in keyboard.text()
    finally:
        for process in (keyboard, listener):
            process.stop()
        bridge.kill()
        bridge.wait()


def test_teleop_stamped_sends_twist_stamped_with_its_frame_id_and_stops_on_sigterm():
    listener = Listener('--stamped')
    keyboard = teleop('-p', 'stamped:=true', '-p', 'frame_id:=base_link')
    try:
        assert keyboard.wait_for_output('CTRL-C to quit', 20), keyboard.text()
        # Until the two have discovered each other, a key's command may reach no one.
        deadline = time.monotonic() + 20
        while not listener.commands and time.monotonic() < deadline:
            keyboard.press('J')
            listener.wait_for(lambda: False, 0.2)
        assert listener.commands[-1] == [0.0, 0.5, 0.0, 0.0, 0.0, 0.0]
        keyboard.press('j')
        assert listener.wait_for(lambda: listener.commands[-1][5] == 1.0, 10)
        # Ended by `kill`, not by a key: it stops the robot and gives the terminal back too.
        keyboard.process.send_signal(signal.SIGTERM)
        assert keyboard.process.wait(timeout=10) == 0, keyboard.text()
        assert listener.wait_for(lambda: listener.commands[-1] == STOP, 10)
        assert set(listener.frame_ids) == {'base_link'}
        assert termios.tcgetattr(keyboard.slave) == keyboard.settings
    finally:
        keyboard.stop()
        listener.stop()


def test_teleop_needs_a_terminal_and_frame_id_needs_stamped():
    done = subprocess.run([sys.executable, '-m', 'sim_bridge.ros.teleop', *ROS_ARGS],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          env=private_domain_env(), timeout=30)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        'teleop_keyboard: standard input is not a terminal; it reads key presses, so run it in '
        'a terminal of its own']
    for parameter, says in (
            ('frame_id:=base_link', "'frame_id' can only be set when 'stamped' is True"),
            ('stamped:=maybe', "parameter 'stamped' to 'maybe' of type 'STRING', expecting "
                               "type 'BOOL'")):
        keyboard = teleop('-p', parameter)
        try:
            assert keyboard.process.wait(timeout=30) == 1
            text = keyboard.text()
            assert 'teleop_keyboard: ' in text and says in text and 'Traceback' not in text
        finally:
            keyboard.stop()


def send_cmd_vel(*arguments: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'sim_bridge.ros.send_cmd_vel', *arguments,
                             *ROS_ARGS], env=private_domain_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kwargs)


def test_send_cmd_vel_once_waits_for_the_subscriber_and_sends_one_command():
    listener = Listener()
    sender = send_cmd_vel('--once', '--linear', '0.2', '--angular', '0.5', '--wait', '20')
    try:
        _, stderr = sender.communicate(timeout=30)
        assert sender.returncode == 0, stderr
        assert listener.wait_for(lambda: listener.commands, 10)
        listener.wait_for(lambda: False, 0.3)
        # No stop after it: like ros2 topic pub --once, the simulator's cmd_vel_timeout ends it.
        assert listener.commands == [[0.2, 0.0, 0.0, 0.0, 0.0, 0.5]]
    finally:
        sender.kill()
        listener.stop()


def test_send_cmd_vel_times_sends_that_many_commands_then_a_stop():
    listener = Listener('--stamped')
    sender = send_cmd_vel('--times', '3', '--rate', '50', '--angular', '-0.3', '--stamped',
                          '--wait', '20')
    try:
        _, stderr = sender.communicate(timeout=30)
        assert sender.returncode == 0, stderr
        assert listener.wait_for(lambda: len(listener.commands) >= 4, 10), listener.commands
        listener.wait_for(lambda: False, 0.3)
        assert listener.commands == [[0.0, 0.0, 0.0, 0.0, 0.0, -0.3]] * 3 + [STOP]
    finally:
        sender.kill()
        listener.stop()


@pytest.mark.parametrize('ending', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_send_cmd_vel_at_a_rate_sends_a_stop_on_ctrl_c_or_sigterm(ending):
    listener = Listener()
    # Started as in a script's background (SIGINT ignored): Ctrl-C still stops it.
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        sender = send_cmd_vel('--rate', '20', '--linear', '-0.1')
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        assert listener.wait_for(lambda: len(listener.commands) >= 3, 20)
        sender.send_signal(ending)
        _, stderr = sender.communicate(timeout=10)
        assert sender.returncode == 0 and 'Traceback' not in stderr, stderr
        assert listener.wait_for(lambda: listener.commands[-1] == STOP, 10)
        assert listener.commands[:-1] == [[-0.1, 0.0, 0.0, 0.0, 0.0, 0.0]] * \
            (len(listener.commands) - 1)
    finally:
        sender.kill()
        listener.stop()


def test_send_cmd_vel_once_without_a_subscriber_fails_after_its_wait():
    sender = send_cmd_vel('--once', '--linear', '0.2', '--wait', '0.3')
    _, stderr = sender.communicate(timeout=30)
    assert sender.returncode == 1
    assert f'no subscriber on {NAMESPACE}/cmd_vel after 0.3 s' in stderr
