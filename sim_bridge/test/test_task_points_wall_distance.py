"""
Task 4's wall distance is the one the student chose: its parameter, as students name it.

A parameter names the wall distance when its name says so (``wall_distance``, ``target_dist``,
``d``, ``setpoint``, ...) and its value is a sane one (0.2-1.5 m); exactly one such, or the
run's behaviour (the median of its distance to the wall) tells the distance instead.
"""

from pathlib import Path

import pytest

from sim_bridge.common.paths import examples_dir
from sim_bridge.runner.run import run_simulation
from sim_bridge.scoring.metrics import declared_wall_distance

#: What else a wall follower declares: speeds, gains, a turn rate, a tolerance.
OTHERS = {'linear_speed': 0.25, 'max_angular': 0.8, 'kp': 1.2, 'wall_gain': 0.9,
          'target_speed': 0.3, 'tolerance': 0.2, 'lookahead_time': 0.5}


@pytest.mark.parametrize('name', [
    'distance', 'wall_distance', 'desired_distance', 'target_dist', 'dist', 'd', 'setpoint',
    'set_point_dist', 'follow_distance', 'followDistance', 'wallDist', 'desired_wall_distance_m',
    'target'])
def test_a_wall_distance_parameter_is_read_as_students_name_it(name):
    assert declared_wall_distance([{**OTHERS, name: 0.55}]) == 0.55


@pytest.mark.parametrize('declared', [
    {},                                                # none: the behaviour tells it
    OTHERS,                                            # speeds, gains, a tolerance: not one
    {'distance': 2.0},                                 # not a sane wall distance
    {'distance': 0.1},
    {'wall_distance': 0.55, 'stop_distance': 0.3},     # ambiguous: two distances
    {'d': 0.5, 'target': 0.7},
])
def test_no_parameter_or_an_ambiguous_pair_leaves_the_distance_to_the_behaviour(declared):
    assert declared_wall_distance([declared]) is None


def test_two_names_of_one_distance_are_not_ambiguous():
    assert declared_wall_distance([{'distance': 0.6}, {'wall_distance': 0.6}]) == 0.6


def careful_follower(tmp_path: Path, declarations: dict[str, float]) -> Path:
    """Return the careful student's follower declaring ``declarations``, keeping the first."""
    source = (examples_dir() / 'careful_wall_follow.py').read_text()
    name, value = next(iter(declarations.items()))
    lines = ''.join(f"        self.declare_parameter('{other}', {number})\n"
                    for other, number in declarations.items())
    source = source.replace("        self.declare_parameter('distance', 0.7)\n", lines)
    source = source.replace("self.get_parameter('distance')", f"self.get_parameter('{name}')")
    path = tmp_path / 'wall_follow.py'
    path.write_text(source)
    return path


@pytest.mark.parametrize('declarations, declared', [
    ({'wall_distance': 0.55, 'linear_speed': 0.25}, 0.55),
    ({'wall_distance': 0.55, 'stop_distance': 0.3}, None),
])
def test_a_run_measures_the_wall_distance_against_the_parameter_that_names_it(
        tmp_path, declarations, declared):
    result = run_simulation('wall_follow_box', [str(careful_follower(tmp_path, declarations))],
                            duration_s=3.0, out_dir=tmp_path / 'out', quiet=True,
                            record=False, plot=False)
    metrics = result.metrics
    assert metrics['node_errors'] == []
    assert metrics['wall_follow']['declared_m'] == declared
    assert metrics['wall_distance_m']['setpoint'] == declared
