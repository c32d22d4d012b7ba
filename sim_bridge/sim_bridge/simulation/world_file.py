"""
The YAML world file's schema (format: sim_bridge.simulation.world), as pydantic models.

:func:`validate_world_file` checks a parsed file against :class:`WorldFile` and returns it
with every default filled in; a file that breaks a rule raises :class:`WorldError` naming the
file, the entry (``obstacles[2] (box_a)``), the key and what is wrong. The models hold what a
file may say; what needs more than the file (models on disk, unique names, where the robot
stands) is checked by sim_bridge.simulation.world.
"""

from collections.abc import Mapping
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError
from sim_bridge.common.values import is_finite_number, unknown_key_problem, with_type

DEFAULT_ROBOT_MODEL = 'lab_robot'
DEFAULT_WALL_THICKNESS = 0.15
DEFAULT_WALL_HEIGHT = 1.0
#: Largest size, radius, length or height (m) a world file may give: a lab, not a continent.
MAX_SIZE_M = 1000.0
#: Largest distance (m) from the origin of a position, along x, y or z, a world file may give.
MAX_COORDINATE_M = 1000.0
OBSTACLE_TYPES = ('cube', 'cylinder', 'sphere', 'model')
#: What a missing key's message adds, by key.
_MISSING_HINTS = {'pose': 'give [x, y] or [x, y, yaw]', 'model': 'name a model folder',
                  'name': 'every obstacle has a unique name',
                  'end': "a wall needs 'start' and 'end' (or 'room')",
                  'start': "a wall needs 'start' and 'end' (or 'room')"}


class WorldError(ValueError):
    """A world file that cannot be used; says which file, entry and field, and why."""

    def __init__(self, file: str, entry: str | None, field_name: str | None,
                 problem: str) -> None:
        self.file = file
        self.entry = entry
        self.field = field_name
        self.problem = problem
        parts = [file, entry, repr(field_name) if field_name else None, problem]
        super().__init__(': '.join(part for part in parts if part))


def _within_limits(numbers: list, value: Any, sizes: bool) -> None:
    """Fail unless every number is a lab's: a size or a position in metres (see module)."""
    if sizes and any(number > MAX_SIZE_M for number in numbers):
        raise ValueError(f'must be at most {MAX_SIZE_M:g} m (sizes are in metres), got '
                         f'{value!r}')
    if not sizes and any(abs(number) > MAX_COORDINATE_M for number in numbers):
        raise ValueError(f'must be within ±{MAX_COORDINATE_M:g} m of the origin (positions are '
                         f'in metres), got {value!r}')


def numbers(count: int, positions: int | None = None):
    """Return a validator of ``count`` finite numbers, the first ``positions`` positions (m)."""
    def check(value: Any) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != count \
                or not all(is_finite_number(item) for item in value):
            raise ValueError(f'must be {count} finite numbers, got {value!r}')
        _within_limits(value[:positions], value, sizes=False)
        return tuple(float(item) for item in value)
    return BeforeValidator(check)


def sizes(count: int):
    """Return a validator of ``count`` lengths (m), each positive and at most MAX_SIZE_M."""
    def check(value: Any) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != count \
                or not all(is_finite_number(item) and item > 0 for item in value):
            raise ValueError(f'must be {count} positive finite numbers, got {value!r}')
        _within_limits(value, value, sizes=True)
        return tuple(float(item) for item in value)
    return BeforeValidator(check)


def _position(value: Any) -> float:
    if not is_finite_number(value):
        raise ValueError(f'must be a finite number, got {value!r}')
    _within_limits([value], value, sizes=False)
    return float(value)


def _size(value: Any) -> float:
    if not is_finite_number(value):
        raise ValueError(f'must be a finite number, got {value!r}')
    if value <= 0:
        raise ValueError(f'must be a positive number, got {value!r}')
    _within_limits([value], value, sizes=True)
    return float(value)


def _pose(value: Any) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) not in (2, 3):
        raise ValueError(f'must be [x, y] or [x, y, yaw], got {value!r}')
    x, y, *yaw = numbers(len(value), positions=2).func(value)
    return (x, y, *yaw) if yaw else (x, y, 0.0)


def _text(what: str, empty: bool = True):
    """Return a validator of text (non-empty unless ``empty``); ``what`` names it in errors."""
    def check(value: Any) -> str:
        if not isinstance(value, str) or (not empty and not value):
            raise ValueError(f'must be {what}, got {value!r}' if not empty
                             else f'must be {what}, got {with_type(value)}')
        return value
    return BeforeValidator(check)


Position = Annotated[float, BeforeValidator(_position)]
Size = Annotated[float, BeforeValidator(_size)]
#: x, y (m) and yaw (rad, 0 when not given) of a place on the floor.
Pose = Annotated[tuple[float, float, float], BeforeValidator(_pose)]
Point = Annotated[tuple[float, float], numbers(2)]
ObstacleName = Annotated[str, _text('text')]
ModelName = Annotated[str, BeforeValidator(
    lambda value: value if isinstance(value, str) and value else _fail(
        f'must be a model name, got {with_type(value)}'))]


def _fail(problem: str):
    raise ValueError(problem)


class _Entry(BaseModel):
    """A mapping of a world file: its keys are these fields, no others."""

    model_config = ConfigDict(extra='forbid', frozen=True)


class Floor(_Entry):
    """The floor: a rectangle of ``size`` (x, y in m) centred on the origin, or endless."""

    size: Annotated[tuple[float, float], sizes(2)] | None = None


class Robot(_Entry):
    """The robot's model (a model folder's name) and its start pose."""

    model: ModelName = DEFAULT_ROBOT_MODEL
    pose: Pose = (0.0, 0.0, 0.0)


class Wall(_Entry):
    """One straight wall from ``start`` to ``end``, or the four walls of a ``room``."""

    name: Annotated[str, _text('a non-empty text', empty=False)] | None = None
    start: Point | None = None
    end: Point | None = None
    room: Annotated[tuple[float, float], sizes(2)] | None = None
    center: Point | None = None
    thickness: Size = DEFAULT_WALL_THICKNESS
    height: Size = DEFAULT_WALL_HEIGHT


class _Obstacle(_Entry):
    name: ObstacleName
    pose: Pose
    #: Height of the centre (a primitive) or of the origin (a model), m; None: on the floor.
    z: Position | None = None


class Cube(_Obstacle):
    """A box of ``size`` (x, y, z in m)."""

    type: Literal['cube']  # noqa: A003 - the file's key
    size: Annotated[tuple[float, float, float], sizes(3)]


class Cylinder(_Obstacle):
    """An upright cylinder (m)."""

    type: Literal['cylinder']  # noqa: A003 - the file's key
    radius: Size
    length: Size


class Sphere(_Obstacle):
    """A ball (m)."""

    type: Literal['sphere']  # noqa: A003 - the file's key
    radius: Size


class PlacedModel(_Obstacle):
    """A model folder placed by name."""

    type: Literal['model']  # noqa: A003 - the file's key
    model: ModelName


Obstacle = Annotated[Union[Cube, Cylinder, Sphere, PlacedModel], Field(discriminator='type')]
_OBSTACLE_MODELS = {'cube': Cube, 'cylinder': Cylinder, 'sphere': Sphere, 'model': PlacedModel}


class WorldFile(_Entry):
    """A whole world file."""

    name: Annotated[str, _text('a non-empty text', empty=False)] | None = None
    description: Annotated[str, _text('text')] = ''
    floor: Floor | None = None
    robot: Robot | None = None
    walls: list[Wall] | None = None
    obstacles: list[Obstacle] | None = None
    target: Annotated[str, BeforeValidator(
        lambda value: value if isinstance(value, str) else _fail(
            f'must be an obstacle name, got {with_type(value)}'))] | None = None
    bounds: Annotated[tuple[float, float, float, float], numbers(4)] | None = None


def validate_world_file(data: Any, label: str) -> WorldFile:
    """Return the world file ``data`` (parsed YAML) as a WorldFile; WorldError if it is not."""
    try:
        return WorldFile.model_validate({} if data is None else data, strict=False)
    except ValidationError as error:
        # An unknown key first: a misspelt key ('raduis') also leaves its own key missing.
        first = min(error.errors(), key=lambda item: item['type'] != 'extra_forbidden')
        raise _world_error(first, data, label) from None


def entry_label(key: str, index: int, entry: Any) -> str:
    """Return how messages name entry ``index`` of list ``key``: ``walls[0] (wall_0)``."""
    name = entry.get('name', f'wall_{index}' if key == 'walls' else None) \
        if isinstance(entry, Mapping) else None
    return f'{key}[{index}] ({name})' if isinstance(name, str) and name else f'{key}[{index}]'


def _world_error(error: dict[str, Any], data: Any, label: str) -> WorldError:
    """Return the WorldError of pydantic's first ``error`` about world file ``data``."""
    loc, model, entry, tag = list(error['loc']), WorldFile, None, None
    if loc and loc[0] in ('floor', 'robot'):
        model, entry, loc = {'floor': Floor, 'robot': Robot}[loc[0]], loc[0], loc[1:]
    elif len(loc) > 1 and isinstance(loc[1], int):  # walls[i] or obstacles[i]
        key, index, loc = loc[0], loc[1], loc[2:]
        entry = entry_label(key, index, data[key][index])
        model = Wall
        if key == 'obstacles' and loc:  # pydantic's location names the obstacle's type
            tag, loc = loc[0], loc[1:]
            model = _OBSTACLE_MODELS[tag]
        if loc[:1] == ['name']:  # a name that is wrong names no entry
            entry = f'{key}[{index}]'
    field_name = str(loc[0]) if loc else None
    kind = error['type']
    if kind == 'value_error':
        problem = str(error['ctx']['error'])
    elif kind == 'extra_forbidden':
        problem = unknown_key_problem(field_name, list(model.model_fields))
    elif kind == 'missing':
        hint = _MISSING_HINTS.get(field_name) or f'a {tag} needs it'
        problem = f'missing; {hint}' if tag or field_name in _MISSING_HINTS else 'missing'
    elif kind in ('union_tag_not_found', 'union_tag_invalid'):
        field_name = 'type'
        given = error['ctx'].get('tag')
        problem = (f"{'missing' if given is None else f'unknown type {given!r}'}; use one of "
                   f"{', '.join(OBSTACLE_TYPES)}")
    elif kind == 'list_type':
        problem = f"must be a list of entries, got {with_type(error['input'])}"
    elif kind in ('model_type', 'model_attributes_type', 'dict_type'):
        problem = (f"must be a mapping{'' if error['loc'] else ' of keys'}, got "
                   f"{with_type(error['input'])}")
    else:
        problem = error['msg']
    return WorldError(label, entry, field_name, problem)
