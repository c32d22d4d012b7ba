"""
The trusted side bounded against any frame: what a node process says cannot crash or bloat it.

Each attack is a hostile node of fixtures/hostile: a graph of 20,000 topics, LaserScan bytes
declared on /cmd_vel, commands stamped with a frame_id of megabytes. Each fails its own run
with one line naming the node (or topic) and the cap; the trusted process goes on.
"""

from pathlib import Path
import re

import pytest
from sim_bridge.runner.boundary.outside import boundary_checks
from sim_bridge.runner.boundary.outside.boundary_checks import checked_graph, Refused
from sim_bridge.runner.run import run_simulation

FIXTURES = Path(__file__).parent / 'fixtures'
HOSTILE = FIXTURES / 'hostile'


def run(tmp_path, node, duration_s=1.0, **kwargs):
    return run_simulation('obstacles', [str(node)], duration_s=duration_s, out_dir=tmp_path,
                          quiet=True, plot=False, **kwargs).metrics


def node_entry(name='n', publishes=(), parameters=()):
    return {'name': name, 'namespace': '/', 'publishes': [list(p) for p in publishes],
            'subscribes': [], 'parameters': list(parameters), 'values': {}}


def test_a_graph_of_twenty_thousand_topics_fails_its_run_with_the_cap(tmp_path):
    metrics = run(tmp_path, HOSTILE / 'long_graph.py', record=False)
    [error] = metrics['node_errors']
    assert "node 'long_graph' publishes or subscribes to 20000 topics: over the cap of " \
        f'{boundary_checks.MAX_TOPICS_PER_NODE} topics per node' in error['error']
    assert '\n' not in error['error']


def test_laserscan_bytes_declared_on_cmd_vel_are_the_nodes_error(tmp_path):
    # Its neighbour publishes Twist on /cmd_vel: rcl refuses a second type on the topic.
    metrics = run_simulation('obstacles', [str(FIXTURES / 'spin_once_loop.py'),
                                           str(HOSTILE / 'type_clash.py')],
                             duration_s=1.0, out_dir=tmp_path, quiet=True, plot=False,
                             record=False).metrics
    [error] = metrics['node_errors']
    assert 'uses /cmd_vel as sensor_msgs/msg/LaserScan' in error['error']
    assert '\n' not in error['error']


def test_messages_on_topics_never_declared_stop_at_the_cap_of_topics(tmp_path):
    metrics = run(tmp_path, HOSTILE / 'many_topics.py', record=False)
    [error] = metrics['node_errors']
    # /clock, which it hears, is one of its topics too
    assert re.fullmatch(r'many_topics: at 0 s of sim time, the node process uses /topic_\d+ '
                        f'beyond the cap of {boundary_checks.MAX_TOPICS} topics per process',
                        error['error'])


def test_a_command_of_megabytes_is_refused_and_never_recorded(tmp_path):
    metrics = run(tmp_path, HOSTILE / 'long_frame_id.py', duration_s=2.0)
    [error] = metrics['node_errors']
    assert ('geometry_msgs/msg/TwistStamped of 9437' in error['error']
            and f'over the cap of {boundary_checks.MAX_MESSAGE_BYTES} bytes per message'
            in error['error'])
    assert (tmp_path / 'run' / 'run_0.mcap').stat().st_size < 2 ** 20


def test_a_string_over_its_cap_is_named_by_its_field(tmp_path):
    metrics = run(tmp_path, HOSTILE / 'long_frame_id.py',
                  params={'padder': {'frame_id_bytes': 100_000}})
    [error] = metrics['node_errors']
    assert ('/cmd_vel whose header.frame_id holds 100000 characters: over the cap of '
            f'{boundary_checks.MAX_STRING_BYTES} characters') in error['error']


@pytest.mark.parametrize('graph, refusal', [
    ([node_entry(f'n{index}') for index in range(101)], 'lists 101 nodes: over the cap of 100'),
    ([node_entry(parameters=[f'p{index}' for index in range(1001)])],
     "node 'n' declares 1001 parameters: over the cap of 1000"),
    ([node_entry('x' * 300)], 'has a name of 300 characters: over the cap of 256'),
    ([node_entry(parameters=['p' * 257])],
     "node 'n' has a parameter name of 257 characters: over the cap of 256"),
    ([node_entry(f'n{index}', [(f'/t{index}_{each}', 'std_msgs/msg/String')
                               for each in range(90)]) for index in range(3)],
     "node 'n2' brings its process's topics to 270: over the cap of 200 topics per process"),
])
def test_each_cap_of_a_graph_is_refused_in_one_line_naming_the_node(graph, refusal):
    with pytest.raises(Refused) as refused:
        checked_graph(graph)
    assert refusal in str(refused.value) and '\n' not in str(refused.value)


def test_a_graph_within_the_caps_is_kept_whole():
    graph = [node_entry(f'n{index}', [(f'/t{index}', 'std_msgs/msg/String')], ['rate'])
             for index in range(100)]
    assert [entry['name'] for entry in checked_graph(graph)] == [f'n{i}' for i in range(100)]
