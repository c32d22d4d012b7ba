"""
The agent changes nothing a node can observe: the same node file, live and stepped, says the same.

Each node file of fixtures/differential runs twice: under plain rclpy at real time
(plain_rclpy_run.py: ``python3 FILE``, its DDS kept in its process) and in a stepped run, in its
sandboxed process under the agent. Both print the same console lines, in the same order (text,
severity, logger, the caller's file, line and function; ``once``, ``throttle_duration_sec`` and
``skip_first`` as rclpy decides them; ``print`` between them), and publish the same messages, in
order. The runner's package docstring (sim_bridge.runner) says which file checks which patch.
"""

import json
import os
from pathlib import Path
import subprocess
import sys

from geometry_msgs.msg import Twist
import pytest
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader
from sim_bridge.runner.node_output import console_pattern

FIXTURES = Path(__file__).parent / 'fixtures' / 'differential'
PLAIN_RUN = Path(__file__).parent / 'plain_rclpy_run.py'
#: A console format that shows each line's caller (the default one shows its wall time).
CONSOLE_FORMAT = '[{severity}] [{name}] {file_name}:{line_number} ({function_name}): {message}'
#: Wall seconds a live run of a 2 s node file gets.
LIVE_TIMEOUT_S = 60


def console_lines(lines: list[str]) -> list[tuple]:
    """Return each line as (severity, logger, file's name, line, function, text), or printed."""
    pattern = console_pattern(CONSOLE_FORMAT)
    said = []
    for line in lines:
        match = pattern.match(line)
        if match is None:
            said.append(('print', line))
        else:
            said.append((match['severity'], match['name'], Path(match['file_name']).name,
                         int(match['line_number']), match['function_name'], match['message']))
    return said


def live(tmp_path: Path, name: str) -> tuple[list[tuple], list[Twist]]:
    """Run the node file under plain rclpy; return its console lines and its /cmd_vel."""
    published = tmp_path / 'live.json'
    environment = dict(os.environ, RCUTILS_CONSOLE_OUTPUT_FORMAT=CONSOLE_FORMAT,
                       PYTHONUNBUFFERED='1', ROS_AUTOMATIC_DISCOVERY_RANGE='OFF')
    done = subprocess.run(
        [sys.executable, str(PLAIN_RUN), str(FIXTURES / name), str(published), '/cmd_vel',
         'geometry_msgs/msg/Twist'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, env=environment, timeout=LIVE_TIMEOUT_S)
    assert done.returncode == 0, done.stdout
    messages = [deserialize_message(bytes.fromhex(data), Twist)
                for data in json.loads(published.read_text())]
    return console_lines(done.stdout.splitlines()), messages


def stepped(tmp_path: Path, name: str) -> tuple[list[tuple], list[Twist]]:
    """
    Run the node file in a stepped run; return its console lines and its /cmd_vel.

    The run is a process of its own: rcutils reads RCUTILS_CONSOLE_OUTPUT_FORMAT once per
    process, so this test's format would otherwise be every later test's.
    """
    out = tmp_path / 'stepped'
    done = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.commands.run', '--world', 'obstacles', '--node',
         str(FIXTURES / name), '--duration', '6', '--out', str(out), '--quiet', '--no-plot'],
        capture_output=True, text=True, timeout=LIVE_TIMEOUT_S,
        env=dict(os.environ, RCUTILS_CONSOLE_OUTPUT_FORMAT=CONSOLE_FORMAT))
    assert done.returncode == 0, done.stderr
    assert json.loads((out / 'metrics.json').read_text())['node_errors'] == []
    entries = [json.loads(line) for line in (out / 'log.jsonl').read_text().splitlines()]
    with Reader(out / 'run') as bag:
        connections = [c for c in bag.connections if c.topic == '/cmd_vel']
        messages = [deserialize_message(data, Twist)
                    for _, _, data in bag.messages(connections=connections)]
    return console_lines([entry['line'] for entry in entries]), messages


@pytest.mark.parametrize('name', [
    'two_severities.py',   # rclpy.spin; the logger (every severity, once, throttle, skip_first)
    'sleep_and_rate.py',   # time.sleep, Rate.sleep, time.time/monotonic, a system-clock throttle
    'multithreaded.py',    # MultiThreadedExecutor, spin_until_future_complete
    'busy_poll_ticks.py',  # main() polling time.time() while a thread spins: paced
])
def test_a_node_says_and_publishes_the_same_live_and_stepped(tmp_path, name):
    live_lines, live_messages = live(tmp_path, name)
    stepped_lines, stepped_messages = stepped(tmp_path, name)
    assert len(live_messages) == 10 and len(live_lines) >= 5  # the file ran to its end
    assert stepped_lines == live_lines
    assert stepped_messages == live_messages
