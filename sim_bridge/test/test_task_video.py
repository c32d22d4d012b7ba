"""
``./lab video TASK``: the loop direction a student's node follows, and a line for every failure.

Issue 32: ``./lab video 4 --node FILE`` filmed only the clockwise start, so a counterclockwise
student's node was filmed circling aimlessly; a run whose node crashed made a video and exited
1 without a word. The nodes are real (a node file of the test's fixtures that keeps the wall on
its left, the kit's example that keeps it on its right), the trials and runs stepped.
"""

import json
from pathlib import Path

import pytest
from sim_bridge.commands import task_video as lab_video
from sim_bridge.common.paths import repo_root, scenarios_dir
from sim_bridge.grading.scenario import Scenario
import yaml

FIXTURES = Path(__file__).parent / 'fixtures'
#: A student's wall follower with the wall on its left and no parameter: counterclockwise.
LEFT_FOLLOWER = FIXTURES / 'left_wall_follower.py'
#: The kit's example of a careful student: the wall on its right, clockwise.
RIGHT_FOLLOWER = repo_root() / 'examples' / 'careful_wall_follow.py'
NAMES = 'Ada Lovelace 100001'
#: The shipped scenario of each loop direction round the box.
LOOPS = {'clockwise': 'wall_follow_box_cw.yaml', 'counterclockwise': 'wall_follow_box_ccw.yaml'}


def film(args: list[str]) -> Scenario:
    """Return the scenario ``./lab video ARGS`` films (trials run when it must find it)."""
    return lab_video.filmed_scenario(lab_video.parse_args(args), scenarios_dir())


@pytest.mark.parametrize('node, direction', [(LEFT_FOLLOWER, 'counterclockwise'),
                                             (RIGHT_FOLLOWER, 'clockwise')],
                         ids=['left_wall', 'right_wall'])
def test_a_students_node_is_filmed_in_the_direction_it_follows(node, direction, capfd):
    scenario = film(['4', '--node', str(node), '--names', NAMES])
    assert scenario.path.name == LOOPS[direction]
    assert scenario.direction == direction and scenario.nodes == (str(node.resolve()),)
    said = capfd.readouterr().err
    assert f'filming {direction}: in a 20 s trial the node went' in said


def test_the_direction_can_be_told_and_the_kits_node_loops_as_the_kit_does(capfd):
    told = film(['4', '--node', str(LEFT_FOLLOWER), '--names', NAMES, '--direction', 'cw'])
    assert told.path.name == LOOPS['clockwise']
    kits = film(['4'])
    assert kits.path.name == LOOPS['clockwise']
    assert film(['4', '--direction', 'ccw']).direction == 'counterclockwise'
    assert 'trial' not in capfd.readouterr().err  # told, or the kit's node: no trial run


def test_a_counterclockwise_students_video_is_of_a_counterclockwise_loop(
        tmp_path, monkeypatch, capfd):
    """End to end: the run filmed starts turned round, and the node loops the box that way."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / 'out'
    status = lab_video.main(['4', '--node', str(LEFT_FOLLOWER), '--names', NAMES,
                             '--speed', '19', '--out', str(out)])
    assert status in (0, 1)  # a video either way; whether the run passed is the grader's
    assert (tmp_path / 'labscan_task4.mp4').is_file()
    params = yaml.safe_load((out / 'params.yaml').read_text())
    assert params['sim_bridge']['ros__parameters']['robot_pose'][2] == pytest.approx(
        -3.141592653589793)
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['wall_follow']['winding'] > 0.75  # most of a loop, counterclockwise
    assert 'filming counterclockwise' in capfd.readouterr().err


@pytest.mark.parametrize('args, said', [
    (['9'], "'9': a lab task is one of"),
    (['4', '--node', str(LEFT_FOLLOWER)], '--node needs --names'),
    (['4', '--names', NAMES], '--names without --node'),
    (['1', '--node', str(LEFT_FOLLOWER), '--names', NAMES, '--direction', 'ccw'],
     '--direction: scan_ahead does not loop round an object'),
    (['4', '--direction', 'left'], "argument --direction: invalid choice: 'left'"),
    (['1', '--speed', '0'], '--speed must be a positive number'),
    (['1', '--speed', 'nan'], '--speed must be a positive number'),
], ids=['task', 'names', 'kit_names', 'direction', 'direction_word', 'speed', 'nan'])
def test_a_bad_command_line_is_one_line_before_any_run(tmp_path, monkeypatch, capfd, args,
                                                       said):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exited:
        lab_video.main([*args, '--out', str(tmp_path / 'out')])
    err = capfd.readouterr().err
    assert exited.value.code == 2 and err.startswith('error: ') and err.count('\n') == 1, err
    assert said in err
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('node, status, said', [
    (FIXTURES / 'raising_node.py', 1,
     "error: the run failed, as the video shows: node 'raiser' raised ZeroDivisionError"),
    (FIXTURES / 'no_node.py', 2, 'must define exactly one rclpy Node subclass'),
    (FIXTURES / 'absent.py', 2, 'absent.py: no such file'),
], ids=['crashes', 'no_node', 'missing'])
def test_a_node_that_fails_is_one_line_of_the_kits_saying_how(tmp_path, monkeypatch, capfd,
                                                              node, status, said):
    monkeypatch.chdir(tmp_path)
    assert lab_video.main(['1', '--node', str(node), '--names', NAMES, '--speed', '4']) == status
    err = capfd.readouterr().err
    # The kit's lines (the node's own traceback aside, as its terminal printed it).
    kits = [line for line in err.splitlines() if line.startswith('error: ')]
    assert len(kits) == 1 and said in kits[0], err
    assert (tmp_path / 'labscan_task1.mp4').is_file() == (status == 1)
