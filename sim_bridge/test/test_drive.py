"""A scenario drives the robot as a person at the teleop would (issue 18 §1)."""

import math
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores
from sim_bridge.common.errors import RunError
from sim_bridge.grading.scenario import scenario_from_dict, ScenarioError
from sim_bridge.ros.drive import DriveError, DrivePlan, parse_drive, Segment
from sim_bridge.runner.run import run_simulation

FIXTURES = Path(__file__).parent / 'fixtures'
#: obstacles.yaml: the robot starts at the origin facing +x, the cube's front face at x = 2.0.
CUBE_FACE_X = 2.0


@pytest.mark.parametrize('drive, message', [
    ([], 'drive: must be a non-empty list of segments, got []'),
    ([{'linear': 0.2}], 'drive[0].duration: missing'),
    ([{'duration': 1}, {'duration': -2, 'linear': 0.2}],
     'drive[1].duration: must be a positive number (s), got -2'),
    ([{'duration': 1, 'linear': math.nan}], 'drive[0].linear: must be a finite number (m/s)'),
    ([{'duration': 1, 'angular': '0.5'}], 'drive[0].angular: must be a finite number (rad/s)'),
    ([{'duration': 1, 'speed': 0.2}], 'drive[0].speed: unknown key; a segment has duration, '
                                      'linear, angular, until'),
    ([{'duration': 9, 'linear': 0.2, 'until': {'within_m': 0.4}}], 'drive[0].until.of: missing'),
    ([{'duration': 9, 'until': {'within_m': math.inf, 'of': 'cube'}}],
     'drive[0].until.within_m: must be a positive number (m), got inf'),
    ([{'duration': 9, 'until': 'cube'}], 'drive[0].until: must be a mapping'),
    (['forward'], 'drive[0]: must be a mapping'),
])
def test_a_bad_drive_plan_is_one_line_naming_the_segment_and_key(drive, message):
    with pytest.raises(DriveError) as error:
        parse_drive(drive)
    assert str(error.value).startswith(message)
    assert '\n' not in str(error.value)


def test_a_scenario_file_with_a_bad_segment_names_the_file_segment_and_key(tmp_path):
    data = {'world': 'obstacles', 'nodes': ['scan_ahead'], 'duration': 5,
            'criteria': ['collisions == 0'],
            'drive': [{'duration': 2, 'linear': 0.2}, {'duration': math.nan}]}
    with pytest.raises(ScenarioError) as error:
        scenario_from_dict(data, 'ahead', tmp_path / 'ahead.yaml')
    assert str(error.value) == (f"{tmp_path / 'ahead.yaml'}: drive[1].duration: must be a "
                                'positive number (s), got nan')
    data['drive'] = [{'duration': 2, 'linear': 0.2}]
    assert scenario_from_dict(data, 'ahead').drive == (Segment(2.0, 0.2, 0.0),)


def test_the_plan_holds_each_segment_for_its_duration_or_until_near_the_obstacle():
    # Driving along x towards an obstacle whose surface is at x = 2.
    plan = DrivePlan(parse_drive([{'duration': 1, 'linear': 0.5},
                                  {'duration': 10, 'linear': 0.2,
                                   'until': {'within_m': 0.4, 'of': 'wall'}},
                                  {'duration': 0.5, 'angular': -1.0}]),
                     lambda name, x, y: 2.0 - x)
    assert plan.command(0.0, 0.0, 0.0) == (0.5, 0.0)
    assert plan.command(0.95, 0.5, 0.0) == (0.5, 0.0)
    assert plan.command(1.0, 0.5, 0.0) == (0.2, 0.0)  # the first ends, the second starts
    assert plan.command(8.0, 1.59, 0.0) == (0.2, 0.0)
    assert plan.command(8.1, 1.61, 0.0) == (0.0, -1.0)  # within 0.4 m: the turn starts
    assert plan.command(8.55, 1.61, 0.0) == (0.0, -1.0)
    assert plan.command(8.6, 1.61, 0.0) is None and plan.done
    assert plan.missed == []


def test_a_segment_that_never_came_near_its_obstacle_is_a_warning(tmp_path, run_warnings):
    # The cylinder is off to the left: 2 s straight ahead never come within 0.4 m of it.
    result = run_simulation('obstacles', ['scan_ahead'], duration_s=3.0, out_dir=tmp_path,
                            quiet=True, plot=False, record=False,
                            drive=[{'duration': 2.0, 'linear': 0.2,
                                    'until': {'within_m': 0.4, 'of': 'cylinder'}}])
    assert run_warnings(result.metrics['warnings']) == [
        'drive[0]: ended after its 2 s with the robot never within 0.4 m of cylinder']


def test_a_segment_ending_near_an_obstacle_the_world_lacks_is_a_run_error(tmp_path):
    with pytest.raises(RunError, match=r"^drive\[0\]\.until\.of: world 'obstacles' has no "
                                       r"obstacle 'cub'; its obstacles are cube, cylinder, "
                                       r'sphere$'):
        run_simulation('obstacles', ['scan_ahead'], duration_s=1.0, out_dir=tmp_path,
                       drive=[{'duration': 5, 'linear': 0.2,
                               'until': {'within_m': 0.4, 'of': 'cub'}}])
    assert not tmp_path.joinpath('metrics.json').exists()


def commands(bag_path: Path) -> list[tuple[float, float, float]]:
    """Return the /cmd_vel commands of a recording: (sim time s, linear m/s, angular rad/s)."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag_path) as bag:
        return [(time / 1e9, msg.linear.x, msg.angular.z) for connection, time, raw in
                bag.messages([c for c in bag.connections if c.topic == '/cmd_vel'])
                for msg in [typestore.deserialize_cdr(raw, connection.msgtype)]]


DRIVE = [{'duration': 15, 'linear': 0.3, 'until': {'within_m': 0.4, 'of': 'cube'}},
         {'duration': 1.0, 'angular': 0.8}]


def test_a_stepped_run_drives_to_the_cube_turns_and_stops_the_same_every_time(tmp_path):
    results = [run_simulation('obstacles', ['scan_ahead'], duration_s=9.0, seed=1,
                              out_dir=tmp_path / name, quiet=True, plot=False, drive=DRIVE)
               for name in ('one', 'two')]
    metrics = results[0].metrics
    assert metrics['collisions'] == 0 and results[0].ok
    sent = commands(tmp_path / 'one' / 'run')
    assert sent == commands(tmp_path / 'two' / 'run')
    wall = ('wall_time_s', 'real_time_factor')
    assert {key: value for key, value in metrics.items() if key not in wall} == {
        key: value for key, value in results[1].metrics.items() if key not in wall}
    assert sent[0] == (0.0, 0.3, 0.0)
    # Forward at 0.3 m/s until the robot's centre is within 0.4 m of the cube's face ...
    forward_s = max(t for t, linear, _ in sent if linear > 0.0)
    assert forward_s == pytest.approx((CUBE_FACE_X - 0.4) / 0.3, abs=0.15)
    # ... then 1 s of turning, then one zero command, and nothing after it.
    turning = [t for t, linear, angular in sent if (linear, angular) == (0.0, 0.8)]
    assert turning[-1] - turning[0] == pytest.approx(1.0 - 0.05)
    assert sent[-1] == pytest.approx((turning[-1] + 0.05, 0.0, 0.0))
    # Stopped ~0.4 m from the face (the distance driven is along x), then turned in place.
    assert metrics['distance_m'] == pytest.approx(CUBE_FACE_X - 0.4, abs=0.05)


def test_a_multithreaded_node_is_driven_too(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'threaded_counting_logger.py')],
                            duration_s=3.0, out_dir=tmp_path, quiet=True, plot=False,
                            drive=[{'duration': 1.0, 'linear': 0.3}])
    assert 'MultiThreadedExecutor' in result.metrics['run_mode']['notes'][0]
    sent = commands(tmp_path / 'run')
    assert sent[0][1:] == (0.3, 0.0) and sent[-1][1:] == (0.0, 0.0)
    assert sent[-1][0] == pytest.approx(1.0, abs=0.2)
    # 1 s at 0.3 m/s.
    assert result.metrics['distance_m'] == pytest.approx(0.3, abs=0.05)
