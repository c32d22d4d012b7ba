"""
Marks: how a batch's runs become the lab's marks, per task and in all.

A scenario's ``task:`` names the lab task it grades and its ``marks:`` are that task's marks
(:mod:`sim_bridge.grading.scenario`); the wall follower's sixteen scenarios are one task worth 3. A
task's marks are earned over every run of its scenarios in the batch: ``marking: all`` gives
them when every run passed and none otherwise; ``proportional`` gives marks x runs passed /
runs. A run that was not submitted is a run that failed. A scenario without ``marks:`` counts
in no total: it is reported by its runs only. A task whose scenarios name the handout's
``points:`` (:mod:`sim_bridge.task_points`) is marked point by point instead: each point is
worth an equal share of the task's marks and earns it in proportion to the runs that show it;
each point lost says why in one line. When the task's starts are set up for a ``direction:``
and the task takes ``directions: one``, only the runs of the direction that earns more count.
Plain values in, plain values out: no rclpy.
"""

from dataclasses import dataclass
from typing import Any, Iterable

from sim_bridge.common.text import reason as failure_reason
from sim_bridge.grading.scenario import LOOP_DIRECTIONS, Scenario
from sim_bridge.grading.task_points import unearned_points


@dataclass(frozen=True)
class PointMarks:
    """One of a task's points over the runs that count: its marks, earned, and why lost."""

    point: str
    #: The point's share of the task's marks, and what its runs earn of it.
    marks: float
    earned: float
    runs: int
    #: (run name, reason) of each counted run that did not show the point.
    lost: tuple[tuple[str, str], ...] = ()
    #: The rule it is judged by (the handout's sentence, what is measured, the margin), or ''.
    rule: str = ''

    def why(self) -> str:
        """Return in one line why the point was lost ('' when earned in every run)."""
        if not self.lost:
            return ''
        run, reason = self.lost[0]
        if self.runs == 1:
            return reason
        return f'{reason} ({run}; lost in {len(self.lost)} of {self.runs} runs)'

    def as_dict(self) -> dict[str, Any]:
        """Return the point for a JSON report."""
        return {'point': self.point, 'marks': self.earned, 'max': self.marks,
                'runs': self.runs, 'lost': len(self.lost), 'why': self.why(), 'rule': self.rule}


@dataclass(frozen=True)
class TaskMarks:
    """One task's runs in a batch (of one student) and the marks they earn."""

    task: str
    #: The names of the task's scenarios in the batch, in the batch's order.
    scenarios: tuple[str, ...]
    #: The task's marks (its maximum), or None for scenarios that carry no marks.
    marks: float | None
    marking: str
    runs: int
    passed: int
    #: The handout's points, when the task is marked by them (else empty).
    points: tuple[PointMarks, ...] = ()
    #: The loop direction whose runs were marked (directions: one), or None.
    direction: str | None = None

    @property
    def title(self) -> str:
        """Return how tables name the task: 'task 1' for a number, else its label."""
        return f'task {self.task}' if self.task.isdigit() else self.task

    @property
    def earned(self) -> float:
        """Return the marks the runs earn (0 for a task without marks)."""
        if not self.marks or not self.runs:
            return 0.0
        if self.points:
            return sum(point.earned for point in self.points)
        if self.marking == 'proportional':
            return self.marks * self.passed / self.runs
        return self.marks if self.passed == self.runs else 0.0

    def share(self, runs: int, passed: int) -> tuple[float, float]:
        """
        Return (score, maximum) of one scenario's ``runs`` of the task, ``passed`` of them.

        The task's marks are split over its scenarios by their runs, so the scenarios' scores
        add up to :attr:`earned`; under ``marking: all`` a scenario scores only when the whole
        task passed.
        """
        if not self.marks or not self.runs:
            return 0.0, 0.0
        maximum = self.marks * runs / self.runs
        if self.marking == 'proportional':
            return self.marks * passed / self.runs, maximum
        return (maximum if self.passed == self.runs else 0.0), maximum

    def rule(self, own: bool = True) -> str:
        """
        Say in a line how the task's runs become its marks.

        ``own``: this student's rule, which names the direction their runs were marked on
        (``the clockwise starts``); else the class's, which says each student's direction
        counts.
        """
        if self.marks is None:
            return f'{self.title} carries no marks'
        if self.points:
            share = format_marks(self.marks / len(self.points))
            mine = ('' if not self.direction else f', the {self.direction} starts' if own
                    else ", the starts of each student's direction (the one earning more)")
            return (f'{self.title}: {format_marks(self.marks)} marks, {share} for each of its '
                    f'{len(self.points)} points, x the runs showing it{mine}')
        runs = f'{self.runs} runs' if self.runs != 1 else '1 run'
        if self.marking == 'proportional':
            return f'{self.title}: {format_marks(self.marks)} marks x runs passed / {runs}'
        every = f'all {runs} pass' if self.runs != 1 else 'its run passes'
        return f'{self.title}: {format_marks(self.marks)} marks when {every}'


def task_order(scenario: Scenario) -> tuple:
    """Return a sort key: tasks with marks by number then label, those without last."""
    task = scenario.task_name
    return (scenario.marks is None, not task.isdigit(), int(task) if task.isdigit() else 0,
            task)


def task_marks(scenarios: Iterable[Scenario], entries: Iterable[dict[str, Any]]
               ) -> list[TaskMarks]:
    """
    Return each task's marks from the run ``entries`` (``RunReport.as_dict``) of a batch.

    Tasks come in :func:`task_order`; a task's runs are the entries of its ``scenarios``.
    """
    scenarios = sorted(scenarios, key=task_order)
    counts: dict[str, list[int]] = {}
    for entry in entries:
        count = counts.setdefault(entry['scenario'], [0, 0])
        count[0] += 1
        count[1] += bool(entry['passed'])
    tasks: dict[str, list[Scenario]] = {}
    for scenario in scenarios:
        tasks.setdefault(scenario.task_name, []).append(scenario)
    result = []
    for name, members in tasks.items():
        runs = sum(counts.get(scenario.name, [0, 0])[0] for scenario in members)
        passed = sum(counts.get(scenario.name, [0, 0])[1] for scenario in members)
        task = TaskMarks(name, tuple(scenario.name for scenario in members),
                         members[0].marks, members[0].marking, runs, passed)
        if members[0].points and members[0].marks:
            task = marked_by_points(task, members, entries)
        result.append(task)
    return result


def marked_by_points(task: TaskMarks, members: list[Scenario],
                     entries: list[dict[str, Any]]) -> TaskMarks:
    """
    Return ``task`` marked by its scenarios' points over the run ``entries`` that count.

    With ``directions: one`` and starts set up for a direction, the runs that count are those
    of the direction whose runs earn the larger share of the points; on a tie, the direction
    whose runs passed their criteria more often (the criteria of a direction's starts check its
    loop direction: the way the student's node went), then the first of LOOP_DIRECTIONS; with
    those of scenarios set up for none.
    """
    groups: dict[str | None, list[str]] = {None: [scenario.name for scenario in members]}
    if members[0].directions == 'one' and any(scenario.direction for scenario in members):
        groups = {direction: [scenario.name for scenario in members
                              if scenario.direction in (direction, None)]
                  for direction in LOOP_DIRECTIONS}
    best: tuple[tuple[float, int], tuple[PointMarks, ...], str | None] | None = None
    for direction, names in groups.items():
        counted = [entry for entry in entries if entry['scenario'] in names]
        points = point_marks(task.marks, members[0].points, counted)
        rank = (sum(point.earned for point in points),
                sum(bool(entry['passed']) for entry in counted))
        if best is None or rank > best[0]:
            best = (rank, points, direction)
    return TaskMarks(task.task, task.scenarios, task.marks, task.marking, task.runs,
                     task.passed, best[1], best[2])


def point_marks(marks: float, point_set: str,
                entries: list[dict[str, Any]]) -> tuple[PointMarks, ...]:
    """
    Return each point of ``point_set`` over the run ``entries``: an equal share of ``marks``.

    A run without judged points (not submitted, or it could not start) loses each point for
    the reason it failed.
    """
    judged = [(entry.get('run', entry['scenario']),
               entry.get('points') or [point.as_dict() for point in unearned_points(
                   point_set, failure_reason(entry) or 'no points judged')])
              for entry in entries]
    named = unearned_points(point_set, '')
    share = marks / len(named)
    result = []
    for index, point in enumerate(named):
        lost = tuple((run, points[index]['reason']) for run, points in judged
                     if not points[index]['earned'])
        earned = share * (len(judged) - len(lost)) / len(judged) if judged else 0.0
        result.append(PointMarks(point.point, share, earned, len(judged), lost, point.rule))
    return tuple(result)


def total(tasks: Iterable[TaskMarks]) -> tuple[float, float]:
    """Return (marks earned, maximum) over the tasks that carry marks."""
    marked = [task for task in tasks if task.marks is not None]
    return sum(task.earned for task in marked), sum(task.marks for task in marked)


def format_marks(value: float) -> str:
    """Return marks as people write them: '2', '1.5', '0.19' (at most two decimals)."""
    return f'{value:.2f}'.rstrip('0').rstrip('.')


def summary(tasks: list[TaskMarks]) -> str:
    """Return a line of marks: 'marks 2.5/5 (task 1: 2/2, task 4: 0.5/3)', or '' for none."""
    marked = [task for task in tasks if task.marks is not None]
    if not marked:
        return ''
    earned, maximum = total(marked)
    return (f'marks {format_marks(earned)}/{format_marks(maximum)} ('
            + ', '.join(f'{task.title}: {format_marks(task.earned)}/{format_marks(task.marks)}'
                        for task in marked) + ')')


def as_dict(tasks: list[TaskMarks]) -> dict[str, Any]:
    """Return the marks for a JSON report: the total, the maximum and each task's."""
    earned, maximum = total(tasks)
    return {'total': earned, 'max': maximum, 'tasks': [
        {'task': task.task, 'scenarios': list(task.scenarios), 'marks': task.earned,
         'max': task.marks, 'marking': task.marking, 'runs': task.runs, 'passed': task.passed,
         'direction': task.direction, 'points': [point.as_dict() for point in task.points]}
        for task in tasks]}
