"""The hints a node error gets (sim_bridge.runner.hints): ROS-installation modules, scan shape."""

import importlib.util
import math
import os

import pytest
from sim_bridge.runner.hints import (
    direction, geometry, printed_scan_hint, ros_module_hint, ROS_MODULES, turtlebot3_lidar)
from sim_bridge.runner.targets import describe, invisible_character_hint


@pytest.mark.skipif(bool(os.environ.get('ROS_DISTRO')), reason='a sourced ROS installation')
@pytest.mark.parametrize('name', sorted(ROS_MODULES))
def test_each_module_hinted_as_ros_only_is_not_importable_from_the_wheels(name):
    spec = importlib.util.find_spec(name)
    # At most a namespace package (sim_bridge/launch/ on the path), not the ROS module.
    assert spec is None or spec.origin is None


@pytest.mark.parametrize('name', sorted(ROS_MODULES))
def test_a_ros_module_hint_names_its_jazzy_package(name, monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    error = ModuleNotFoundError(f"No module named '{name}.sub'", name=f'{name}.sub')
    hint = ros_module_hint(error)
    assert hint.startswith(f'{name} comes with a ROS 2 Jazzy installation (apt package '
                           f"ros-jazzy-{name.replace('_', '-')}), not with the ROS wheels")


def test_on_a_sourced_ros_the_hint_says_to_install_the_package(monkeypatch):
    monkeypatch.setenv('ROS_DISTRO', 'jazzy')
    error = ModuleNotFoundError("No module named 'tf2_ros'", name='tf2_ros')
    assert ros_module_hint(error) == ('tf2_ros is part of ROS 2 but not installed here: sudo '
                                      'apt install ros-jazzy-tf2-ros')


def test_a_folder_named_like_a_ros_module_is_not_that_module(monkeypatch):
    monkeypatch.delenv('ROS_DISTRO', raising=False)
    error = ImportError("cannot import name 'LaunchDescription' from 'launch' (unknown "
                        'location)', name='launch')
    assert ros_module_hint(error).startswith('launch comes with a ROS 2 Jazzy installation')


@pytest.mark.parametrize('error', [
    ModuleNotFoundError("No module named 'nosuchthing'", name='nosuchthing'),
    ImportError("cannot import name 'Buffer' from 'tf2_ros'", name='tf2_ros'),
    ValueError('tf2_ros'),
])
def test_other_errors_get_no_ros_module_hint(error):
    assert ros_module_hint(error) == ''


@pytest.mark.parametrize('angle, says', [
    (0.0, ', ahead'), (-1.57, ', right'), (1.57, ', left'), (math.pi, ', behind'),
    (-math.pi, ', behind'), (6.28, ', ahead'), (0.8, '')])
def test_beam_directions_follow_rep_103(angle, says):
    assert direction(angle) == says


def test_geometry_names_the_first_and_last_beams():
    assert geometry(36, -1.57, 3.14 / 35) == (
        '36 ranges from -1.57 rad (index 0, right) to +1.57 rad (index 35, left)')
    assert geometry(360, 0.0, 6.28 / 359) == (
        '360 ranges from 0 rad (index 0, ahead) to +6.28 rad (index 359, ahead)')


@pytest.mark.parametrize('error_line, failing_line, hinted', [
    ('IndexError: array index out of range', 'left = latest.ranges[90]', True),
    ('ValueError: min() arg is an empty sequence', 'front = min(msg.ranges[260:280])', True),
    ('ValueError: zero-size array to reduction operation minimum which has no identity',
     'left = np.array(msg.ranges)[80:100].min()', True),
    ('IndexError: list index out of range', 'turn = TURNS[choice]', False),  # not a scan
    ('ValueError: could not convert string to float', 'x = float(msg.ranges[0])', False),
    ('KeyError: 90', 'left = ranges[90]', False)])
def test_a_process_runs_printed_scan_error_gets_the_simulators_scan_geometry(
        error_line, failing_line, hinted):
    burger = turtlebot3_lidar()
    hint = printed_scan_hint(error_line, failing_line, burger)
    # On the Burger itself, only its own geometry: nothing else to compare with.
    assert hint == ('this scan has 360 ranges from 0 rad (index 0, ahead) to +6.28 rad (index '
                    '359, ahead)' if hinted else '')


@pytest.mark.parametrize('character, name, instead', [
    ('\u00a0', 'no-break space (U+00A0)', 'a space'),
    ('\u200b', 'zero width space (U+200B)', 'nothing (delete it)'),
])
def test_an_invisible_character_gets_the_line_and_what_to_replace_it_with(
        character, name, instead):
    source = f'def main():\n    x = 1\n{character * 4}return x\n'
    with pytest.raises(SyntaxError) as raised:
        compile(source, 'wanderbot.py', 'exec')
    hint = invisible_character_hint(raised.value)
    assert hint == (f'line 3 holds a {name}, as text copied from a document does: replace '
                    f'every one in the file with {instead}')
    assert hint in describe(raised.value)


def test_other_syntax_errors_get_no_invisible_character_hint():
    with pytest.raises(SyntaxError) as raised:
        compile('def main(:\n', 'wanderbot.py', 'exec')
    assert invisible_character_hint(raised.value) == ''
