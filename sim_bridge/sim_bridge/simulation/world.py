"""
World files: load, validate and describe a simulated world.

World file format (YAML)
========================

A world file is a YAML mapping with these keys, all optional. Lengths are in metres, angles
in radians (counter-clockwise, REP-103); ``[x, y]`` are floor coordinates. Every key not
listed here is an error, so a typo never goes unnoticed::

    name: room                  # defaults to the file name without .yaml
    description: free text

    floor:                      # optional; without it the floor is an endless plane
      size: [12, 10]            # floor rectangle centred on the origin, x and y sizes

    robot:
      model: lab_robot          # a model folder from models/ (default lab_robot)
      pose: [0.0, -1.5, 0.0]    # start: x, y, yaw (default [0, 0, 0])

    walls:                      # each entry is one straight wall or one rectangular room
      - name: divider           # optional (default wall_<index>)
        start: [-3.5, 1.5]      # ends of the wall's centre line
        end: [-1.5, 1.5]
        thickness: 0.15         # optional (default 0.15)
        height: 1.0             # optional (default 1.0)
      - name: outer             # a room: four walls named outer_north/_south/_east/_west
        room: [8, 6]            # free inside size, x and y, between the walls' inner faces
        center: [0, 0]          # optional (default [0, 0])
        thickness: 0.15         # optional, as above
        height: 1.0             # optional, as above

    obstacles:                  # each entry needs a unique name and a type
      - name: box               # type cube needs size: [x, y, z]
        type: cube
        size: [1, 1, 1]
        pose: [2.0, 0.0, 0.3]   # x, y, yaw; yaw is optional (default 0)
      - name: pillar            # type cylinder needs radius and length (axis vertical)
        type: cylinder
        radius: 0.5
        length: 1.0
        pose: [0.0, 2.2]
      - name: ball              # type sphere needs radius
        type: sphere
        radius: 0.5
        pose: [-2.5, -1.5]
        z: 0.5                  # optional height of the centre (default: resting on the floor)
      - name: block             # type model places a model folder from models/ (or from
        type: model             # GZ_SIM_RESOURCE_PATH / GAZEBO_MODEL_PATH) by name and pose
        model: obstacle_box
        pose: [1.5, -2.0, 0.0]
        z: 0.0                  # optional height of the model's origin (default 0, the floor)

    target: block               # optional: the obstacle a wall follower circles (grading)
    bounds: [-5, -4, 5, 4]      # optional: xmin, ymin, xmax, ymax of the area used for
                                # coverage; default: the walls' extent, or without walls the
                                # obstacles and the robot start plus 1 m all round

Numbers must be numbers (``1e3``, ``1.0e3`` and ``1.0e+3`` are, as in YAML 1.2; ``'1'`` is
text), sizes and radii positive. A world is lab-sized: sizes, radii, lengths and heights at most
:data:`MAX_SIZE_M` (1000 m), positions (poses, wall ends, centres, ``z``, ``bounds``) within
± :data:`MAX_COORDINATE_M` (1000 m) of the origin, so that bounds written in millimetres are
an error, not a world the simulator cannot hold. The robot must start clear of every obstacle.
A file breaking any rule is rejected with a :class:`WorldError` naming the file, the entry and
the field, e.g.
``worlds/room.yaml: obstacles[2] (box_a): 'size': must be 3 positive finite numbers, got
[1, -1, 1]``.

Gazebo's SDF worlds (``.world``, ``.sdf``, or any file holding ``<sdf><world>``) load too:
their models and ``<include>``s (see :mod:`.sdf`), the ground plane as the floor (a
``<plane>``, or a ground slab, :func:`~.sdf.ground_of`: never an obstacle; the world is read
with its top at z = 0, where the robot stands), and ``<physics><max_step_size>``. The robot is
the world's model with a diff-drive plugin and a lidar, or the model passed to
:meth:`World.load` / :meth:`World.with_robot`. Other models are obstacles, held fixed; what
is not simulated is summed up in :attr:`World.ignored`.

What the simulator sees: every obstacle is one or more :class:`~.geometry.Shape`
primitives (walls and cubes are boxes); the lidar sees their 3-D shapes, and the robot
collides with what lies in its height band, from just above the floor to its top
(:class:`~.floor_slice.FloorSlice`): its outline, from its own collision shapes, against the
obstacles' parts in the band (of a table whose top is above the robot, only the legs; of a
ball, its widest section below the robot's top). "The robot must start clear" means clear in
that slice.
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property
import math
import os
from pathlib import Path
from typing import Any

from sim_bridge.common import paths
from sim_bridge.common.values import with_type
from sim_bridge.common.yaml_loader import load_yaml, read_text
from sim_bridge.simulation import world_file
from sim_bridge.simulation.floor_slice import FloorSlice
from sim_bridge.simulation.geometry import Footprint, Shape, triangulate, wrap_angle
from sim_bridge.simulation.sdf import GROUND_TOP_M, is_sdf_text, load_model, parse_world
from sim_bridge.simulation.sdf_frames import place
from sim_bridge.simulation.sdf_lookup import MODEL_FILE_SUFFIXES
from sim_bridge.simulation.sdf_model import describe_ignored, Ignored, Model, Plane
from sim_bridge.simulation.sdf_values import SdfError
from sim_bridge.simulation.world_file import (  # noqa: F401 - the world file's names
    DEFAULT_ROBOT_MODEL, MAX_COORDINATE_M, MAX_SIZE_M, OBSTACLE_TYPES, validate_world_file,
    WorldError)
import yaml

#: The largest world file read (bytes): an SDF world of a whole house is a few hundred KiB.
WORLD_FILE_LIMIT_BYTES = 16 * 2 ** 20
#: Margin (m) around obstacles and robot start for the default bounds of a world without walls.
BOUNDS_MARGIN = 1.0


@dataclass(frozen=True)
class Obstacle:
    """
    One named thing in the world the robot must not hit.

    ``kind`` is 'cube', 'cylinder', 'sphere', 'wall' or 'model'; ``shapes`` are its 3-D
    primitives in the world frame, ``footprints`` their whole vertical projections (what
    the robot can hit is :meth:`World.footprints`, in its height band); ``pose`` (x, y in m,
    yaw in rad) is where the entry placed it; ``model`` names its model folder, if any.
    """

    name: str
    kind: str
    shapes: tuple[Shape, ...]
    pose: tuple[float, float, float]
    model: str | None = None

    @cached_property
    def footprints(self) -> tuple[Footprint, ...]:
        """Return the floor outlines of the shapes: their whole vertical projections."""
        return tuple(shape.footprint() for shape in self.shapes)

    def distance(self, x: float, y: float) -> float:
        """Return the signed distance from the floor point (x, y) to the outline (m)."""
        return min(footprint.distance(x, y) for footprint in self.footprints)


@dataclass(frozen=True)
class World:
    """
    A loaded world: obstacles, the robot's model and start pose, a target and bounds.

    ``robot_start`` is (x m, y m, yaw rad); ``robot`` the parsed robot model (its ``radius`` is
    the robot's footprint, its ``lidar`` the sensor); ``bounds`` (xmin, ymin, xmax, ymax in m)
    the area used for coverage; ``floor_size`` (x, y in m) or None for an endless floor;
    ``sources`` the files it was read from: the world file (if any), then each model's SDF file;
    ``physics_step_s`` an SDF world's ``<physics><max_step_size>`` (s), None when unset;
    ``ignored`` one line summing up what the simulator does not simulate ('' for nothing).
    """

    name: str
    path: Path | None
    obstacles: tuple[Obstacle, ...]
    robot_start: tuple[float, float, float]
    robot_model: str
    robot: Model
    target: str | None
    bounds: tuple[float, float, float, float]
    floor_size: tuple[float, float] | None = None
    description: str = ''
    sources: tuple[Path, ...] = ()
    physics_step_s: float | None = None
    ignored: str = ''
    #: What the world itself (not its robot) has that is not simulated.
    world_ignored: tuple[Ignored, ...] = ()

    @classmethod
    def load(cls, name_or_path: str | os.PathLike, robot: str | os.PathLike | None = None,
             robot_pose: Sequence[float] | None = None, lidar: str | None = None) -> 'World':
        """
        Load a shipped world by name (``room``) or any world file (YAML or SDF) by path.

        ``robot`` (a model name or folder) replaces the world's robot, spawned at
        ``robot_pose`` (x m, y m, yaw rad; default: where the world puts its robot, else the
        origin) as ``ros_gz_sim create`` does; without ``robot``, ``robot_pose`` moves the
        world's own robot there (as the bridge's parameter does); ``lidar`` names the
        robot's lidar sensor to use when it has several (default: its first). Raises
        FileNotFoundError for an unknown world and :class:`WorldError` for a bad file.
        """
        path = paths.find_world(name_or_path)
        label = _display_path(path)
        try:
            text = read_text(path, WORLD_FILE_LIMIT_BYTES)
        except (OSError, UnicodeDecodeError) as error:  # a link to /dev/zero, a Latin-1 file
            why = getattr(error, 'strerror', None) or f'not UTF-8 text: {error.reason}'
            raise WorldError(label, None, None, f'cannot read: {why}') from None
        xml = is_sdf_text(text)
        suffix = path.suffix.lower()
        if xml and suffix in ('.yaml', '.yml'):
            raise WorldError(label, None, None, 'holds XML (an SDF world), not YAML: name it '
                             '.world or .sdf')
        if not xml and suffix in ('.world', '.sdf'):
            raise WorldError(label, None, None, 'holds YAML (a kit world), not SDF XML: name '
                             'it .yaml')
        if xml:
            world = _sdf_world(path, text, label, robot is not None, lidar)
        else:
            world = cls._load_yaml(path, text, label)
            if lidar is not None and robot is None:  # the YAML world's robot, re-read
                robot = world.robot.path
        pose = world.robot_start if robot_pose is None else tuple(robot_pose)
        if robot is not None:
            return world.with_robot(robot, pose, lidar)
        return world if robot_pose is None else world.with_robot_at(pose)

    @classmethod
    def _load_yaml(cls, path: Path, text: str, label: str) -> 'World':
        try:
            data = load_yaml(text)
        except yaml.YAMLError as error:
            mark = getattr(error, 'problem_mark', None)
            where = f'line {mark.line + 1}, column {mark.column + 1}: ' if mark else ''
            problem = getattr(error, 'problem', None) or str(error)
            raise WorldError(label, None, None, f'invalid YAML: {where}{problem}') from None
        return _Parser(label, path.parent).world(data, path)

    @classmethod
    def from_dict(cls, data: Any, source: str = '<dict>') -> 'World':
        """Build a world from an already parsed mapping; ``source`` names it in errors."""
        return _Parser(source).world(data, None)

    def obstacle(self, name: str) -> Obstacle:
        """Return the obstacle called ``name``; KeyError when there is none."""
        for obstacle in self.obstacles:
            if obstacle.name == name:
                return obstacle
        raise KeyError(f"world '{self.name}' has no obstacle '{name}'")

    def shapes(self) -> tuple[Shape, ...]:
        """Return every obstacle's 3-D primitives."""
        return tuple(shape for obstacle in self.obstacles for shape in obstacle.shapes)

    @cached_property
    def floor_slice(self) -> FloorSlice:
        """Return the world through the robot's height band, and the robot's outline."""
        return _floor_slice(self._label(), self.robot, self.obstacles)

    def footprints(self) -> tuple[Footprint, ...]:
        """Return the outlines the robot can hit (its band's slice), in obstacle order."""
        return self.floor_slice.footprints

    def footprint_owners(self) -> tuple[str, ...]:
        """Return, for each entry of :meth:`footprints`, the name of its obstacle."""
        return self.floor_slice.owners

    def obstacle_footprints(self, name: str) -> tuple[Footprint, ...]:
        """Return the outlines of obstacle ``name`` in the robot's band (maybe none)."""
        return tuple(footprint for footprint, owner in zip(self.footprints(),
                                                           self.footprint_owners())
                     if owner == name)

    def with_robot_start(self, x: float, y: float, yaw: float) -> 'World':
        """
        Return this world with the robot starting at (x m, y m, yaw rad) instead.

        Raises :class:`WorldError` when the robot would start overlapping an obstacle.
        """
        pose = (float(x), float(y), wrap_angle(float(yaw)))
        if not all(math.isfinite(value) for value in pose) or \
                max(map(abs, pose[:2])) > MAX_COORDINATE_M:  # lab-sized, as in a world file
            raise WorldError(self._label(), 'robot', 'pose', 'must be finite, x and y within '
                             f'±{MAX_COORDINATE_M:g} m of the origin, got {pose}')
        _check_robot_clear(self._label(), pose, self.floor_slice, self.robot.name)
        moved = replace(self, robot_start=pose)
        # The same robot among the same obstacles: the same slice, not sliced again.
        moved.__dict__['floor_slice'] = self.floor_slice
        return moved

    def with_robot(self, model: str | os.PathLike,
                   pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   lidar: str | None = None) -> 'World':
        """
        Return this world with the robot ``model`` (a name or a folder) at (x m, y m, yaw rad).

        The model's own ``<pose>`` is replaced by ``pose``, as ``ros_gz_sim create`` does;
        ``lidar`` names its lidar sensor to use (default: its first). Raises
        :class:`WorldError` for a model that cannot be loaded or has no collision shape, or a
        pose overlapping an obstacle.
        """
        label = self._label()
        parser = _Parser(label)
        folder = self.path.parent if self.path is not None else None
        robot = parser.model(str(model), 'robot', folder, lidar)
        if not robot.shapes:
            raise WorldError(label, 'robot', 'model', f"model '{model}' has no collision shape "
                             'to give the robot a footprint')
        world = replace(self, robot=robot, robot_model=robot.name,
                        sources=tuple(dict.fromkeys(self.sources + robot.sources)),
                        ignored=_ignored_line(self.world_ignored + robot.not_simulated))
        return world.with_robot_at(pose)

    def with_robot_at(self, pose: Sequence[float]) -> 'World':
        """Return with_robot_start(*pose), WorldError when ``pose`` is not (x m, y m, yaw rad)."""
        try:
            return self.with_robot_start(*pose)
        except WorldError:
            raise
        except (TypeError, ValueError):  # not three numbers
            raise WorldError(self._label(), 'robot', 'pose',
                             f'must be (x, y, yaw), got {pose!r}') from None

    def mirrored_start(self) -> 'World':
        """
        Return this world with the robot turned round on its start (yaw + pi).

        A wall-follow world starts with the target on the robot's right (a clockwise run);
        turned round on the same spot the robot has it on its left at the same distance, the
        counter-clockwise start.
        """
        x, y, yaw = self.robot_start
        return self.with_robot_start(x, y, yaw + math.pi)

    def _label(self) -> str:
        return _display_path(self.path) if self.path is not None else self.name


def _display_path(path: Path) -> str:
    """Return ``path`` relative to the working directory when it is below it."""
    try:
        return str(path.resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def _ignored_line(items: tuple[Ignored, ...]) -> str:
    text = describe_ignored(items)
    return f'ignored: {text}' if text else ''


def _floor_slice(label: str, robot: Model, obstacles: tuple[Obstacle, ...]) -> FloorSlice:
    try:
        return FloorSlice(robot.shapes,
                          [(obstacle.name, obstacle.shapes) for obstacle in obstacles])
    except ValueError as error:
        raise WorldError(label, 'robot', 'model', f"'{robot.name}' ({robot.path}): {error}"
                         ) from None


def _check_robot_clear(label: str, pose: tuple[float, float, float],
                       floor_slice: FloorSlice, robot_name: str) -> None:
    """Fail unless robot ``robot_name``'s outline at ``pose`` is clear of the obstacles."""
    _, index, clear = floor_slice.probe(pose)
    if not clear:
        outline = (f'radius {floor_slice.robot_radius:g} m' if floor_slice.round
                   else f'outline reaching {floor_slice.robot_radius:g} m from its origin')
        raise WorldError(label, 'robot', 'pose',
                         f"the robot '{robot_name}' ({outline}) at ({pose[0]:g}, {pose[1]:g}) "
                         f"overlaps obstacle '{floor_slice.owners[index]}'")


class _Parser:
    """Turns the parsed YAML of one file into a World, raising WorldError on the first fault."""

    def __init__(self, label: str, folder: Path | None = None) -> None:
        self.label = label
        self.folder = folder
        self.model_files: list[Path] = []

    def fail(self, entry: str | None, field_name: str | None, problem: str) -> WorldError:
        return WorldError(self.label, entry, field_name, problem)

    def world(self, data: Any, path: Path | None) -> World:
        spec = validate_world_file(data, self.label)
        name = spec.name or (path.stem if path is not None else self.label)
        robot_model, robot, robot_start = self.robot(spec.robot or world_file.Robot())
        obstacles = []
        declared = {}
        for index, wall in enumerate(spec.walls or []):
            where, walls = self.walls(wall, index)
            self.add_unique(declared, walls, where)
            obstacles += walls
        for index, entry in enumerate(spec.obstacles or []):
            where = world_file.entry_label('obstacles', index, {'name': entry.name})
            obstacle = self.obstacle(entry, where)
            self.add_unique(declared, [obstacle], where)
            obstacles.append(obstacle)
        names = [obstacle.name for obstacle in obstacles]
        if spec.target is not None and spec.target not in names:
            raise self.fail(None, 'target', f"names no obstacle ('{spec.target}'); obstacles: "
                            f"{', '.join(names) or 'none'}")
        _check_robot_clear(self.label, robot_start,
                           _floor_slice(self.label, robot, tuple(obstacles)), robot.name)
        bounds = spec.bounds
        if bounds is None:
            bounds = _default_bounds(obstacles, robot_start, robot.radius)
        elif bounds[0] >= bounds[2] or bounds[1] >= bounds[3]:
            raise self.fail(None, 'bounds', f'must be [xmin, ymin, xmax, ymax] with xmin < xmax '
                            f'and ymin < ymax, got {list(bounds)}')
        files_read = ([path] if path is not None else []) + self.model_files
        return World(name=name, path=path, obstacles=tuple(obstacles), robot_start=robot_start,
                     robot_model=robot_model, robot=robot, target=spec.target, bounds=bounds,
                     floor_size=spec.floor.size if spec.floor else None,
                     description=spec.description, sources=tuple(dict.fromkeys(files_read)),
                     ignored=_ignored_line(robot.not_simulated))

    def add_unique(self, declared: dict[str, str], obstacles: list[Obstacle],
                   where: str) -> None:
        """Check the obstacles of entry ``where`` have new names and record them."""
        for obstacle in obstacles:
            if obstacle.name in declared:
                raise self.fail(where, 'name', f"duplicate name '{obstacle.name}' (also used "
                                f'by {declared[obstacle.name]})')
            declared[obstacle.name] = where

    def robot(self, spec: world_file.Robot) -> tuple[str, Model, tuple[float, float, float]]:
        model = self.model(spec.model, 'robot', self.folder)
        if not model.shapes:
            raise self.fail('robot', 'model', f"model '{spec.model}' has no collision shape to "
                            'give the robot a footprint')
        x, y, yaw = spec.pose
        return spec.model, model, (x, y, wrap_angle(yaw))

    def model(self, name: Any, where: str, folder: Path | None = None,
              lidar: str | None = None) -> Model:
        """Return the model ``name`` (a folder's name, or a path to a folder or SDF file)."""
        if not isinstance(name, str) or not name:
            raise self.fail(where, 'model', f'must be a model name, got {with_type(name)}')
        try:
            given = Path(name)
            found = given if given.parent != Path('.') or given.suffix in MODEL_FILE_SUFFIXES \
                else paths.find_model(name, folder)
            model = load_model(found, lidar=lidar, world_folder=folder)
        except FileNotFoundError as error:
            raise self.fail(where, 'model', str(error)) from None
        except SdfError as error:
            raise self.fail(where, 'model', f"model '{name}' is broken: {error}") from None
        self.model_files += model.sources or [model.path]
        return model

    def walls(self, spec: world_file.Wall, index: int) -> tuple[str, list[Obstacle]]:
        """Return the label of wall entry ``index`` and its walls: one, or a room's four."""
        name = spec.name or f'wall_{index}'
        where = f'walls[{index}] ({name})'
        thickness, height = spec.thickness, spec.height
        if spec.room is not None:
            for key in ('start', 'end'):
                if getattr(spec, key) is not None:
                    raise self.fail(where, key, "a wall entry has either 'room' or "
                                    "'start' and 'end', not both")
            size_x, size_y = spec.room
            center_x, center_y = spec.center or (0.0, 0.0)
            half_x = 0.5 * size_x + 0.5 * thickness
            half_y = 0.5 * size_y + 0.5 * thickness
            outer_x = size_x + 2.0 * thickness
            sides = (('north', 0.0, half_y, outer_x), ('south', 0.0, -half_y, outer_x),
                     ('east', half_x, 0.0, size_y), ('west', -half_x, 0.0, size_y))
            return where, [_wall(f'{name}_{side}', center_x + dx, center_y + dy,
                                 0.0 if side in ('north', 'south') else 0.5 * math.pi,
                                 length, thickness, height)
                           for side, dx, dy, length in sides]
        if spec.center is not None:
            raise self.fail(where, 'center', "only a 'room' wall entry has a center")
        for key in ('start', 'end'):
            if getattr(spec, key) is None:
                raise self.fail(where, key, "missing; a wall needs 'start' and 'end' (or "
                                "'room')")
        start, end = spec.start, spec.end
        length = math.hypot(end[0] - start[0], end[1] - start[1])
        if length <= 0.0:
            raise self.fail(where, 'end', 'must differ from start')
        return where, [_wall(name, 0.5 * (start[0] + end[0]), 0.5 * (start[1] + end[1]),
                             math.atan2(end[1] - start[1], end[0] - start[0]), length,
                             thickness, height)]

    def obstacle(self, spec: world_file.Obstacle, where: str) -> Obstacle:
        """Return the obstacle of entry ``where``: its shapes placed at its pose."""
        x, y, yaw = spec.pose
        yaw = wrap_angle(yaw)
        if spec.type == 'model':
            model = self.model(spec.model, where, self.folder)
            if not model.shapes:
                raise self.fail(where, 'model', f"model '{spec.model}' has no collision shapes")
            shapes = tuple(shape.placed(x, y, spec.z or 0.0, yaw) for shape in model.shapes)
            return Obstacle(spec.name, 'model', shapes, (x, y, yaw), model=spec.model)
        if spec.type == 'cube':
            shape = Shape('box', size=spec.size)
        elif spec.type == 'cylinder':
            shape = Shape('cylinder', radius=spec.radius, length=spec.length)
        else:
            shape = Shape('sphere', radius=spec.radius)
        centre_z = 0.5 * shape.height if spec.z is None else spec.z
        return Obstacle(spec.name, spec.type, (shape.placed(x, y, centre_z, yaw),), (x, y, yaw))


def _wall(name: str, x: float, y: float, yaw: float, length: float, thickness: float,
          height: float) -> Obstacle:
    shape = Shape('box', x, y, 0.5 * height, wrap_angle(yaw), size=(length, thickness, height))
    return Obstacle(name, 'wall', (shape,), (x, y, shape.yaw))


def _shape_bounds(shape: Shape) -> tuple[float, float, float, float]:
    """Return the floor bounding box (xmin, ymin, xmax, ymax) of a shape (m)."""
    try:
        return shape.footprint().bounds()
    except ValueError:
        points = triangulate(shape)[0] @ shape.rotation().T + (shape.x, shape.y, shape.z)
        low = points.min(axis=0)
        high = points.max(axis=0)
        return (float(low[0]), float(low[1]), float(high[0]), float(high[1]))


def _default_bounds(obstacles: list[Obstacle], robot_start: tuple[float, float, float],
                    robot_radius: float) -> tuple[float, float, float, float]:
    walls = [shape for obstacle in obstacles if obstacle.kind == 'wall'
             for shape in obstacle.shapes]
    if walls:
        boxes = [_shape_bounds(shape) for shape in walls]
        margin = 0.0
    else:
        x, y = robot_start[:2]
        boxes = [_shape_bounds(shape) for obstacle in obstacles for shape in obstacle.shapes]
        boxes.append((x - robot_radius, y - robot_radius, x + robot_radius, y + robot_radius))
        margin = BOUNDS_MARGIN
    return (min(box[0] for box in boxes) - margin, min(box[1] for box in boxes) - margin,
            max(box[2] for box in boxes) + margin, max(box[3] for box in boxes) + margin)


def _sdf_world(path: Path, text: str, label: str, robot_given: bool,
               lidar: str | None) -> World:
    """
    Return the World of an SDF world file; its robot is the model that can drive and scan.

    With ``lidar`` named, the robot is the first model with a drive and a lidar of that name.
    """
    try:
        sdf = parse_world(text, path)
    except SdfError as error:
        raise WorldError(label, None, None, _without_file(str(error), path)) from None
    except FileNotFoundError as error:
        raise WorldError(label, None, None, str(error)) from None
    robot = None
    for placed in sdf.models:
        if lidar is not None and placed.model.drive is not None and not robot_given and \
                any(name == lidar for name, _ in placed.model.lidars):
            robot = replace(placed, model=placed.model.with_lidar(lidar))
            break
        if lidar is None and placed.model.is_robot:
            robot = placed
            break
    if robot is None and lidar is not None and not robot_given:
        raise WorldError(label, None, None, f"has no robot with a lidar sensor named '{lidar}'"
                         ": name one of its robot's lidars, or pass --robot MODEL")
    if robot is None and not robot_given:
        raise WorldError(label, None, None, 'has no robot (a model with a diff-drive plugin and '
                         'a lidar): pass one with --robot MODEL, e.g. --robot turtlebot3_burger')
    obstacles = []
    ignored = list(sdf.ignored)
    floor_z, floor = _floor(sdf.planes)
    for placed in sdf.models:
        if robot is not None and placed.name == robot.name:
            continue
        ignored += placed.model.not_simulated
        x, y, z, roll, pitch, yaw = placed.pose
        shapes = tuple(place(shape, (x, y, z - floor_z, roll, pitch, yaw))
                       for shape in placed.model.shapes)
        if not shapes:
            continue
        obstacles.append(Obstacle(placed.name, 'model', shapes, (x, y, yaw),
                                  model=placed.model.name))
        if not placed.static:
            ignored.append(('model held fixed', placed.name))
    start, radius = ((0.0, 0.0, 0.0), 0.0) if robot is None else (  # None: with_robot's
        (robot.pose[0], robot.pose[1], wrap_angle(robot.pose[5])), robot.model.radius)
    name = sdf.name if sdf.name != 'default' else path.stem
    world = World(name=name, path=path, obstacles=tuple(obstacles), robot_start=start,
                  robot_model=robot.name if robot is not None else '',
                  robot=robot.model if robot is not None else Model('none', path, ()),
                  target=None, bounds=_default_bounds(obstacles, start, radius),
                  floor_size=floor, sources=sdf.sources, physics_step_s=sdf.physics_step_s,
                  ignored=_ignored_line(tuple(ignored) + (robot.model.not_simulated if robot
                                                          else ())),
                  world_ignored=tuple(ignored))
    if robot is not None:
        _check_robot_clear(label, start, world.floor_slice, robot.name)
    return world


def _floor(planes: Sequence[Plane]) -> tuple[float, tuple[float, float] | None]:
    """
    Return the height (m) of the floor the robot stands on and its size (x, y m; None: endless).

    The floor is the highest ground within :data:`~.sdf.GROUND_TOP_M` of z = 0 (a ground slab's
    top is 0.05 m up in gz-sim's examples); the world is read with it at z = 0, as the robot
    standing on it sees the world in Gazebo.
    """
    grounds = [plane for plane in planes if abs(plane.z) <= GROUND_TOP_M]
    if not grounds:
        return 0.0, next((plane.size for plane in planes), None)
    floor = max(grounds, key=lambda plane: plane.z)
    return floor.z, floor.size


def _without_file(message: str, path: Path) -> str:
    """Return an SdfError's message without its leading file name when it is ``path``."""
    return message.removeprefix(f'{path}: ')
