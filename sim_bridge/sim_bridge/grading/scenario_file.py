"""
The YAML scenario file's schema (format: sim_bridge.scenario), as a pydantic model.

:func:`validate_scenario_file` checks a parsed file against :class:`ScenarioFile` and returns
it with its defaults; a file that breaks a rule raises :class:`ScenarioError` naming the file,
the key (``nodes[1]``, ``params.wall_follow.distance``) and what is wrong. What needs more
than a value of the file (its criteria read, its remapping rules, its drive plan, the seeds
together) is checked by sim_bridge.scenario.
"""

from collections.abc import Mapping
import math
from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, ValidationError
from sim_bridge.common.values import described, is_number_not_nan, unknown_key_problem
from sim_bridge.runner.options import is_seed, MAX_SEED

#: The longest simulated run (s): a day. A lab's run lasts minutes; ``duration: 1e9`` (a typo,
#: or milliseconds) would hold a batch for months of wall time.
MAX_DURATION_S = 86400.0
#: How a task's runs become marks: all must pass for its marks, or marks in proportion.
MARKINGS = ('all', 'proportional')
#: What a scenario's ``setpoint:`` can set, and the unit of each.
SETPOINTS = {'wall_distance_m': 'm'}


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names the file and the field."""


def _check(test, problem):
    """Return a validator passing values ``test`` accepts; ``problem(value)`` says why not."""
    def check(value: Any) -> Any:
        if not test(value):
            raise ValueError(problem(value))
        return value
    return BeforeValidator(check)


def _one_or_list(value: Any) -> Any:
    """Return a text as a list of that text (``nodes: wall_follow``), anything else as is."""
    return [value] if isinstance(value, str) else value


def _is_parameter_value(value: Any) -> bool:
    scalar = (bool, int, float, str)
    if isinstance(value, list):
        return all(isinstance(item, scalar) for item in value)
    return isinstance(value, scalar)


def _seed_problem(value: Any) -> str:
    return (f'must be a non-negative integer up to {MAX_SEED} (a ROS integer parameter is '
            f'int64), got {value!r}')


Text = Annotated[str, _check(lambda value: isinstance(value, str) and value != '',
                             lambda value: f'must be a TARGET text, got {described(value)}')]
Seed = Annotated[int, _check(is_seed, _seed_problem)]
ParameterValue = Annotated[Any, _check(
    _is_parameter_value, lambda value: 'must be a bool, number, text or a list of one of them, '
    f'got {described(value)}')]
Parameters = Annotated[dict[str, ParameterValue], _check(
    lambda value: isinstance(value, Mapping),
    lambda value: f'must map parameter names to values, got {described(value)}')]
SetpointName = Annotated[str, _check(
    lambda name: name in SETPOINTS,
    lambda name: f"unknown; setpoints are {', '.join(SETPOINTS)}")]


class ScenarioFile(BaseModel):
    """A whole scenario file (its keys are these fields, no others)."""

    model_config = ConfigDict(extra='forbid', frozen=True)

    description: Annotated[str, _check(lambda value: isinstance(value, str),
                                       lambda value: f'must be text, got {described(value)}')] = ''
    world: Annotated[str, _check(lambda value: isinstance(value, str) and value != '',
                                 lambda value: 'must be a world name or path, got '
                                 f'{described(value)}')]
    nodes: Annotated[list[Text], _check(
        lambda value: isinstance(value, list) and value != [],
        lambda value: f'must be a non-empty list of TARGETs, got {described(value)}'),
        BeforeValidator(_one_or_list)]
    params: Annotated[dict[str, Parameters], _check(
        lambda value: isinstance(value, Mapping),
        lambda value: f'must map node names to parameters, got {described(value)}'),
        BeforeValidator(lambda value: value or {})] = {}
    duration: Annotated[float, _check(
        lambda value: is_number_not_nan(value) and 0 < value <= MAX_DURATION_S,
        lambda value: f'must be a positive number of seconds, at most {MAX_DURATION_S:g} '
        f'(a day), got {value!r}')]
    seed: Seed | None = None
    seeds: Annotated[list[Seed], _check(
        lambda value: isinstance(value, list) and value != [],
        lambda value: f'must be a non-empty list of integers, got {described(value)}'
    )] | None = None
    start: Annotated[str | tuple[float, float, float] | None, _check(
        lambda value: value is None or value == 'mirrored' or (
            isinstance(value, list) and len(value) == 3 and all(map(is_number_not_nan, value))),
        lambda value: f"must be 'mirrored' or [x, y, yaw], got {value!r}")] = None
    robot: Annotated[str | None, _check(
        lambda value: value is None or (isinstance(value, str) and value != ''),
        lambda value: f'must be a robot model name, got {described(value)}')] = None
    remap: Annotated[list[Any], _check(
        lambda value: isinstance(value, list),
        lambda value: f'must be a list of remapping rules, got {described(value)}'),
        BeforeValidator(lambda value: _one_or_list(value or []))] = []
    setpoint: Annotated[dict[SetpointName, Annotated[float, _check(
        lambda value: is_number_not_nan(value) and math.isfinite(value),
        lambda value: f'must be a number (m), got {described(value)}')]], _check(
        lambda value: isinstance(value, Mapping),
        lambda value: 'must map metrics to values, e.g. wall_distance_m: 0.5, got '
        f'{described(value)}'), BeforeValidator(lambda value: value or {})] = {}
    drive: Any = None
    criteria: Annotated[list[Any], _check(
        lambda value: isinstance(value, list) and value != [],
        lambda value: f'must be a non-empty list of criteria, got {described(value)}')]

    # The handout's points, the start's loop direction and the directions marked: read by
    # sim_bridge.grading.scenario (they name its tables).
    points: Any = None
    direction: Any = None
    directions: Any = None
    # (pydantic runs the validators of one annotation last first: the check, then the text.)
    task: Annotated[str | None, BeforeValidator(
        lambda value: value if value is None else str(value).strip()), _check(
        lambda value: value is None or isinstance(value, (int, str))
        and not isinstance(value, bool) and str(value).strip() != '',
        lambda value: 'must be a task number or label, e.g. 1 or wall_follow, got '
        f'{described(value)}')] = None
    marks: Annotated[float | None, _check(
        lambda value: value is None or (is_number_not_nan(value) and 0 < value < math.inf),
        lambda value: f'must be a positive number, got {described(value)}')] = None
    marking: Annotated[str, _check(
        lambda value: value in MARKINGS,
        lambda value: f"must be one of {', '.join(MARKINGS)} (all: every run passes for the "
        f'marks; proportional: marks x runs passed / runs), got {described(value)}')] = MARKINGS[0]


def validate_scenario_file(data: Any, label: str) -> ScenarioFile:
    """Return the scenario ``data`` (parsed YAML) as a ScenarioFile; ScenarioError if not."""
    if not isinstance(data, Mapping):
        raise ScenarioError(f'{label}: must be a mapping of keys, got {described(data)}')
    if 'seed' in data and 'seeds' in data:
        raise ScenarioError(f"{label}: seeds: give either 'seed' or 'seeds', not both")
    try:
        return ScenarioFile.model_validate(data)
    except ValidationError as error:
        raise _scenario_error(error.errors(), label) from None


def _scenario_error(errors: list[dict[str, Any]], label: str) -> ScenarioError:
    """Return the ScenarioError of pydantic's ``errors``: unknown keys, missing, then values."""
    order = {'extra_forbidden': 0, 'missing': 1}
    error = min(errors, key=lambda item: order.get(item['type'], 2))
    where = ''
    for part in error['loc']:
        if part == '[key]':  # a mapping's key was refused: the key names it
            continue
        where += f'[{part}]' if isinstance(part, int) else f'.{part}' if where else str(part)
    if error['type'] == 'value_error':
        problem = str(error['ctx']['error'])
    elif error['type'] == 'extra_forbidden':
        problem = unknown_key_problem(error['loc'][-1], list(ScenarioFile.model_fields))
    else:
        problem = 'missing' if error['type'] == 'missing' else error['msg']
    return ScenarioError(': '.join(part for part in (label, where, problem) if part))
