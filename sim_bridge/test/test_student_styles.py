"""
Node files in the styles students write, each doing what its author meant on its own robot.

A TurtleBot3 avoider (360 beams, index 0 ahead) on the Burger; a node that publishes only when
its decision changes (the base keeps the last command, as Gazebo's DiffDrive does); a node on a
MultiThreadedExecutor, one made as a plain ``Node('...')`` in main(), and two nodes spun together
(each its own main(), stepped like every node file); an avoider derived from the course's helper
base class.
"""

import json
from pathlib import Path

import pytest
from sim_bridge.runner.run import run_simulation

FIXTURES = Path(__file__).parent / 'fixtures'


def test_a_turtlebot3_avoider_drives_and_avoids_on_the_burger(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'tb3_avoider.py')], duration_s=30.0,
                            robot='turtlebot3_burger', out_dir=tmp_path, quiet=True,
                            record=False, plot=False)
    metrics = result.metrics
    assert metrics['node_errors'] == [] and metrics['collisions'] == 0
    assert metrics['distance_m'] > 2.0          # not stuck: it went round the cube
    assert metrics['min_clearance_m'] < 0.5     # and it did meet it
    assert metrics['run_mode']['mode'] == 'stepped'


def test_a_node_that_publishes_only_on_change_drives_up_to_the_cube_and_stops(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'on_change_driver.py')],
                            duration_s=20.0, out_dir=tmp_path, quiet=True, record=False,
                            plot=False)
    metrics = result.metrics
    assert metrics['node_errors'] == [] and metrics['collisions'] == 0
    # Two commands in all (go, stop): the cube's face is 2.0 m ahead, the robot 0.15 m round.
    assert 1.0 < metrics['distance_m'] < 1.85
    assert metrics['max_stationary_s'] > 5.0


def test_a_node_on_a_multithreaded_executor_runs_its_main_and_drives(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'multithreaded_driver.py')],
                            duration_s=3.0, out_dir=tmp_path, quiet=True, plot=False)
    metrics = result.metrics
    assert metrics['run_mode']['mode'] == 'stepped'
    assert metrics['node_errors'] == [] and metrics['distance_m'] > 0.3


def test_an_avoider_on_a_helper_base_class_runs_the_class_main_constructs(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'helper_base_avoider.py')],
                            duration_s=30.0, out_dir=tmp_path, quiet=True, record=False,
                            plot=False)
    metrics = result.metrics
    assert metrics['run_mode']['mode'] == 'stepped'
    assert metrics['node_errors'] == [] and metrics['collisions'] == 0
    assert metrics['distance_m'] > 2.0 and len(metrics['turns_deg']) >= 1  # it turned away


@pytest.mark.parametrize('name', ['plain_node_in_function.py', 'two_nodes_in_main.py'])
def test_a_cautious_driver_in_main_drives_up_to_the_cube_and_stops(tmp_path, name, run_warnings):
    result = run_simulation('obstacles', [str(FIXTURES / name)], duration_s=12.0,
                            out_dir=tmp_path, quiet=True, record=False, plot=False)
    metrics = result.metrics
    assert metrics['run_mode']['mode'] == 'stepped'
    assert metrics['node_errors'] == [] and metrics['collisions'] == 0
    # The cube's face is 2.0 m ahead: it stops 0.6 m before it, and stays there; the two
    # nodes' own topic (gap_ahead) has both its ends, so nothing is warned of.
    assert 1.0 < metrics['distance_m'] < 1.85 and metrics['max_stationary_s'] > 2.0
    assert run_warnings(metrics['warnings']) == []


def test_a_node_spun_in_a_thread_handles_every_scan_before_main_goes_on(tmp_path):
    # main() loops on a Rate while a thread spins the node, whose callbacks take wall time:
    # each step is handled by the thread before the main thread says it is idle.
    result = run_simulation('obstacles', [str(FIXTURES / 'threaded_spinner.py')],
                            duration_s=5.0, out_dir=tmp_path, quiet=True, plot=False,
                            record=False)
    lines = [json.loads(line) for line in (tmp_path / 'log.jsonl').read_text().splitlines()]
    printed = [(line['t'], line['text']) for line in lines if line['level'] == 'STDOUT']
    assert result.metrics['node_errors'] == []
    assert printed == [(t / 2, f'handled {5 * t} scans') for t in range(1, 11)]


def test_the_construct_template_polling_the_clock_in_main_drives_up_to_the_cube(tmp_path):
    # main() polls time.time() with no sleep while a thread spins a MultiThreadedExecutor:
    # sim time follows the wall clock while it does, each scan handled by the thread.
    result = run_simulation('obstacles', [str(FIXTURES / 'busy_poll_template.py')],
                            duration_s=8.0, out_dir=tmp_path, quiet=True, record=False,
                            plot=False)
    metrics = result.metrics
    assert metrics['node_errors'] == [] and metrics['collisions'] == 0
    assert metrics['sim_time_s'] >= 8.0
    # The cube's face is 2.0 m ahead: it stops 0.6 m before it (0.25 m/s, one scan late).
    assert 1.0 < metrics['distance_m'] < 1.85 and metrics['max_stationary_s'] > 1.0
    assert any('sim time followed the wall clock' in note
               for note in metrics['run_mode']['notes'])
