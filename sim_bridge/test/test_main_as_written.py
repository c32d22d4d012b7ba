"""
A node file runs as ``python3 FILE`` would run it: stepped when its main() allows, else as written.

The decision (sim_bridge.runner.node_styles) is read from the source alone; the runs of the files
it sends to a process (their own main(), against the simulator run live, each on a ROS domain of
its own) are checked for doing what their authors meant.
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
from sim_bridge.runner.node_styles import decide, node_class
from sim_bridge.runner.options import gui_problem
from sim_bridge.runner.process_run import (
    DOMAIN_BASE, DOMAIN_COUNT, DomainReservation, last_traceback, node_spec, printed_error)
from sim_bridge.runner.run import run_simulation
from sim_bridge.runner.targets import load_node_class, run_mode, TargetError

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


@pytest.mark.parametrize('main_body', [
    'rclpy.init(args=args)\nrclpy.spin(Driver())',
    'rclpy.init(args=args)\nnode = Driver()\nrclpy.spin(node)\nnode.destroy_node()\n'
    'rclpy.shutdown()',
    'rclpy.init(args=args)\nnode = Driver()\ntry:\n    rclpy.spin(node)\n'
    'except KeyboardInterrupt:\n    pass\nfinally:\n    node.destroy_node()\n'
    '    rclpy.try_shutdown()',
    'rclpy.init(args=args)\nexecutor = SingleThreadedExecutor()\nexecutor.add_node(Driver())\n'
    'executor.spin()',
])
def test_canonical_main_allows_stepping(main_body):
    decision = decide(source(main_body))
    assert decision.steppable, decision.reason


@pytest.mark.parametrize('main_body, reason', [
    ('rclpy.init()\nnode = Driver()\nwhile rclpy.ok():\n'
     '    rclpy.spin_once(node, timeout_sec=0.1)',
     'main() loops on rclpy.spin_once (line 21)'),
    ('rclpy.init()\nexecutor = MultiThreadedExecutor()\nexecutor.add_node(Driver())\n'
     'executor.spin()', 'main() spins a MultiThreadedExecutor (line 20)'),
    ('rclpy.init()\nnode = rclpy.create_node("mover")\nrclpy.spin(node)',
     'main() builds its node with rclpy.create_node(...) (line 20), not a Node subclass'),
    ('rclpy.init()\nnode = Node("mover")\nrclpy.spin(node)',
     'main() builds its node with Node(...) (line 20), not a Node subclass'),
    ('rclpy.init()\na, b = Driver(), Driver()\nrclpy.spin(a)',
     'main() starts several nodes (lines 20, 20)'),
    ('rclpy.init()\nnode = Driver()\nrclpy.spin_once(node)', 'main() calls spin_once (line 21)'),
    ('rclpy.init()\nnode = Driver()\ntime.sleep(1.0)\nrclpy.spin(node)',
     'main() sleeps (line 21)'),
])
def test_main_doing_more_runs_as_a_process(main_body, reason):
    assert tuple(decide(source(main_body))) == (False, reason)


def test_a_sleeping_callback_runs_as_a_process_and_a_hang_stays_stepped():
    pacing = HEADER.replace('        pass', '        time.sleep(0.5)')
    main_body = 'rclpy.init()\nrclpy.spin(Driver())'
    assert tuple(decide(source(main_body, pacing))) == (
        False, 'the callback on_timer() calls time.sleep (line 15): sleeping freezes simulated '
               'time in a stepped run')
    # An hour's sleep is a hang: the stepped run's watchdog names its line.
    hang = HEADER.replace('        pass', '        time.sleep(3600)')
    assert decide(source(main_body, hang)).steppable
    # A sleep outside any callback (a worker thread's loop) does not stop the clock.
    worker = HEADER + '\n    def worker(self):\n        time.sleep(0.1)\n'
    assert decide(source(main_body, worker)).steppable


def test_files_without_main_or_one_node_class():
    assert decide(HEADER).steppable  # a module of Node classes: named by FILE:ClassName
    assert decide('def broken(:\n').steppable  # the loader reports the syntax error
    two = HEADER + '\n\nclass Other(Node):\n    pass\n'
    assert tuple(decide(source('rclpy.init()\nrclpy.spin(make())', two))) == (
        False, 'it defines 2 Node subclasses: main() decides what runs')
    # main() says which of the two it runs: that one is stepped.
    assert tuple(decide(source('rclpy.init()\nrclpy.spin(Driver())', two))) == (
        True, 'main() only spins its Node subclass Driver')
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
    assert tuple(decide(source(main_body, HELPER_BASE))) == (
        True, 'main() only spins its Node subclass Driver')
    assert node_class(source(main_body, HELPER_BASE)) == 'Driver'
    assert node_class(HELPER_BASE) == 'Driver'  # no main(): the most derived class


def test_a_callback_a_helper_base_class_registers_is_read_for_sleeps():
    sleepy_base = HELPER_BASE.replace('        pass', '        time.sleep(0.5)')
    assert tuple(decide(source('rclpy.init()\nrclpy.spin(Driver())', sleepy_base))) == (
        False, 'the callback on_timer() calls time.sleep (line 15): sleeping freezes simulated '
               'time in a stepped run')


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


@pytest.mark.parametrize('path', LAB_NODES, ids=lambda path: path.name)
def test_the_lab_nodes_are_stepped(path):
    assert run_mode(str(path)).steppable, run_mode(str(path)).reason


def test_a_target_naming_its_class_is_stepped():
    assert run_mode(f"{FIXTURES / 'sleepy_timer.py'}:Sleepy").steppable


def test_a_file_without_main_guard_runs_its_main_as_a_console_script():
    spec = node_spec(FIXTURES / 'function_node.py', ['--ros-args'])
    assert spec.cmd[1] == '-c' and "['main']()" in spec.cmd[2] and spec.cmd[-1] == '--ros-args'
    spec = node_spec(FIXTURES / 'spin_once_loop.py', ['--ros-args'])
    assert spec.cmd[1:] == (str((FIXTURES / 'spin_once_loop.py').resolve()), '--ros-args')


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


@pytest.mark.parametrize('name, printed', [
    ('spin_once_loop.py', 'loop driver started'),
    ('function_node.py', 'mover is moving'),
    ('sleepy_timer.py', 'sent a command, now resting'),
])
def test_a_file_that_cannot_be_stepped_runs_its_main_and_drives(tmp_path, name, printed):
    metrics, console = run_file(tmp_path, name)
    assert metrics['run_mode']['mode'] == 'process'
    assert metrics['distance_m'] > 0.3
    assert metrics['sim_time_s'] >= 3.0
    assert printed in console
    with Reader(tmp_path / 'out' / 'run') as bag:  # the recording, as a stepped run's
        counts = {connection.topic: connection.msgcount for connection in bag.connections}
    assert counts['/cmd_vel'] > 0 and counts['/scan'] > 0  # the node's, over DDS; the bridge's
    assert 'run mode' in console and 'process (' in console


def test_a_stepped_run_says_so(tmp_path):
    metrics, console = run_file(tmp_path, 'quitter.py', 1.0)
    assert metrics['run_mode'] == {'mode': 'stepped',
                                   'reason': 'main() only spins its one Node subclass'}


def test_a_process_run_takes_one_node_file(tmp_path):
    with pytest.raises(RunError, match=r'spin_once_loop\.py: main\(\) loops on rclpy\.spin_once '
                                       r'\(line 22\), so it runs as its own process; a process '
                                       'run takes one node file: run it alone'):
        run_simulation('obstacles', ['scan_ahead', str(FIXTURES / 'spin_once_loop.py')],
                       duration_s=1.0, out_dir=tmp_path / 'out')
    assert not (tmp_path / 'out').exists()


def test_a_process_run_reports_its_progress_in_simulated_time(tmp_path):
    seen = []
    result = run_simulation('obstacles', [str(FIXTURES / 'function_node.py')], duration_s=2.0,
                            out_dir=tmp_path / 'out', quiet=True, plot=False,
                            progress=lambda sim_s, duration_s: seen.append((sim_s, duration_s)))
    assert result.metrics['run_mode']['mode'] == 'process'
    assert seen == sorted(seen) and seen[-1] == (2.0, 2.0)  # the grader's stall watch sees it


def test_ctrl_c_stops_a_process_run_and_writes_its_outputs(tmp_path):
    runner = subprocess.Popen(
        [sys.executable, '-m', 'sim_bridge.run', '--world', 'obstacles', '--node',
         str(FIXTURES / 'spin_once_loop.py'), '--duration', '600', '--out',
         str(tmp_path / 'out'), '--no-plot'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    try:
        for line in runner.stdout:  # its node is up: simulated time runs
            if 'loop driver started' in line:
                break
        runner.send_signal(signal.SIGINT)
        _, stderr = runner.communicate(timeout=60)
    finally:
        runner.kill()
    assert runner.returncode == 130, stderr
    assert 'its outputs are in' in stderr
    metrics = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert metrics['run_mode']['mode'] == 'process' and metrics['sim_time_s'] < 600


def test_logic_in_the_main_block_itself_is_read_too():
    script = HEADER + textwrap.dedent("""

        if __name__ == '__main__':
            rclpy.init()
            node = Driver()
            while rclpy.ok():
                rclpy.spin_once(node)
        """)
    assert tuple(decide(script)) == (
        False, 'the __main__ block loops on rclpy.spin_once (line 21)')
    canonical = HEADER + "\n\nif __name__ == '__main__':\n    rclpy.init()\n"
    canonical += '    rclpy.spin(Driver())\n'
    assert decide(canonical).steppable


def test_two_runs_at_once_never_share_a_ros_domain(tmp_path):
    # Two process runs with the same pid spread (a grader's --jobs 2) must not hear each other.
    first = DomainReservation(pid=7, folder=tmp_path)
    second = DomainReservation(pid=7, folder=tmp_path)
    assert first.domain_id == DOMAIN_BASE + 7
    assert second.domain_id == DOMAIN_BASE + 8
    first.release()
    again = DomainReservation(pid=7, folder=tmp_path)
    assert again.domain_id == DOMAIN_BASE + 7
    held = [DomainReservation(pid=7, folder=tmp_path) for _ in range(DOMAIN_COUNT - 2)]
    with pytest.raises(RuntimeError, match='held by another run'):
        DomainReservation(pid=7, folder=tmp_path)
    for reservation in (again, second, *held):
        reservation.release()


def test_a_process_run_names_the_topics_nothing_is_at_the_other_end_of(tmp_path):
    metrics, console = run_file(tmp_path, 'namespaced_loop.py', 2.0, '--no-record')
    assert metrics['run_mode'] == {'mode': 'process',
                                   'reason': 'main() runs a loop of its own (line 28)'}
    warnings = [
        'cruiser subscribes to /robot/scan: nothing publishes it (the simulator publishes '
        '/scan: --remap /robot/scan:=/scan)',
        'cruiser publishes /robot/cmd_vel: nothing subscribes to it (the simulator subscribes '
        'to /cmd_vel: --remap /robot/cmd_vel:=/cmd_vel)']
    assert metrics['warnings'] == warnings and metrics['distance_m'] == 0.0
    assert all(f'warning: {warning}' in console for warning in warnings)
    # The rules it names connect it: it drives, and nothing is left to warn of.
    metrics, _ = run_file(tmp_path, 'namespaced_loop.py', 3.0, '--no-record', '--remap',
                          '/robot/scan:=/scan', '--remap', '/robot/cmd_vel:=/cmd_vel')
    assert metrics['warnings'] == [] and metrics['distance_m'] > 0.3


def test_gui_without_a_display_is_refused_in_one_line_before_anything_starts(
        tmp_path, monkeypatch):
    assert gui_problem({}, 'linux').startswith('--gui needs a display, and DISPLAY is not set')
    assert gui_problem({'DISPLAY': ':0'}, 'linux') is None
    assert gui_problem({}, 'darwin') is None  # pybullet's window is not X11's there
    monkeypatch.delenv('DISPLAY', raising=False)
    for node in ('scan_ahead', str(FIXTURES / 'function_node.py')):  # stepped, process
        with pytest.raises(RunError, match='--gui needs a display'):
            run_simulation('obstacles', [node], duration_s=1.0, gui=True,
                           out_dir=tmp_path / 'out')
    assert not (tmp_path / 'out').exists()


def test_a_process_run_with_gui_shows_its_live_simulator_in_the_window(tmp_path, monkeypatch):
    import pybullet
    modes, connect = [], pybullet.connect

    def headless_connect(mode, *args, **kwargs):  # no display here: the GUI path in DIRECT
        modes.append(mode)
        return connect(pybullet.DIRECT, *args, **kwargs)

    monkeypatch.setattr(pybullet, 'connect', headless_connect)
    monkeypatch.setenv('DISPLAY', ':99')
    result = run_simulation('obstacles', [str(FIXTURES / 'function_node.py')], duration_s=2.0,
                            gui=True, out_dir=tmp_path, quiet=True, record=False, plot=False)
    assert modes == [pybullet.GUI]
    assert result.metrics['run_mode']['mode'] == 'process' and result.metrics['distance_m'] > 0.2


def test_an_error_in_a_process_run_is_reported_at_the_nodes_deepest_line(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'loop_random_turn.py')],
                            duration_s=20.0, out_dir=tmp_path, quiet=True, record=False,
                            plot=False)
    [error] = result.metrics['node_errors']
    path = (FIXTURES / 'loop_random_turn.py').resolve()
    # random.choice raised it; the student's call of it is the line to fix.
    assert error['error'].endswith(
        f'IndexError: Cannot choose from an empty sequence at {path}:22: '
        'return random.choice(allowed)')
    assert error['error'].startswith('loop_random_turn-1 ended (exit status 1) at ')
    assert error['traceback'].splitlines()[-3:] == [
        f'  File "{path}", line 22, in pick_turn', '    return random.choice(allowed)',
        'IndexError: Cannot choose from an empty sequence']
    assert 'random.py' not in error['traceback'] and 'runpy' not in error['traceback']
    assert result.metrics['distance_m'] > 0.3  # it drove up to the cube first


def test_a_ros_module_missing_in_a_process_run_says_where_it_comes_from(tmp_path, monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    result = run_simulation('obstacles', [str(FIXTURES / 'tf_yaw_loop.py')], duration_s=3.0,
                            out_dir=tmp_path, quiet=True, record=False, plot=False)
    [error] = result.metrics['node_errors']
    path = (FIXTURES / 'tf_yaw_loop.py').resolve()
    assert (f"ModuleNotFoundError: No module named 'tf_transformations' at {path}:5: from "
            'tf_transformations import euler_from_quaternion (tf_transformations comes with a '
            'ROS 2 Jazzy installation (apt package ros-jazzy-tf-transformations), not with the '
            'ROS wheels from PyPI; for Euler angles and quaternions PyPI has transforms3d'
            ) in error['error']


def test_a_node_that_ends_itself_in_a_process_run_ends_it_with_every_output(tmp_path):
    metrics, console = run_file(tmp_path, 'timed_drive_loop.py', 20.0, plot=True)
    assert metrics['node_errors'] == [] and metrics['run_mode']['mode'] == 'process'
    assert metrics['ended_by'].startswith('timed_drive_loop-1 ended (exit status 0) at ')
    assert metrics['ended_by'] in metrics['warnings']
    # Ended where it ended itself (its 2 s of driving, the /clock it reads late under load).
    assert 2.0 <= metrics['sim_time_s'] < 20.0
    assert 'done driving' in console
    out = tmp_path / 'out'
    assert (out / 'params.yaml').is_file() and (out / 'trajectory.png').stat().st_size > 0
    with Reader(out / 'run') as bag:
        assert {connection.topic for connection in bag.connections} >= {'/clock', '/scan'}


def test_the_last_traceback_a_process_printed_is_read_with_its_code_lines():
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


def test_ros_args_after_the_target_reach_a_node_process_unchanged(tmp_path):
    metrics, _ = run_file(tmp_path, 'namespaced_loop.py', 3.0, '--no-record', '--ros-args',
                          '-r', '/robot/scan:=/scan', '-r', '/robot/cmd_vel:=/cmd_vel')
    assert metrics['run_mode']['mode'] == 'process'
    assert metrics['warnings'] == [] and metrics['distance_m'] > 0.3


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
    assert [report.metrics['run_mode']['mode'] for report in reports] == [
        'process', 'stepped', 'process']
    # The report says why the unwired one did not move, and how to wire it.
    warning = ('cruiser subscribes to /robot/scan: nothing publishes it (the simulator '
               'publishes /scan: --remap /robot/scan:=/scan)')
    assert warning in reports[2].metrics['warnings']
    assert warning in format_table(reports)


def test_turtlebot3_scan_code_in_a_process_run_gets_the_scans_geometry(tmp_path):
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


def test_a_parameter_a_node_process_does_not_declare_is_a_warning(tmp_path):
    remaps = ('--remap', '/robot/scan:=/scan', '--remap', '/robot/cmd_vel:=/cmd_vel')
    metrics, _ = run_file(tmp_path, 'namespaced_loop.py', 3.0, '--no-record', *remaps,
                          '--param', 'cruiser:speed=0.2', '--param', 'cruiser:sped=0.2',
                          '--param', 'ghost:speed=0.2')
    # Asked of the node over ROS (its list_parameters service), as `ros2 param list` asks.
    assert metrics['warnings'] == [
        'parameters given for node(s) ghost, but the nodes are cruiser, sim_bridge; they were '
        'ignored',
        "node 'cruiser' did not declare parameter 'sped' (given by --param or the params "
        'file); it was ignored']
    assert 0.1 < metrics['distance_m'] < 0.65  # 3 s at 0.2 m/s at most, not its 0.3 m/s


def test_a_process_run_measures_the_wall_distance_against_the_nodes_own_distance(tmp_path):
    # No setpoint given: as in a stepped run, the node's `distance` parameter, asked over ROS.
    from scan_pkg import wall_follow
    from sim_bridge.runner.node_styles import Decision
    from sim_bridge.runner.options import prepare_run, RunSpec
    from sim_bridge.runner.process_run import run_as_process
    spec = RunSpec('wall_follow_box', (wall_follow.__file__,), duration_s=3.0, seed=1,
                   params={'wall_follow': {'distance': 0.6}}, out_dir=tmp_path, quiet=True,
                   record=False, plot=False)
    result = run_as_process(spec, prepare_run(spec), wall_follow.__file__,
                            Decision(False, 'the test runs it so'))
    assert result.metrics['node_errors'] == [] and result.metrics['warnings'] == []
    assert result.metrics['wall_distance_m']['setpoint'] == 0.6


def test_a_process_forked_after_a_process_run_can_collect_its_garbage(tmp_path):
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
