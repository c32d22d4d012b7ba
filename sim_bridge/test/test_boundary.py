"""
The trust boundary: a run's nodes execute in a process of their own, the simulator never does.

Each hostile node of fixtures/hostile is contained: it forges nothing, a pickle or garbage on
every file descriptor it has fails its own run with a reason, a callback that never returns
ends its run within the limit, a flood of output is capped. Runs stay deterministic.
"""

import json
from pathlib import Path
import subprocess
import sys

from geometry_msgs.msg import TwistStamped
from mcap.reader import make_reader
import pytest
from rcl_interfaces.msg import Log
from rclpy.serialization import deserialize_message, serialize_message
from sim_bridge.runner import outputs, stepped_run, stepping
from sim_bridge.runner.boundary.outside import link
from sim_bridge.runner.run import run_simulation

FIXTURES = Path(__file__).parent / 'fixtures'
HOSTILE = FIXTURES / 'hostile'
#: Modules of the trusted side: none may be loaded in a node's process.
TRUSTED_MODULES = ('sim_bridge.simulation', 'sim_bridge.scoring', 'sim_bridge.grading',
                   'sim_bridge.ros', 'sim_bridge.runner.run', 'sim_bridge.runner.stepped_run',
                   'sim_bridge.runner.boundary.outside', 'pybullet', 'scan_pkg')


def run(tmp_path, node, duration_s=3.0, **kwargs):
    return run_simulation('obstacles', [str(node)], duration_s=duration_s, out_dir=tmp_path,
                          quiet=True, plot=False, **kwargs).metrics


def test_a_node_process_loads_nothing_of_the_simulator_or_the_grader(tmp_path):
    node = tmp_path / 'modules.py'
    node.write_text(
        'import sys\nimport rclpy\nfrom rclpy.node import Node\n\n\n'
        'def main():\n    rclpy.init()\n    node = Node("modules")\n'
        '    print(" ".join(sorted(sys.modules)))\n    rclpy.spin(node)\n')
    metrics = run(tmp_path / 'out', node, duration_s=0.5, record=False)
    log = (tmp_path / 'out' / 'log.jsonl').read_text()
    modules = json.loads(log.splitlines()[0])['text'].split()
    assert metrics['node_errors'] == [] and 'rclpy' in modules
    assert [m for m in modules if m in TRUSTED_MODULES
            or m.startswith(tuple(f'{name}.' for name in TRUSTED_MODULES))] == []


def test_a_node_that_patches_the_scoring_and_rewrites_results_forges_nothing(tmp_path,
                                                                             monkeypatch):
    monkeypatch.chdir(tmp_path)
    metrics = run(tmp_path / 'out', HOSTILE / 'forger.py')
    assert metrics['distance_m'] < 0.01 and metrics['node_errors'] == []
    written = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert written['distance_m'] < 0.01


def test_a_pickle_and_garbage_on_every_fd_fail_that_run_only(tmp_path):
    marker = tmp_path / 'pwned'
    metrics = run(tmp_path / 'out', HOSTILE / 'fd_spray.py',
                  params={'sprayer': {'marker': str(marker)}})
    assert not marker.exists()
    [error] = metrics['node_errors']
    assert 'malformed frame' in error['error'] and metrics['sim_time_s'] == pytest.approx(1.0)
    with open(tmp_path / 'out' / 'run' / 'run_0.mcap', 'rb') as bag:  # the recording is whole
        assert any(channel.topic == '/scan'
                   for _, channel, _ in make_reader(bag).iter_messages())
    honest = run(tmp_path / 'honest', FIXTURES / 'spin_once_loop.py')
    assert honest['node_errors'] == [] and honest['distance_m'] > 0.1


def test_bytes_after_a_message_never_reach_the_runners_side_or_the_bag(tmp_path):
    # What is republished is the message rclpy read from the bytes, not the bytes.
    metrics = run(tmp_path, HOSTILE / 'padded_commands.py', duration_s=1.0)
    with (tmp_path / 'run' / 'run_0.mcap').open('rb') as bag:
        commands = [message.data for _, channel, message in make_reader(bag).iter_messages()
                    if channel.topic == '/cmd_vel']
    assert metrics['node_errors'] == [] and metrics['distance_m'] > 0.05
    command = deserialize_message(commands[0], TwistStamped)
    assert len(commands) >= 9 and command.twist.linear.x == 0.2
    assert {len(data) for data in commands} == {len(serialize_message(command))}


def test_a_callback_that_never_returns_ends_its_run_with_the_line(tmp_path, monkeypatch):
    monkeypatch.setattr(link, 'EXCHANGE_TIMEOUT_S', 2.0)
    metrics = run(tmp_path, HOSTILE / 'stuck.py', record=False)
    [error] = metrics['node_errors']
    assert error['error'] == ("no reply for 2 s: node 'stuck' did not return from its timer "
                              f"callback at {HOSTILE / 'stuck.py'}:14: while True:")


def test_a_flood_of_output_is_capped(tmp_path, monkeypatch):
    monkeypatch.setattr(link, 'OUTPUT_CAP_BYTES', 2 ** 20)
    metrics = run(tmp_path, HOSTILE / 'flood.py', duration_s=1.0, record=False,
                  params={'flood': {'mib': 1}})  # 10 MiB printed; each line kept twice
    assert (tmp_path / 'log.jsonl').stat().st_size < 3 * 2 ** 20
    assert any('bytes of output' in warning for warning in metrics['warnings'])


def test_the_same_seed_gives_the_same_messages_and_metrics(tmp_path):
    runs = []
    for name in ('a', 'b'):
        metrics = run(tmp_path / name, FIXTURES / 'spin_once_loop.py', duration_s=5.0, seed=3)
        with open(tmp_path / name / 'run' / 'run_0.mcap', 'rb') as bag:
            # /rosout carries the wall-clock stamp rcl gives a line: its text, not its bytes.
            messages = [(channel.topic, message.log_time,
                         deserialize_message(message.data, Log).msg
                         if channel.topic == '/rosout' else message.data)
                        for _, channel, message in make_reader(bag).iter_messages()]
        for varying in ('wall_time_s', 'real_time_factor'):
            metrics.pop(varying)
        runs.append((metrics, messages))
    assert runs[0] == runs[1]
    assert any(topic == '/cmd_vel' for topic, *_ in runs[0][1])


def test_the_runners_executor_spins_only_for_what_the_node_process_sent(tmp_path,
                                                                        monkeypatch):
    # No node of the runner's hears the scans and /clock (the node process's taps are not on
    # its executor): a step that sent them makes no wait there, only the node's commands do.
    counts = {'spins': 0, 'answered': 0, 'after_publishing': 0}
    spin, exchange = stepped_run.spin_until_idle, link.Agent.exchange
    after_publishing = stepped_run.spin_after_publishing

    def counted_spin(executor):
        counts['spins'] += 1
        return spin(executor)

    def counted_after_publishing(executor, topics):
        counts['after_publishing'] += 1
        assert topics == {'/cmd_vel'}
        return after_publishing(executor, topics)

    def counted_exchange(agent, *args):
        published = exchange(agent, *args)
        counts['answered'] += bool(published)
        return published
    monkeypatch.setattr(stepped_run, 'spin_until_idle', counted_spin)
    monkeypatch.setattr(stepped_run, 'spin_after_publishing', counted_after_publishing)
    monkeypatch.setattr(link.Agent, 'exchange', counted_exchange)
    metrics = run(tmp_path, FIXTURES / 'spin_once_loop.py', duration_s=2.0)
    assert metrics['node_errors'] == [] and counts['answered'] >= 10
    assert counts['after_publishing'] == counts['answered']
    assert counts['spins'] == 1  # the one before the first step


def test_the_runners_own_subscriptions_take_the_nodes_commands_and_leave_nothing_ready(
        tmp_path, monkeypatch):
    # After a republish the bridge and the recorder (sinks) take the command from their
    # subscriptions, with no wait: a wait made after them in a real run finds nothing ready.
    found = []
    after_publishing = stepped_run.spin_after_publishing

    def checked(executor, topics):
        ran = after_publishing(executor, topics)
        found.append((ran, stepping.spin_until_idle(executor)))
        return ran
    monkeypatch.setattr(stepped_run, 'spin_after_publishing', checked)
    metrics = run(tmp_path, FIXTURES / 'spin_once_loop.py', duration_s=2.0)
    assert metrics['node_errors'] == [] and metrics['distance_m'] > 0.1
    # each command twice (the bridge's callback and the recorder's), then nothing ready
    assert len(found) >= 10 and all(ran >= 2 and ran % 2 == 0 and left == 0
                                    for ran, left in found)


def test_the_recording_is_written_while_the_node_process_handles_its_step(
        tmp_path, monkeypatch):
    # The bag's writes are the trusted side's work the node's turn can hide (a second CPU).
    state = {'handling': False, 'written_then': 0, 'written': 0}
    exchange, write = link.Agent.exchange, outputs.BagRecorder.write

    def noted_exchange(agent, *args):
        state['handling'] = True
        try:
            return exchange(agent, *args)
        finally:
            state['handling'] = False

    def noted_write(bag, *args):
        state['written'] += 1
        state['written_then'] += state['handling']
        return write(bag, *args)
    monkeypatch.setattr(link.Agent, 'exchange', noted_exchange)
    monkeypatch.setattr(outputs.BagRecorder, 'write', noted_write)
    metrics = run(tmp_path, FIXTURES / 'spin_once_loop.py', duration_s=2.0)
    assert metrics['node_errors'] == [] and state['written'] > 100
    assert state['written_then'] > 0.9 * state['written']
    with (tmp_path / 'run' / 'run_0.mcap').open('rb') as bag:
        scans = [message for _, channel, message in make_reader(bag).iter_messages()
                 if channel.topic == '/scan']
    assert len(scans) == 20  # 2 s at 10 Hz: every scan sent is in the bag


ODOM_NODE = """
import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node


def main():
    rclpy.init()
    node = Node('circler')
    if {hears}:
        node.create_subscription(Odometry, 'odom', lambda msg: None, 10)
    pub = node.create_publisher(Twist, 'cmd_vel', 10)
    command = Twist()
    command.linear.x, command.angular.z = 0.2, 0.4
    node.create_timer(0.1, lambda: pub.publish(command))
    rclpy.spin(node)
"""


def test_odometry_no_node_hears_is_recorded_as_the_odometry_a_node_hears(tmp_path):
    # Odometry with no subscription is not published; the bag holds the same bytes.
    recorded = []
    for hears in (True, False):
        node = tmp_path / f'circler_{hears}.py'
        node.write_text(ODOM_NODE.format(hears=hears))
        metrics = run(tmp_path / str(hears), node, duration_s=2.0)
        assert metrics['node_errors'] == [] and metrics['distance_m'] > 0.2
        with (tmp_path / str(hears) / 'run' / 'run_0.mcap').open('rb') as bag:
            recorded.append([(message.log_time, message.data) for _, channel, message
                             in make_reader(bag).iter_messages() if channel.topic == '/odom'])
    assert len(recorded[0]) >= 99 and recorded[0] == recorded[1]


def test_lines_are_stamped_with_the_sim_time_and_node_of_the_code_that_wrote_them(tmp_path):
    run(tmp_path, FIXTURES / 'threaded_counting_logger.py', duration_s=3.5, record=False)
    lines = [json.loads(line) for line in (tmp_path / 'log.jsonl').read_text().splitlines()]
    printed = [(line['t'], line['node'], line['text']) for line in lines
               if line['level'] == 'STDOUT']
    assert printed == [(1.0, 'threaded_counter', 'printed count 1'),
                       (2.0, 'threaded_counter', 'printed count 2'),
                       (3.0, 'threaded_counter', 'printed count 3')]
    assert [line['t'] for line in lines if line['level'] == 'INFO'] == [1.0, 2.0, 3.0]


def test_the_agent_is_a_module_of_its_own(tmp_path):
    agent = 'sim_bridge.runner.boundary.inside.agent'
    result = subprocess.run([sys.executable, '-m', agent, '--help'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and '--in' in result.stdout
