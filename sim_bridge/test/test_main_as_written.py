"""
A node file runs as ``python3 FILE`` would run it: its own main(), in a process of its own.

Every style (a spin_once loop, a node made in a function, a sleeping callback, several nodes) is
stepped with the simulator (sim_bridge.runner.boundary.inside.agent): checked for doing what its
author meant. Which Node class a file of several runs is read from its source
(sim_bridge.runner.node_styles).
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap

import pytest
from rosbags.rosbag2 import Reader
from sim_bridge.commands.run import main
from sim_bridge.common.errors import RunError
from sim_bridge.runner.boundary.inside.node_main import prepare
from sim_bridge.runner.node_styles import node_class
from sim_bridge.runner.options import gui_problem
from sim_bridge.runner.run import run_simulation, STEPPED_REASON
from sim_bridge.runner.stepped_run import last_traceback, printed_error
from sim_bridge.runner.targets import load_node_class, TargetError

FIXTURES = Path(__file__).parent / 'fixtures'
LAB_NODES = sorted((Path(__file__).parents[2] / 'scan_pkg' / 'scan_pkg').glob('*.py'))

HEADER = """
import time
import rclpy
from rclpy.node import Node
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor


class Driver(Node):

    def __init__(self):
        super().__init__('driver')
        self.create_timer(0.1, self.on_timer)

    def on_timer(self):
        pass
"""


def source(main_body: str, header: str = HEADER) -> str:
    """Return a node file: ``header``, then ``main()`` with ``main_body`` and a __main__ block."""
    body = textwrap.indent(textwrap.dedent(main_body).strip(), '    ')
    return (f'{header}\n\ndef main(args=None):\n{body}\n\n\n'
            "if __name__ == '__main__':\n    main()\n")


def test_files_without_main_or_one_node_class():
    two = HEADER + '\n\nclass Other(Node):\n    pass\n'
    # main() says which of the two it runs.
    assert node_class(source('rclpy.init()\nrclpy.spin(Driver())', two)) == 'Driver'
    assert node_class(source('rclpy.init()\nrclpy.spin(make())', two)) is None


HELPER_BASE = HEADER.replace('class Driver(Node)', 'class Base(Node)').replace(
    "super().__init__('driver')", 'super().__init__(name)').replace(
    'def __init__(self):', 'def __init__(self, name):') + """

class Driver(Base):

    def __init__(self):
        super().__init__('driver')
"""


@pytest.mark.parametrize('main_body', ['rclpy.init()\nrclpy.spin(Driver())',
                                       'rclpy.init()\nrclpy.spin(make())'])
def test_a_helper_base_class_is_not_the_node_main_runs(main_body):
    # Constructed in main(), or not (a factory): the most derived class is the node.
    assert node_class(source(main_body, HELPER_BASE)) == 'Driver'
    assert node_class(HELPER_BASE) == 'Driver'  # no main(): the most derived class


def test_the_class_main_constructs_is_loaded_of_several(tmp_path):
    from rclpy.node import Node
    path = tmp_path / 'avoider.py'
    path.write_text(source('rclpy.init()\nrclpy.spin(Driver())', HELPER_BASE))
    assert load_node_class(str(path), Node).__name__ == 'Driver'
    unrelated = tmp_path / 'two.py'
    unrelated.write_text(source('rclpy.init()\nrclpy.spin(make())',
                                HEADER + '\n\nclass Other(Node):\n    pass\n'))
    with pytest.raises(TargetError, match='several: Driver, Other'):
        load_node_class(str(unrelated), Node)


def test_a_file_without_main_guard_runs_its_main_as_a_console_script():
    start, path = prepare(str(FIXTURES / 'function_node.py'))  # its module code runs here
    assert start.__name__ == 'main' and path == str(FIXTURES / 'function_node.py')


def run_file(tmp_path: Path, name: str, duration_s: float = 3.0, *options: str,
             status: int = 0, plot: bool = False) -> tuple[dict, str]:
    """Run a fixture with ``python -m sim_bridge.run``; return its metrics and console output."""
    done = subprocess.run(
        [sys.executable, '-m', 'sim_bridge.run', '--world', 'obstacles', '--node',
         str(FIXTURES / name), '--duration', str(duration_s), '--out', str(tmp_path / 'out'),
         *([] if plot else ['--no-plot']), *options],
        capture_output=True, text=True, timeout=120, env=dict(os.environ))
    assert done.returncode == status, done.stderr
    metrics = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    return metrics, done.stdout + done.stderr


def test_a_node_drawing_unseeded_random_numbers_does_the_same_at_every_run(tmp_path):
    # As the handout's wanderbot: random.uniform never seeded, a set iterated. Two gradings of
    # one file give one set of marks.
    printed = []
    for run in ('first', 'second'):
        (tmp_path / run).mkdir()
        run_file(tmp_path / run, 'random_turner.py', 2.0)
        lines = (tmp_path / run / 'out' / 'log.jsonl').read_text().splitlines()
        printed.append([json.loads(line)['text'] for line in lines
                        if json.loads(line).get('text', '').startswith('drew ')])
    assert len(printed[0]) == 4 and printed[0] == printed[1]


def test_a_main_loop_that_yields_with_sleep_0_reaches_its_second(tmp_path):
    # Each time.sleep(0) waits for the simulator's next step (as any sleep, to the step at or
    # after its end): the loop runs at the simulator's pace and ends, never stuck at 0 s.
    metrics, console = run_file(tmp_path, 'yielding_loop.py', 5.0)
    assert metrics['node_errors'] == [] and 'drove for 1.0 s' in console
    assert metrics['sim_time_s'] == pytest.approx(1.0, abs=0.05)


@pytest.mark.parametrize('name, printed', [
    ('spin_once_loop.py', 'loop driver started'),
    ('function_node.py', 'mover is moving'),
    ('sleepy_timer.py', 'sent a command, now resting'),
])
def test_every_style_runs_its_own_main_stepped_and_drives(tmp_path, name, printed):
    metrics, console = run_file(tmp_path, name)
    assert metrics['run_mode']['mode'] == 'stepped'
    assert metrics['distance_m'] > 0.3
    assert metrics['sim_time_s'] >= 3.0
    assert printed in console
    with Reader(tmp_path / 'out' / 'run') as bag:  # the recording, as a stepped run's
        counts = {connection.topic: connection.msgcount for connection in bag.connections}
    assert counts['/cmd_vel'] > 0 and counts['/scan'] > 0  # the node's, over DDS; the bridge's
    assert 'run mode' in console and 'stepped (' in console


def test_a_stepped_run_says_so(tmp_path):
    metrics, console = run_file(tmp_path, 'quitter.py', 1.0)
    isolation = metrics['run_mode'].pop('sandbox')  # how its node was isolated
    assert metrics['run_mode'] == {'mode': 'stepped', 'reason': STEPPED_REASON}
    assert isolation.startswith(('bubblewrap', 'PARTLY sandboxed', 'NOT sandboxed'))


def test_node_files_of_any_style_run_together_each_in_its_process(tmp_path):
    result = run_simulation('obstacles', ['scan_ahead', str(FIXTURES / 'spin_once_loop.py')],
                            duration_s=2.0, out_dir=tmp_path / 'out', quiet=True, plot=False)
    assert result.metrics['node_errors'] == [] and result.metrics['distance_m'] > 0.1
    lines = (tmp_path / 'out' / 'log.jsonl').read_text()
    assert 'loop driver started' in lines and 'scan_ahead' in lines


def test_a_run_reports_its_progress_in_simulated_time(tmp_path):
    seen = []
    result = run_simulation('obstacles', [str(FIXTURES / 'function_node.py')], duration_s=2.0,
                            out_dir=tmp_path / 'out', quiet=True, plot=False,
                            progress=lambda sim_s, duration_s: seen.append((sim_s, duration_s)))
    assert result.ok
    assert seen == sorted(seen) and seen[-1] == (2.0, 2.0)  # the grader's stall watch sees it


def test_ctrl_c_stops_a_run_and_writes_its_outputs(tmp_path):
    runner = subprocess.Popen(
        [sys.executable, '-m', 'sim_bridge.run', '--world', 'obstacles', '--node',
         str(FIXTURES / 'threaded_counting_logger.py'), '--duration', '600', '--out',
         str(tmp_path / 'out'), '--no-plot'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    try:
        for line in runner.stdout:  # its node printed at 1 s: simulated time runs
            if 'printed count 1' in line:
                break
        runner.send_signal(signal.SIGINT)
        _, stderr = runner.communicate(timeout=60)
    finally:
        runner.kill()
    assert runner.returncode == 130, stderr
    assert 'its outputs are in' in stderr
    metrics = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert metrics['sim_time_s'] < 600


def test_a_run_names_the_topics_nothing_is_at_the_other_end_of(tmp_path, run_warnings):
    metrics, console = run_file(tmp_path, 'namespaced_loop.py', 2.0, '--no-record')
    warnings = [
        'cruiser subscribes to /robot/scan: nothing publishes it (the simulator publishes '
        '/scan: --remap /robot/scan:=/scan)',
        'cruiser publishes /robot/cmd_vel: nothing subscribes to it (the simulator subscribes '
        'to /cmd_vel: --remap /robot/cmd_vel:=/cmd_vel)']
    assert run_warnings(metrics['warnings']) == warnings and metrics['distance_m'] == 0.0
    assert all(f'warning: {warning}' in console for warning in warnings)
    # The rules it names connect it: it drives, and nothing is left to warn of.
    metrics, _ = run_file(tmp_path, 'namespaced_loop.py', 3.0, '--no-record', '--remap',
                          '/robot/scan:=/scan', '--remap', '/robot/cmd_vel:=/cmd_vel')
    assert run_warnings(metrics['warnings']) == [] and metrics['distance_m'] > 0.3


def test_gui_without_a_display_is_refused_in_one_line_before_anything_starts(
        tmp_path, monkeypatch):
    assert gui_problem({}, 'linux').startswith('--gui needs a display, and DISPLAY is not set')
    assert gui_problem({'DISPLAY': ':0'}, 'linux') is None
    assert gui_problem({}, 'darwin') is None  # pybullet's window is not X11's there
    monkeypatch.delenv('DISPLAY', raising=False)
    for node in ('scan_ahead', str(FIXTURES / 'function_node.py')):
        with pytest.raises(RunError, match='--gui needs a display'):
            run_simulation('obstacles', [node], duration_s=1.0, gui=True,
                           out_dir=tmp_path / 'out')
    assert not (tmp_path / 'out').exists()


def test_an_error_in_a_main_loop_is_reported_at_the_nodes_deepest_line(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'loop_random_turn.py')],
                            duration_s=20.0, out_dir=tmp_path, quiet=True, record=False,
                            plot=False)
    [error] = result.metrics['node_errors']
    path = (FIXTURES / 'loop_random_turn.py').resolve()
    # random.choice raised it; the student's call of it is the line to fix.
    assert error['error'].endswith(
        f'IndexError: Cannot choose from an empty sequence at {path}:22: '
        'return random.choice(allowed)')
    assert error['error'].startswith("node 'wanderer' raised IndexError")
    lines = error['traceback'].splitlines()
    assert [line for line in lines if line.startswith('  File ')][-1] == (
        f'  File "{path}", line 22, in pick_turn')
    assert lines[-1] == 'IndexError: Cannot choose from an empty sequence'
    assert 'random.py' not in error['traceback'] and 'runpy' not in error['traceback']
    assert result.metrics['distance_m'] > 0.3  # it drove up to the cube first


def test_a_ros_module_missing_in_a_node_file_says_where_it_comes_from(tmp_path, monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    with pytest.raises(RunError) as raised:  # at import: the run cannot start
        run_simulation('obstacles', [str(FIXTURES / 'tf_yaw_loop.py')], duration_s=3.0,
                       out_dir=tmp_path, quiet=True, record=False, plot=False)
    error = {'error': str(raised.value)}
    path = FIXTURES / 'tf_yaw_loop.py'
    assert (f"ModuleNotFoundError: No module named 'tf_transformations' at {path}:5: from "
            'tf_transformations import euler_from_quaternion (tf_transformations comes with a '
            'ROS 2 Jazzy installation (apt package ros-jazzy-tf-transformations), not with the '
            'ROS wheels from PyPI; for Euler angles and quaternions PyPI has transforms3d'
            ) in error['error']


def test_a_node_that_ends_itself_in_its_main_loop_ends_the_run_with_every_output(
        tmp_path, run_warnings):
    metrics, console = run_file(tmp_path, 'timed_drive_loop.py', 20.0, plot=True)
    assert metrics['node_errors'] == []
    assert metrics['ended_by'] == (
        "node 'timed_drive_loop' shut ROS down (rclpy.shutdown()) in its main() at "
        f"{FIXTURES / 'timed_drive_loop.py'}:25: rclpy.shutdown()")
    assert run_warnings(metrics['warnings']) == [
        f"{metrics['ended_by']}: the run ended at 2 s of its 20 s"]
    assert metrics['sim_time_s'] == pytest.approx(2.0)  # its 2 s of driving, exactly
    assert 'done driving' in console
    out = tmp_path / 'out'
    assert (out / 'params.yaml').is_file() and (out / 'trajectory.png').stat().st_size > 0
    with Reader(out / 'run') as bag:
        assert {connection.topic for connection in bag.connections} >= {'/clock', '/scan'}


def test_the_last_traceback_a_node_process_sent_is_read_with_its_code_lines():
    printed = textwrap.dedent("""\
        [INFO] [1795615054.7] [wanderer]: up
        Traceback (most recent call last):
          File "/lab/a.py", line 3, in on_scan
            x = msg.ranges[400]
                ~~~~~~~~~~^^^^^
        IndexError: tuple index out of range

        During handling of the above exception, another exception occurred:

        Traceback (most recent call last):
          File "/lab/a.py", line 9, in main
            rclpy.spin(node)
          File "/venv/rclpy/executors.py", line 5, in spin
            raise error
        KeyError: 'x'
        """).splitlines()
    frames, error = last_traceback(printed)
    assert [(f.filename, f.lineno, f.name, f.line) for f in frames] == [
        ('/lab/a.py', 9, 'main', 'rclpy.spin(node)'),
        ('/venv/rclpy/executors.py', 5, 'spin', 'raise error')]
    assert error == "KeyError: 'x'"
    assert last_traceback(['[INFO] nothing went wrong']) is None
    missing = printed_error("ModuleNotFoundError: No module named 'tf2_ros.buffer'")
    assert isinstance(missing, ModuleNotFoundError) and missing.name == 'tf2_ros.buffer'
    assert printed_error("KeyError: 'x'") is None


def test_ros_args_after_the_target_reach_a_stepped_node_unchanged(tmp_path, capsys):
    status = main(['--world', 'obstacles', '--node', str(FIXTURES / 'quitter.py'), '--duration',
                   '5', '--quiet', '--no-plot', '--no-record', '--out', str(tmp_path),
                   '--ros-args', '-p', 'drive_time:=0.5'])
    assert status == 0
    metrics = json.loads((tmp_path / 'metrics.json').read_text())
    assert metrics['sim_time_s'] < 1.0 and 'quitter' in metrics['ended_by']  # not its 1.0 s
    status = main(['--world', 'obstacles', '--node', 'scan_ahead', '--out', str(tmp_path / 'x'),
                   '--ros-args', '-r', 'bad'])
    assert status == 2
    assert capsys.readouterr().err.endswith(
        "error: rcl cannot read the nodes' arguments: Couldn't parse remap rule: '-r bad'\n")


def test_ros_args_after_the_target_reach_a_main_loop_unchanged(tmp_path, run_warnings):
    metrics, _ = run_file(tmp_path, 'namespaced_loop.py', 3.0, '--no-record', '--ros-args',
                          '-r', '/robot/scan:=/scan', '-r', '/robot/cmd_vel:=/cmd_vel')
    assert run_warnings(metrics['warnings']) == [] and metrics['distance_m'] > 0.3


def test_a_class_of_both_styles_is_graded_each_run_in_its_child(tmp_path):
    from sim_bridge.grading.batch import format_table, grade_runs
    from sim_bridge.grading.runs import GradeJob
    from sim_bridge.grading.scenario import scenario_from_dict
    base = {'world': 'obstacles', 'duration': 4.0, 'seed': 1,
            'criteria': ['len(node_errors) == 0', 'collisions == 0', 'distance_m > 0.3']}
    process = scenario_from_dict({**base, 'nodes': [str(FIXTURES / 'namespaced_loop.py')],
                                  'remap': ['/robot/scan:=/scan', '/robot/cmd_vel:=/cmd_vel']},
                                 'cruiser')
    stepped = scenario_from_dict({**base, 'nodes': [str(FIXTURES / 'helper_base_avoider.py')]},
                                 'avoider')
    unwired = scenario_from_dict({**base, 'nodes': [str(FIXTURES / 'namespaced_loop.py')]},
                                 'unwired')
    jobs = [GradeJob(run, tmp_path / run.name) for each in (process, stepped, unwired)
            for run in each.runs()]
    reports = grade_runs(jobs, workers=2, quiet=True, record=False, plot=False)
    assert [report.passed for report in reports] == [True, True, False], [
        report.error or report.metrics for report in reports]
    assert [report.metrics['run_mode']['mode'] for report in reports] == ['stepped'] * 3
    # The report says why the unwired one did not move, and how to wire it.
    warning = ('cruiser subscribes to /robot/scan: nothing publishes it (the simulator '
               'publishes /scan: --remap /robot/scan:=/scan)')
    assert warning in reports[2].metrics['warnings']
    assert warning in format_table(reports)


def test_turtlebot3_scan_code_in_a_main_loop_gets_the_scans_geometry(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'tb3_loop.py')], duration_s=3.0,
                            out_dir=tmp_path / 'lab', quiet=True, record=False, plot=False)
    [error] = result.metrics['node_errors']
    path = (FIXTURES / 'tb3_loop.py').resolve()
    assert error['error'].endswith(
        f'IndexError: array index out of range at {path}:26: left = latest.ranges[90] (this '
        'scan has 36 ranges from -1.57 rad (index 0, right) to +1.57 rad (index 35, left); '
        '`--robot turtlebot3_burger` has 360 ranges from 0 rad (index 0, ahead) to +6.28 rad '
        '(index 359, ahead))')
    # On the robot it was written for, it drives.
    result = run_simulation('obstacles', [str(FIXTURES / 'tb3_loop.py')], duration_s=3.0,
                            robot='turtlebot3_burger', out_dir=tmp_path / 'burger', quiet=True,
                            record=False, plot=False)
    assert result.metrics['node_errors'] == [] and result.metrics['distance_m'] > 0.2


def test_a_parameter_a_main_loops_node_does_not_declare_is_a_warning(tmp_path, run_warnings):
    remaps = ('--remap', '/robot/scan:=/scan', '--remap', '/robot/cmd_vel:=/cmd_vel')
    metrics, _ = run_file(tmp_path, 'namespaced_loop.py', 3.0, '--no-record', *remaps,
                          '--param', 'cruiser:speed=0.2', '--param', 'cruiser:sped=0.2',
                          '--param', 'ghost:speed=0.2')
    # Read from the node's process, as `ros2 param list` would list them.
    assert run_warnings(metrics['warnings']) == [
        'parameters given for node(s) ghost, but the nodes are sim_bridge, cruiser; they were '
        'ignored',
        "node 'cruiser' did not declare parameter 'sped' (given by --param or the params "
        'file); it was ignored']
    assert 0.1 < metrics['distance_m'] < 0.65  # 3 s at 0.2 m/s at most, not its 0.3 m/s


def test_a_run_measures_the_wall_distance_against_the_nodes_own_distance(tmp_path, run_warnings):
    # No setpoint given: the node's `distance` parameter, as its process says it is.
    from scan_pkg import wall_follow
    result = run_simulation('wall_follow_box', [wall_follow.__file__], duration_s=3.0, seed=1,
                            params={'wall_follow': {'distance': 0.6}}, out_dir=tmp_path,
                            quiet=True, record=False, plot=False)
    assert result.metrics['node_errors'] == [] and run_warnings(result.metrics['warnings']) == []
    assert result.metrics['wall_distance_m']['setpoint'] == 0.6


def test_a_process_forked_after_a_run_can_collect_its_garbage(tmp_path):
    # A multiprocessing pool forked later (ament_flake8's, under colcon test) crashed in its
    # first garbage collection, freeing the run's rclpy objects without their DDS threads.
    import gc
    run_simulation('obstacles', [str(FIXTURES / 'spin_once_loop.py')], duration_s=1.0,
                   out_dir=tmp_path, quiet=True, record=False, plot=False)
    child = os.fork()
    if child == 0:
        gc.collect()
        os._exit(0)
    _, status = os.waitpid(child, 0)
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, (
        f'the forked process ended with status {status}')


def test_a_turtlebot3_node_publishing_twist_stamped_drives_the_robot(tmp_path):
    # TurtleBot3's Jazzy packages publish TwistStamped on /cmd_vel; the node runs in the
    # runner's process, beside the bridge, and starts without an incompatible-type error.
    result = run_simulation('obstacles', [str(FIXTURES / 'tb3_stamped_driver.py')],
                            duration_s=3.0, robot='turtlebot3_burger', out_dir=tmp_path,
                            quiet=True, record=True, plot=False)
    assert result.metrics['node_errors'] == []
    assert result.metrics['distance_m'] == pytest.approx(0.1 * 2.9, abs=0.03)
    with Reader(tmp_path / 'run') as reader:
        (connection,) = [c for c in reader.connections if c.topic == '/cmd_vel']
        assert connection.msgtype == 'geometry_msgs/msg/TwistStamped'
        assert connection.msgcount >= 25


def test_two_nodes_publishing_both_command_types_get_a_hint(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'tb3_stamped_driver.py'),
                                          str(FIXTURES / 'on_change_driver.py')],
                            duration_s=1.0, robot='turtlebot3_burger', out_dir=tmp_path,
                            quiet=True, record=False, plot=False)
    [error] = result.metrics['node_errors']
    assert error['error'].endswith(
        '(another node of this run already uses /cmd_vel with another type than '
        'geometry_msgs/msg/Twist: every node of a run must use one type on a topic)')


def test_a_spin_once_loop_of_a_twist_stamped_node_drives_the_robot(tmp_path):
    # The node's process says its nodes publish TwistStamped; the bridge follows the publisher
    # it finds on the graph; the recording follows too.
    metrics, _ = run_file(tmp_path, 'stamped_loop.py')
    assert metrics['run_mode']['mode'] == 'stepped'
    assert metrics['node_errors'] == [] and metrics['distance_m'] > 0.2
    with Reader(tmp_path / 'out' / 'run') as bag:
        (connection,) = [c for c in bag.connections if c.topic == '/cmd_vel']
        assert connection.msgtype == 'geometry_msgs/msg/TwistStamped'
