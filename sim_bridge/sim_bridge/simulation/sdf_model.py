"""
What the SDF reader makes: a model (shapes, lidars, drive) and a world (models, floor, step).

:class:`Model` holds a model's collision shapes, its lidars and its diff drive;
:class:`SdfWorld` a world's models where they stand (:class:`PlacedModel`), the floor
(:class:`Plane`) and the physics step. Lengths in m, angles in rad.
"""

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, replace
from functools import cached_property
import math
from pathlib import Path

import numpy as np
from sim_bridge.simulation.geometry import Footprint, Shape, triangulate
from sim_bridge.simulation.robot import DiffDriveConfig
from sim_bridge.simulation.sdf_lidar import LidarConfig
from sim_bridge.simulation.sdf_values import Pose6, SdfError, ZERO_POSE

#: An entry of an ignored list: (what, its name or '' when only counted).
Ignored = tuple[str, str]


def describe_ignored(items: Iterable[Ignored]) -> str:
    """
    Return one line summing up ignored items, e.g. ``12 visuals, 2 lights, plugins a, b``.

    Items without a name are counted; named items are listed once each. '' for none.
    """
    items = list(items)
    counts = Counter(kind for kind, name in items if not name)
    named: dict[str, list[str]] = {}
    for kind, name in items:
        if name and name not in named.setdefault(kind, []):
            named[kind].append(name)
    parts = [f'{count} {kind}{"s" if count > 1 else ""}' for kind, count in counts.items()]
    parts += [f'{kind}{"s" if len(names) > 1 else ""} {", ".join(names)}'
              for kind, names in named.items()]
    return ', '.join(parts)


@dataclass(frozen=True)
class Plane:
    """A ``<plane>`` collision: the floor at height ``z`` (m), ``size`` (x, y in m)."""

    z: float
    size: tuple[float, float]


@dataclass(frozen=True)
class Model:
    """
    A model read from its SDF file: collision shapes in the model frame, maybe a lidar and a drive.

    ``shapes`` are every collision of every link (and nested model) in the model frame, whose
    origin is where the model is placed (on the floor, z = 0, for a robot); ``pose`` is the
    model's own ``<pose>``, used only where nothing places the model (an ``<include>``'s pose,
    a YAML entry's or a spawn pose replace it, as in Gazebo). ``planes`` are its ``<plane>``
    collisions (a ground plane: the floor). ``lidars`` are every lidar sensor read, by name,
    ``lidar`` the one used (see :meth:`with_lidar`). ``ignored`` lists what the simulator does
    not simulate but the unused lidars (:attr:`not_simulated` adds them; see
    :func:`describe_ignored`); ``sources`` the SDF and mesh files read.
    """

    name: str
    path: Path
    shapes: tuple[Shape, ...]
    lidar: LidarConfig | None = None
    static: bool = False
    #: The model's diff-drive plugin, None when it has none.
    drive: DiffDriveConfig | None = None
    pose: Pose6 = ZERO_POSE
    planes: tuple[Plane, ...] = ()
    ignored: tuple[Ignored, ...] = ()
    sources: tuple[Path, ...] = ()
    lidars: tuple[tuple[str, LidarConfig], ...] = ()
    #: (parent link, child link, the parent's pose, the child's pose; in the model frame, m
    #: and rad) of each joint between the top model's links, at joint position 0: the tree of
    #: frames robot_state_publisher sends as TF.
    joints: tuple[tuple[str, str, Pose6, Pose6], ...] = ()

    def with_lidar(self, name: str) -> 'Model':
        """Return this model using its lidar sensor called ``name``; SdfError when none is."""
        for sensor, config in self.lidars:
            if sensor == name:
                return replace(self, lidar=config)
        names = ', '.join(sensor for sensor, _ in self.lidars) or 'none'
        raise SdfError(f'{self.path}: <model name="{self.name}">: has no lidar sensor named '
                       f"'{name}' (lidars: {names})")

    @property
    def not_simulated(self) -> tuple[Ignored, ...]:
        """Return :attr:`ignored` and the lidars not used (a 1-beam one is a range sensor)."""
        unused = tuple(('sensor', f'{name} (1 beam lidar)' if config.samples == 1
                        else f'{name} (lidar not used)')
                       for name, config in self.lidars if config is not self.lidar)
        return self.ignored + unused

    @cached_property
    def footprints(self) -> tuple[Footprint, ...]:
        """Return the floor outlines of the shapes (upright primitives only, for now)."""
        return tuple(shape.footprint() for shape in self.shapes)

    @property
    def is_robot(self) -> bool:
        """Return True for a model Gazebo can drive and scan with: a diff drive and a lidar."""
        return self.drive is not None and self.lidar is not None

    @cached_property
    def radius(self) -> float:
        """Return the radius of the smallest circle about the origin holding the outline (m)."""
        radius = 0.0
        for shape in self.shapes:
            if shape.upright and shape.kind in ('box', 'cylinder', 'sphere'):
                footprint = shape.footprint()
                if footprint.kind == 'circle':
                    reach = math.hypot(footprint.x, footprint.y) + footprint.radius
                else:
                    reach = float(max(math.hypot(*corner) for corner in footprint.outline()))
            else:
                points = triangulate(shape)[0] @ shape.rotation().T + (shape.x, shape.y, 0.0)
                reach = float(np.hypot(points[:, 0], points[:, 1]).max())
            radius = max(radius, reach)
        return radius

    @property
    def height(self) -> float:
        """Return the height of the top of the highest collision shape (m)."""
        return max((shape.z_range()[1] for shape in self.shapes), default=0.0)


@dataclass(frozen=True)
class PlacedModel:
    """A model of a world at its ``pose`` (x, y, z m, roll, pitch, yaw rad) in the world."""

    name: str
    model: Model
    pose: Pose6
    static: bool


@dataclass(frozen=True)
class SdfWorld:
    """
    An SDF ``<world>``: its models where they stand, the floor and the physics step.

    ``planes`` are the ground planes in the world frame; ``physics_step_s`` is
    ``<physics><max_step_size>`` (s), None when unset; ``ignored`` what the world itself (not
    its models, see :attr:`Model.ignored`) has that is not simulated.
    """

    name: str
    path: Path
    models: tuple[PlacedModel, ...]
    planes: tuple[Plane, ...]
    physics_step_s: float | None
    ignored: tuple[Ignored, ...]
    sources: tuple[Path, ...]
