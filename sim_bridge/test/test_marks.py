"""Marks: a scenario's task:, marks: and marking:, and how a task's runs become its marks."""

import pytest

from sim_bridge.grading.marks import format_marks, summary, task_marks, total
from sim_bridge.grading.scenario import (
    load_scenario, load_scenarios, scenario_from_dict, ScenarioError)

BASE = {'world': 'wall_follow_box', 'nodes': ['wall_follow'], 'duration': 10.0,
        'criteria': ['collisions == 0']}


def scenario(name, **keys):
    return scenario_from_dict({**BASE, **keys}, name)


def entries(name, passed, failed=0):
    return ([{'scenario': name, 'passed': True}] * passed
            + [{'scenario': name, 'passed': False}] * failed)


def test_a_scenario_carries_its_task_marks_and_marking():
    marked = scenario('box_cw', task=4, marks=3, marking='proportional')
    assert (marked.task, marked.task_name, marked.marks, marked.marking) == (
        '4', '4', 3.0, 'proportional')
    plain = scenario('box_ccw')
    assert (plain.task, plain.task_name, plain.marks, plain.marking) == (
        None, 'box_ccw', None, 'all')


@pytest.mark.parametrize('keys, message', [
    ({'marks': 0}, 'marks: must be a positive number, got int 0'),
    ({'marks': -2}, 'marks: must be a positive number'),
    ({'marks': '3'}, "marks: must be a positive number, got the text '3'"),
    ({'marks': True}, 'marks: must be a positive number'),
    ({'marks': float('inf')}, 'marks: must be a positive number'),
    ({'marks': 3, 'marking': 'some'}, 'marking: must be one of all, proportional (all: every '
     "run passes for the marks; proportional: marks x runs passed / runs), got the text 'some'"),
    ({'marking': 'all'}, 'marking: says how runs become marks, but the scenario has no marks:'),
    ({'task': ''}, 'task: must be a task number or label'),
    ({'task': [4]}, 'task: must be a task number or label, e.g. 1 or wall_follow, got a list'),
])
def test_a_bad_marks_key_is_named_in_one_line(keys, message):
    with pytest.raises(ScenarioError) as error:
        scenario('box_cw', **keys)
    assert str(error.value).startswith(f'<scenario box_cw>: {message}')
    assert '\n' not in str(error.value)


def test_scenarios_of_one_task_that_disagree_on_its_marks_are_refused(tmp_path):
    for name, marks in (('a', 3), ('b', 2)):
        (tmp_path / f'{name}.yaml').write_text(
            'world: wall_follow_box\nnodes: [wall_follow]\nduration: 10\n'
            f'criteria: [collisions == 0]\ntask: 4\nmarks: {marks}\n')
    with pytest.raises(ScenarioError) as error:
        load_scenarios([tmp_path])
    assert str(error.value) == (
        f"{tmp_path / 'b.yaml'}: marks: 2, but {tmp_path / 'a.yaml'} of the same task '4' "
        'says 3; a task has one marks')
    assert load_scenario(tmp_path / 'b.yaml').marks == 2.0  # alone, it is a scenario like any


def test_all_gives_the_marks_only_when_every_run_of_the_task_passes():
    scenarios = [scenario('ahead', task=1, marks=2), scenario('ahead_fast', task=1, marks=2)]
    [task] = task_marks(scenarios, entries('ahead', 1) + entries('ahead_fast', 2))
    assert (task.title, task.scenarios, task.runs, task.passed, task.earned) == (
        'task 1', ('ahead', 'ahead_fast'), 3, 3, 2.0)
    [task] = task_marks(scenarios, entries('ahead', 1) + entries('ahead_fast', 1, failed=1))
    assert task.earned == 0.0
    assert task.rule() == 'task 1: 2 marks when all 3 runs pass'
    # Each scenario's share: a passed scenario of a failed task scores nothing under 'all'.
    assert task.share(1, 1) == (0.0, pytest.approx(2 / 3))


def test_proportional_gives_the_marks_in_proportion_to_the_runs_passed():
    scenarios = [scenario(name, task='4', marks=3, marking='proportional')
                 for name in ('box_cw', 'box_ccw')]
    [task] = task_marks(scenarios, entries('box_cw', 3) + entries('box_ccw', 1, failed=2))
    assert task.earned == pytest.approx(2.0)
    shares = [task.share(3, 3), task.share(3, 1)]
    assert shares == [(1.5, 1.5), (0.5, 1.5)]
    assert sum(score for score, _ in shares) == pytest.approx(task.earned)


def test_tasks_come_in_order_and_a_scenario_without_marks_counts_in_no_total():
    scenarios = [scenario('extra', task='extra'), scenario('wall', task=4, marks=3),
                 scenario('ahead', task=1, marks=2), scenario('wander', task=2, marks=3,
                                                              marking='proportional')]
    tasks = task_marks(scenarios, entries('ahead', 1) + entries('wander', 4, failed=1)
                       + entries('wall', 0, failed=3) + entries('extra', 1))
    assert [task.title for task in tasks] == ['task 1', 'task 2', 'task 4', 'extra']
    assert total(tasks) == (pytest.approx(4.4), 8.0)
    assert summary(tasks) == 'marks 4.4/8 (task 1: 2/2, task 2: 2.4/3, task 4: 0/3)'
    assert tasks[-1].rule() == 'extra carries no marks'
    assert summary(tasks[-1:]) == ''


def test_a_task_with_no_runs_in_the_batch_earns_nothing_of_its_marks():
    [task] = task_marks([scenario('ahead', task=1, marks=2)], [])
    assert (task.earned, task.share(0, 0), total([task])) == (0.0, (0.0, 0.0), (0.0, 2.0))


@pytest.mark.parametrize('value, text', [(2.0, '2'), (1.5, '1.5'), (0.1875, '0.19'),
                                         (2 / 3, '0.67'), (0.0, '0')])
def test_marks_read_as_people_write_them(value, text):
    assert format_marks(value) == text


def test_a_follower_earning_all_points_from_both_starts_is_marked_on_the_way_it_went():
    """A left-wall follower loops from either start: its own direction is the one it passed."""
    cw, ccw = (scenario(name, task=4, marks=3, marking='proportional', points='wall_follow',
                        direction=direction)
               for name, direction in (('box_cw', 'clockwise'), ('box_ccw', 'counterclockwise')))
    earned = [{'point': point, 'earned': True, 'reason': '', 'rule': ''}
              for point in ('loops the object in one direction',
                            'keeps the wall at the distance it chose', 'no collision')]
    runs = [{'scenario': 'box_cw', 'passed': False, 'points': earned},   # laps <= -1 fails
            {'scenario': 'box_ccw', 'passed': True, 'points': earned}]
    (task,) = task_marks([cw, ccw], runs)
    assert (task.earned, task.direction) == (3.0, 'counterclockwise')
