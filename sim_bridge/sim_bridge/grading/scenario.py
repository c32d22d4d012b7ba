"""
Scenario files for the grader: what to run, for how long, and what a pass is.

Scenario file format (YAML)
===========================

A scenario is a YAML mapping; every key not listed here is an error::

    description: wall_follow clockwise around the box    # optional free text
    task: 4                       # optional: the lab task it grades (a number or a label)
    marks: 3                      # optional: the task's marks (> 0), shared by its scenarios
    marking: proportional         # optional: how runs become marks: 'all' (default: every run
                                  # of the task passes, or none) or 'proportional'
    points: wall_follow           # optional: the handout's points of the task, each earning
                                  # its share of the marks (sim_bridge.task_points): one of
                                  # range_ahead, wander, regions, wall_follow, closest
    direction: clockwise          # optional: the loop the start is set up for (the target on
                                  # the robot's right: clockwise; on its left: counterclockwise)
    directions: one               # optional, per task: 'one' (default: the student's choice,
                                  # its better direction counts) or 'both' (every start counts)
    world: wall_follow_box        # a shipped world's name, or a world file's path
    nodes: [wall_follow]          # TARGETs run with the simulator: a console script, a module
                                  # or a file path.py[:ClassName]
    params:                       # optional: parameters per node name, as in a ROS params
      wall_follow:                # file ('sim_bridge' is the simulator's node); the value
        side: right               # $seed stands for each run's seed
        distance: 0.5
    duration: 76.2                # simulated seconds
    seeds: [1, 2, 3]              # one run per seed; or  seed: 1  (default 0)
    start: mirrored               # optional robot start: 'mirrored' (turned round on the
                                  # world's start: the target on its left) or [x, y, yaw]
    robot: turtlebot3_burger      # optional robot model instead of the world's (as --robot)
    remap: [/robot/scan:=/scan]   # optional ROS remapping rules for the nodes (as --remap):
                                  # FROM:=TO, or NODE:FROM:=TO for one node
    setpoint:                     # optional: the value a metric is measured against, whatever
      wall_distance_m: 0.5        # the node's own parameters are called (m)
    drive:                        # optional: the robot driven as from the teleop, segment by
      - {duration: 3, linear: 0.3}            # segment (sim_bridge.ros.drive): forward 3 s,
      - {duration: 2, angular: 0.8}           # turn left 2 s, forward until 0.4 m from
      - {duration: 15, linear: 0.2, until: {within_m: 0.4, of: cube}}  # the cube (<= 15 s)
    criteria:                     # every one must hold for a run to pass
      - len(node_errors) == 0
      - collisions == 0
      - laps <= -1
      - wall_distance_m.mae <= 0.10
      - all(turns_deg) > 90
      - printed_range_ahead: {max_error_m: 0.05, min_matched_fraction: 0.95}

Relative paths (a world file, a node file) are relative to the scenario file. The scenario's
name is the file name without ``.yaml``. A seed is an integer from 0 to MAX_SEED (2**63 - 1).

With ``points:``, a task's marks are its points' (:mod:`sim_bridge.marks`), each point earning
its share of the marks over the task's runs, whatever the criteria say; the criteria still say
whether each run passed. A task whose scenarios state a ``direction:`` is marked on the runs of
one direction, the one whose runs earn more (the handout lets the student choose), unless
``directions: both``.

``marks:`` are the marks of the scenario's ``task:`` (default: a task of its own, named after
the scenario): every scenario of a task states the same ``marks:`` and ``marking:``, and the
task's marks are earned over all of its scenarios' runs (:mod:`sim_bridge.grading.marks`). A
scenario without ``marks:`` is graded and reported, and counts in no total.

``setpoint: wall_distance_m`` is the distance (m) ``wall_distance_m.mae`` and ``.rms`` measure
the robot's wall distance against. Without it, the runner falls back to the value of a
``distance`` parameter of a node, if one has it.

When ``--node-override`` replaces a node (a student's node, with a node name and parameters of
its own), the scenario's parameters for the replaced node are given to every node it runs
under ``/**`` in the params file, as ROS does for a node whatever its name; a parameter the
student's node does not declare is ignored with a warning, as ROS ignores it.

Criteria
--------
``<value> <op> <number>`` where ``<op>`` is one of ``<  <=  ==  !=  >=  >`` and ``<value>`` a
metric of ``metrics.json`` (``collisions``; a nested one with a dot, ``wall_distance_m.mae``)
or a function of a list metric: ``min(turns_deg)``, ``max(...)``, ``len(...)``, ``all(...)``
(every entry satisfies the comparison; true for an empty list), ``any(...)``; ``abs(laps)``
for a number. The number may be ``inf`` or ``-inf``. Nothing is evaluated as Python. A metric
that has no value (null, e.g. no wall distance without a target) fails its criterion.

What a node prints on each scan (:mod:`sim_bridge.scoring.printed_values`) is a criterion of its
own, a mapping: ``printed_range_ahead``, ``printed_regions`` or ``printed_closest``, with
``max_error_m`` (m, the worst error of a printed value allowed) and ``min_matched_fraction``
(the share of the scans a line must give the value for, 0 to 1); ``printed_closest`` may add
``max_bearing_error_deg`` (deg), checked on the lines that print a bearing. Its result is one
line: the worst printed value, where, and the truth. The run scores the printed values a
scenario's criteria name (``printed.<kind>.worst_error_m`` and the rest are metrics too).
"""

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
import math
import os
from pathlib import Path
import re
from typing import Any, Callable

from sim_bridge.common.values import described, is_number_not_nan
from sim_bridge.common.yaml_loader import load_yaml, read_text
from sim_bridge.grading.criteria import (
    Criterion, CriterionResult, format_value, parse_criterion, parse_printed_criterion,
    PrintedCriterion)
from sim_bridge.grading.task_points import POINT_SETS
from sim_bridge.ros.drive import DriveError, parse_drive, Segment
from sim_bridge.runner.options import EVERY_NODE, is_seed, MAX_SEED, remap_problem
from sim_bridge.runner.targets import split_target, target_name
from sim_bridge.scoring.printed_values import KINDS as PRINTED_KINDS
import yaml

SCENARIO_SUFFIX = '.yaml'
#: A parameter value replaced by each run's seed, so a node's own randomness follows it.
SEED_PLACEHOLDER = '$seed'
#: The longest simulated run (s): a day. A lab's run lasts minutes; ``duration: 1e9`` (a typo,
#: or milliseconds) would hold a batch for months of wall time.
MAX_DURATION_S = 86400.0
#: What a NODE of ``--node-override NODE=TARGET`` can be: a node's name, no path.
_OVERRIDE_NODE = re.compile(r'[\w.-]+')
_KEYS = ('description', 'world', 'nodes', 'params', 'duration', 'seed', 'seeds', 'start',
         'robot', 'remap', 'setpoint', 'drive', 'criteria', 'task', 'marks', 'marking', 'points',
         'direction', 'directions')
#: How a task's runs become marks: all must pass for its marks, or marks in proportion.
MARKINGS = ('all', 'proportional')
#: The loops a wall-following start is set up for, and which of them a task marks.
LOOP_DIRECTIONS = ('clockwise', 'counterclockwise')
DIRECTION_CHOICES = ('one', 'both')
#: What a scenario's ``setpoint:`` can set, and the unit of each.
SETPOINTS = {'wall_distance_m': 'm'}
_REQUIRED = ('world', 'nodes', 'duration', 'criteria')


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names the file and the field."""


#: Makes the error of one field of a scenario: fail(FIELD or None, PROBLEM).
Fail = Callable[[str | None, str], ScenarioError]


@dataclass(frozen=True)
class ScenarioRun:
    """One run of a scenario: the scenario with one of its seeds."""

    scenario: 'Scenario'
    seed: int

    @property
    def name(self) -> str:
        """Return ``<scenario>/seed_<n>``, also the run's output folder below the grade's."""
        return f'{self.scenario.name}/seed_{self.seed}'

    @property
    def params(self) -> dict[str, dict[str, Any]]:
        """Return the node parameters with ``$seed`` replaced by this run's seed."""
        return {node: {name: self.seed if value == SEED_PLACEHOLDER else value
                       for name, value in values.items()}
                for node, values in self.scenario.params.items()}


@dataclass(frozen=True)
class Scenario:
    """
    A loaded scenario file (see the module docstring for the format).

    ``duration_s`` in s; ``start`` is None, 'mirrored' or (x m, y m, yaw rad); ``params`` maps
    node names to parameter values; ``world`` and file ``nodes`` are resolved paths or names;
    ``robot`` a robot model or None; ``remap`` ROS remapping rules; ``setpoint`` maps metrics
    of SETPOINTS to the value (m) they measure against; ``drive`` the segments the runner's
    teleop drives the robot by (sim_bridge.ros.drive), none when empty; ``task`` the lab task it
    grades (None: a task of its own), ``marks`` that task's marks (None: no marks) and
    ``marking`` one of MARKINGS; ``points`` the task's point set (task_points.POINT_SETS) or
    None, ``direction`` the loop its start is for (LOOP_DIRECTIONS) or None, ``directions``
    one of DIRECTION_CHOICES.
    """

    name: str
    path: Path | None
    world: str
    nodes: tuple[str, ...]
    duration_s: float
    criteria: tuple[Criterion | PrintedCriterion, ...]
    seeds: tuple[int, ...] = (0,)
    params: dict[str, dict[str, Any]] = field(default_factory=dict)
    start: str | tuple[float, float, float] | None = None
    description: str = ''
    robot: str | None = None
    remap: tuple[str, ...] = ()
    setpoint: dict[str, float] = field(default_factory=dict)
    drive: tuple[Segment, ...] = ()
    task: str | None = None
    marks: float | None = None
    marking: str = MARKINGS[0]
    points: str | None = None
    direction: str | None = None
    directions: str = DIRECTION_CHOICES[0]

    @property
    def task_name(self) -> str:
        """Return the task the scenario grades: its ``task:``, or the scenario's own name."""
        return self.task if self.task is not None else self.name

    def runs(self) -> list[ScenarioRun]:
        """Return one run per seed."""
        return [ScenarioRun(self, seed) for seed in self.seeds]

    @property
    def printed(self) -> tuple[str, ...]:
        """Return the printed values (printed_values.KINDS) the criteria look at."""
        kinds = {criterion.kind if isinstance(criterion, PrintedCriterion) else
                 criterion.path[1] if criterion.path[:1] == ('printed',)
                 and len(criterion.path) > 1 else None for criterion in self.criteria}
        return tuple(kind for kind in PRINTED_KINDS if kind in kinds)

    def judge(self, metrics: Mapping[str, Any]) -> list[CriterionResult]:
        """Judge every criterion on one run's metrics."""
        return [criterion.evaluate(metrics) for criterion in self.criteria]

    def absolute(self) -> 'Scenario':
        """Return the scenario with relative world and node file paths made absolute."""
        return replace(self, world=_resolve(self.world, Path.cwd(), SCENARIO_SUFFIX),
                       nodes=tuple(_resolve(node, Path.cwd(), '.py') for node in self.nodes))

    def with_node_override(self, override: str) -> 'Scenario':
        """
        Return the scenario with a node replaced, e.g. by a student's file.

        ``override`` is ``TARGET`` or ``NODE=TARGET``. With ``NODE=``, the nodes named NODE
        (by console script, module or file name) are replaced and a scenario without one is
        returned unchanged. Without it, the nodes of the same name as TARGET are replaced, or
        else the only node; a scenario with several nodes and none of that name is an error.
        An override naming an existing file is that file, '=' or not (``/tmp/a=b/wf.py``);
        one that could be read either way is an error, as is one that is neither. The
        replaced nodes' parameters go to every node (EVERY_NODE): the new node's name is
        its own.
        """
        node, equals, target = split_override(override)
        wanted = node if equals else target_name(target)
        matching = [index for index, current in enumerate(self.nodes)
                    if target_name(current) == wanted]
        if not matching and not equals:
            if len(self.nodes) != 1:
                raise ScenarioError(
                    f"--node-override '{override}': scenario {self.name} runs "
                    f"{', '.join(self.nodes)}; say which one to replace with NODE={target}")
            matching = [0]
        nodes = list(self.nodes)
        params = dict(self.params)
        for index in matching:
            replaced = params.pop(target_name(nodes[index]), {})
            params[EVERY_NODE] = {**params.get(EVERY_NODE, {}), **replaced}
            nodes[index] = target
        if not params.get(EVERY_NODE, True):
            del params[EVERY_NODE]  # a replaced node without parameters
        return replace(self, nodes=tuple(nodes), params=params)


def with_node_overrides(scenarios: list[Scenario], overrides: list[str]) -> list[Scenario]:
    """
    Apply each ``--node-override`` to every scenario (:meth:`Scenario.with_node_override`).

    ScenarioError when a ``NODE=TARGET`` override names a node no scenario runs: a misspelt
    NODE would otherwise grade the scenarios' own node in silence.
    """
    names = sorted({target_name(target) for scenario in scenarios for target in scenario.nodes})
    for override in overrides:
        node, equals, _ = split_override(override)
        if equals and node not in names:
            raise ScenarioError(f"--node-override '{override}': no scenario runs a node '{node}' "
                                f"(they run {', '.join(names)})")
        scenarios = [scenario.with_node_override(override) for scenario in scenarios]
    return scenarios


def split_override(override: str) -> tuple[str, bool, str]:
    """
    Read ``--node-override``: return (NODE, whether NODE= was given, TARGET).

    ScenarioError when it is empty, or neither an existing file nor ``NODE=TARGET`` with a
    node name for NODE, or both an existing file and ``NODE=`` an existing file.
    """
    label = f"--node-override '{override}'"
    node, equals, target = override.partition('=')
    named = bool(equals and target and _OVERRIDE_NODE.fullmatch(node))
    if Path(split_target(override)[0]).is_file():
        if named and Path(split_target(target)[0]).is_file():
            raise ScenarioError(f'{label} is ambiguous: both the file {override} and node {node} '
                                f'replaced by {target} exist; write ./{override} for the file')
        return '', False, override
    if not equals:
        if not override:
            raise ScenarioError(f'{label}: expected TARGET or NODE=TARGET')
        return '', False, override
    if not named:
        raise ScenarioError(f'{label}: no such file, and not NODE=TARGET (NODE a node name '
                            'without a path, TARGET a console script, module or file)')
    return node, True, target


def load_scenario(path: str | os.PathLike) -> Scenario:
    """Load and validate a scenario file; ScenarioError names the file and the field."""
    path = Path(path)
    label = str(path)
    try:
        data = load_yaml(read_text(path))
    except OSError as error:
        raise ScenarioError(f'{label}: cannot read: {error.strerror or error}') from None
    except UnicodeDecodeError as error:  # e.g. a file saved as Latin-1
        raise ScenarioError(f'{label}: not UTF-8 text: {error.reason} at byte {error.start}'
                            ) from None
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(error, 'problem', None) or error
        raise ScenarioError(f'{label}: invalid YAML{where}: {problem}') from None
    return scenario_from_dict(data, path.stem, path)


def scenario_from_dict(data: Any, name: str, path: Path | None = None) -> Scenario:
    """Validate a parsed scenario called ``name``, read from the file ``path`` if any."""
    label = str(path) if path is not None else f'<scenario {name}>'
    base = path.parent if path is not None else None

    def fail(field_name: str | None, problem: str) -> ScenarioError:
        return ScenarioError(': '.join(part for part in (label, field_name, problem) if part))

    if not isinstance(data, Mapping):
        raise fail(None, f'must be a mapping of keys, got {described(data)}')
    for key in data:
        if key not in _KEYS:
            raise fail(str(key), f"unknown key; expected one of {', '.join(_KEYS)}")
    for key in _REQUIRED:
        if key not in data:
            raise fail(key, 'missing')
    if 'seed' in data and 'seeds' in data:
        raise fail('seeds', "give either 'seed' or 'seeds', not both")
    world, nodes = _world_and_nodes(data, fail)
    params = _params(data, fail)
    setpoint = _setpoint(data, fail)
    description, task, marks, marking = _grading(data, fail)
    return Scenario(name=name, path=path,
                    world=_resolve(world, base, SCENARIO_SUFFIX),
                    nodes=tuple(_resolve(node, base, '.py') for node in nodes),
                    duration_s=_duration(data, fail), criteria=_criteria(data, fail),
                    seeds=_seeds(data, fail),
                    params={str(node): dict(values) for node, values in params.items()},
                    start=_start(data, fail), description=description,
                    robot=_robot(data, fail), remap=_remap(data, fail),
                    setpoint={str(metric): float(value) for metric, value in setpoint.items()},
                    drive=_drive(data, fail), task=str(task).strip() if task is not None else None,
                    marks=float(marks) if marks is not None else None, marking=marking,
                    **_points(data, fail))


def _world_and_nodes(data: Mapping[Any, Any], fail: Fail) -> tuple[str, list[str]]:
    """Return the scenario's world and its list of TARGETs."""
    world = data['world']
    if not isinstance(world, str) or not world:
        raise fail('world', f'must be a world name or path, got {described(world)}')
    nodes = data['nodes']
    if isinstance(nodes, str):
        nodes = [nodes]
    if not isinstance(nodes, list) or not nodes:
        raise fail('nodes', f'must be a non-empty list of TARGETs, got {described(nodes)}')
    for index, node in enumerate(nodes):
        if not isinstance(node, str) or not node:
            raise fail(f'nodes[{index}]', f'must be a TARGET text, got {described(node)}')
    return world, nodes


def _duration(data: Mapping[Any, Any], fail: Fail) -> float:
    """Return the run length (s of simulated time)."""
    duration = data['duration']
    if not is_number_not_nan(duration) or not 0 < duration <= MAX_DURATION_S:
        raise fail('duration', f'must be a positive number of seconds, at most '
                   f'{MAX_DURATION_S:g} (a day), got {duration!r}')
    return float(duration)


def _seeds(data: Mapping[Any, Any], fail: Fail) -> tuple[int, ...]:
    """Return the runs' seeds (``seed:`` or ``seeds:``, default 0)."""
    seeds = data.get('seeds', [data.get('seed', 0)])
    if not isinstance(seeds, list) or not seeds:
        raise fail('seeds', f'must be a non-empty list of integers, got {described(seeds)}')
    for index, seed in enumerate(seeds):
        if not is_seed(seed):
            field_name = f'seeds[{index}]' if 'seeds' in data else 'seed'
            raise fail(field_name, f'must be a non-negative integer up to {MAX_SEED} (a ROS '
                       f'integer parameter is int64), got {seed!r}')
    if len(set(seeds)) != len(seeds):
        raise fail('seeds', f'has repeated seeds: {seeds}')
    return tuple(seeds)


def _params(data: Mapping[Any, Any], fail: Fail) -> Mapping[Any, Any]:
    """Return the parameters per node name."""
    params = data.get('params') or {}
    if not isinstance(params, Mapping):
        raise fail('params', f'must map node names to parameters, got {described(params)}')
    for node, values in params.items():
        if not isinstance(values, Mapping):
            raise fail(f'params.{node}', f'must map parameter names to values, '
                       f'got {described(values)}')
        for parameter, value in values.items():
            if not _is_parameter_value(value):
                raise fail(f'params.{node}.{parameter}', 'must be a bool, number, text or a '
                           f'list of one of them, got {described(value)}')
    return params


def _start(data: Mapping[Any, Any], fail: Fail) -> Any:
    """Return the robot's start: None, 'mirrored' or (x m, y m, yaw rad)."""
    start = data.get('start')
    if start is not None and start != 'mirrored':
        if not (isinstance(start, list) and len(start) == 3
                and all(map(is_number_not_nan, start))):
            raise fail('start', f"must be 'mirrored' or [x, y, yaw], got {start!r}")
        start = tuple(float(value) for value in start)
    return start


def _criteria(data: Mapping[Any, Any], fail: Fail) -> tuple[Any, ...]:
    """Return the scenario's criteria, each parsed."""
    criteria = data['criteria']
    if not isinstance(criteria, list) or not criteria:
        raise fail('criteria', f'must be a non-empty list of criteria, got {described(criteria)}')
    parsed = []
    for index, text in enumerate(criteria):
        try:
            parsed.append(parse_printed_criterion(text) if isinstance(text, Mapping)
                          else parse_criterion(text))
        except ValueError as error:
            raise fail(f'criteria[{index}]', str(error)) from None
    return tuple(parsed)


def _robot(data: Mapping[Any, Any], fail: Fail) -> str | None:
    """Return the robot model spawned instead of the world's, or None."""
    robot = data.get('robot')
    if robot is not None and not (isinstance(robot, str) and robot):
        raise fail('robot', f'must be a robot model name, got {described(robot)}')
    return robot


def _remap(data: Mapping[Any, Any], fail: Fail) -> tuple[str, ...]:
    """Return the ROS remapping rules for the target nodes."""
    remap = data.get('remap') or []
    if isinstance(remap, str):
        remap = [remap]
    if not isinstance(remap, list):
        raise fail('remap', f'must be a list of remapping rules, got {described(remap)}')
    for index, rule in enumerate(remap):
        problem = remap_problem(rule)
        if problem is not None:
            raise fail(f'remap[{index}]', problem)
    return tuple(remap)


def _setpoint(data: Mapping[Any, Any], fail: Fail) -> Mapping[Any, Any]:
    """Return the setpoints per metric (in their units)."""
    setpoint = data.get('setpoint') or {}
    if not isinstance(setpoint, Mapping):
        raise fail('setpoint', f'must map metrics to values, e.g. wall_distance_m: 0.5, got '
                   f'{described(setpoint)}')
    for metric, value in setpoint.items():
        if metric not in SETPOINTS:
            raise fail(f'setpoint.{metric}', f"unknown; setpoints are {', '.join(SETPOINTS)}")
        if not is_number_not_nan(value) or not math.isfinite(value):
            raise fail(f'setpoint.{metric}', f'must be a number ({SETPOINTS[metric]}), got '
                       f'{described(value)}')
    return setpoint


def _drive(data: Mapping[Any, Any], fail: Fail) -> tuple[Segment, ...]:
    """Return the teleop's drive segments (empty: no driving)."""
    drive = ()
    if data.get('drive') is not None:
        try:
            drive = parse_drive(data['drive'])
        except DriveError as error:
            raise fail(None, str(error)) from None
    return drive


def _grading(data: Mapping[Any, Any], fail: Fail) -> tuple[str, Any, Any, str]:
    """Return the description, task, marks and marking."""
    description = data.get('description', '')
    if not isinstance(description, str):
        raise fail('description', f'must be text, got {described(description)}')
    task = data.get('task')
    if task is not None and not (isinstance(task, (int, str)) and not isinstance(task, bool)
                                 and str(task).strip()):
        raise fail('task', f'must be a task number or label, e.g. 1 or wall_follow, got '
                   f'{described(task)}')
    marks = data.get('marks')
    if marks is not None and not (is_number_not_nan(marks) and 0 < marks < float('inf')):
        raise fail('marks', f'must be a positive number, got {described(marks)}')
    marking = data.get('marking', MARKINGS[0])
    if marking not in MARKINGS:
        raise fail('marking', f"must be one of {', '.join(MARKINGS)} (all: every run passes for "
                   'the marks; proportional: marks x runs passed / runs), '
                   f'got {described(marking)}')
    if 'marking' in data and marks is None:
        raise fail('marking', 'says how runs become marks, but the scenario has no marks:')
    return description, task, marks, marking


def _points(data: Mapping[Any, Any], fail: Fail) -> dict[str, Any]:
    """Return the points, the start's direction and the directions marked (Scenario's keys)."""
    for key, allowed in (('points', POINT_SETS), ('direction', LOOP_DIRECTIONS),
                         ('directions', DIRECTION_CHOICES)):
        if data.get(key) is not None and data[key] not in allowed:
            raise fail(key, f"must be one of {', '.join(allowed)}, got {described(data[key])}")
    return {'points': data.get('points'), 'direction': data.get('direction'),
            'directions': data.get('directions') or DIRECTION_CHOICES[0]}


def load_scenarios(paths: list[str | os.PathLike]) -> list[Scenario]:
    """Load scenario files; a folder stands for every ``*.yaml`` in it, sorted by name."""
    files = []
    for path in map(Path, paths):
        if path.is_dir():
            found = sorted(path.glob(f'*{SCENARIO_SUFFIX}'))
            if not found:
                raise ScenarioError(f'{path}: no {SCENARIO_SUFFIX} scenario files in it')
            files += found
        else:
            files.append(path)
    # A run's outputs are named after its scenario (<out>/<scenario>/seed_<n>): a file given
    # twice (a.yaml and a folder holding it) runs once, two files of one name are refused.
    named: dict[str, Path] = {}
    for file in files:
        other = named.setdefault(file.stem, file)
        if other != file and other.resolve() != file.resolve():
            raise ScenarioError(f'{file}: its name {file.stem!r} is also the name of {other} '
                                '(runs are named after their scenario); rename one')
    scenarios = [load_scenario(file) for file in named.values()]
    check_tasks(scenarios)
    return scenarios


def check_tasks(scenarios: list[Scenario]) -> None:
    """
    Refuse scenarios of one task that disagree on its ``marks:`` or ``marking:``.

    A task's marks are earned over all its scenarios' runs: two values would make its maximum
    depend on which scenarios a batch grades. ScenarioError names both files.
    """
    first: dict[str, Scenario] = {}
    for scenario in scenarios:
        other = first.setdefault(scenario.task_name, scenario)
        for key in ('marks', 'marking', 'points', 'directions'):
            mine, theirs = getattr(scenario, key), getattr(other, key)
            if mine != theirs:
                raise ScenarioError(
                    f'{scenario.path or scenario.name}: {key}: {_shown(mine)}, but '
                    f'{other.path or other.name} of the same task {scenario.task_name!r} says '
                    f'{_shown(theirs)}; a task has one {key}')


def _shown(value: Any) -> str:
    return 'none' if value is None else format_value(value) if isinstance(value, float) \
        else str(value)


def _resolve(reference: str, base: Path | None, suffix: str) -> str:
    """Anchor a file reference (``path/x.py:Class``, ``../w.yaml``) at the scenario's folder."""
    where, class_name = split_target(reference, base)
    if base is None or not (where.endswith(suffix) or '/' in where) or Path(where).is_absolute():
        return reference
    return str(base / where) + (f':{class_name}' if class_name else '')


def _is_parameter_value(value: Any) -> bool:
    scalar = (bool, int, float, str)
    if isinstance(value, list):
        return all(isinstance(item, scalar) for item in value)
    return isinstance(value, scalar)
