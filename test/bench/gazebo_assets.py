"""
Acceptance check: load every third-party Gazebo model folder and world, unedited, in place.

Reads ``../shared/gazebo_assets`` (next to the repository's folder; see its README) with the
model folders on ``GZ_SIM_RESOURCE_PATH`` and ``GAZEBO_MODEL_PATH``, as a user would set them,
and prints one row per model folder or world: loaded or the error, the lidar it got (samples,
angles in rad, range in m, rate in Hz, frame), the number of collision shapes, the floor
footprint area (m², '-' while the shapes have no 2-D outline), what was ignored, and
``seen-not-blocking``: of the lidar hits on the model (rays cast at the Burger's heights
from all round it), how many land farther than 1 cm outside the outline that blocks the robot
(a robot would drive through what its lidar sees; 0 is right). Nothing is copied or written.

``--models ROOT`` adds every model folder under ROOT (e.g. a checkout of osrf/gazebo_models),
``--worlds FILE`` adds world files (e.g. gz-sim's examples/worlds/*.sdf) and ``--robots FILE``
robot files (SDF, URDF or xacro), each loaded as the robot of an empty world. Rows are
summarised by outcome at the end.

Run: python test/bench/gazebo_assets.py [ASSETS_FOLDER] [--models ROOT ...]
     [--worlds FILE ...] [--robots FILE ...]
"""

import argparse
from collections import Counter
import os
from pathlib import Path
import sys

import numpy as np
import pybullet
import shapely

from sim_bridge.common import paths
from sim_bridge.simulation.floor_slice import FloorSlice
from sim_bridge.simulation.geometry import FootprintSet
from sim_bridge.simulation.lidar import build_scene, cast_rays
from sim_bridge.simulation.sdf import load_model
from sim_bridge.simulation.sdf_lidar import LidarConfig
from sim_bridge.simulation.sdf_model import describe_ignored
from sim_bridge.simulation.world import World

ASSETS = Path(__file__).resolve().parents[3] / 'shared' / 'gazebo_assets'
#: Where ROBOTIS's launch files spawn the robot (x m, y m, yaw rad) in a world with none.
SPAWN_POSES = {'turtlebot3_world': (-2.0, -0.5, 0.0)}
#: Farther than this (m) outside the blocking outline, a lidar hit counts as seen-not-blocking.
SEEN_MARGIN = 0.01


def lidar_text(lidar: LidarConfig | None) -> str:
    if lidar is None:
        return '-'
    return (f'{lidar.samples} x {lidar.min_angle:g}..{lidar.max_angle:g} rad, '
            f'{lidar.range_min:g}-{lidar.range_max:g} m, {lidar.update_rate:g} Hz, '
            f'{lidar.frame_id}')


def area_text(footprints_of) -> str:
    """Return the area (m²) of the union of some footprints, or '-' when there are none."""
    try:
        footprints = footprints_of()
    except ValueError:
        return '-'
    if not footprints:
        return '-'
    union = shapely.union_all([shapely.Polygon(fp.outline()) for fp in footprints])
    return f'{union.area:.3f}'


def seen_not_blocking(robot_shapes, shapes) -> str:
    """
    Return 'N/M': of M lidar hits on ``shapes`` at the robot's heights, N outside its slice.

    Rays are cast level at four heights across the robot's band, from 256 points on a circle
    around the shapes towards and across them.
    """
    floor_slice = FloorSlice(robot_shapes, [('model', shapes)])
    low, high = floor_slice.band
    client = pybullet.connect(pybullet.DIRECT)
    try:
        build_scene(client, shapes, floor_size=(0.001, 0.001))
        corners = np.array([shape.world_mesh().bounds for shape in shapes])
        centre = 0.5 * (corners[:, 0].min(axis=0) + corners[:, 1].max(axis=0))
        reach = float(np.linalg.norm(corners[:, 1].max(axis=0) - corners[:, 0].min(axis=0)))
        around = np.linspace(0.0, 2.0 * np.pi, 256, endpoint=False)
        aims = around + np.pi + np.tile([-0.3, 0.0, 0.3], len(around) // 3 + 1)[:len(around)]
        hits = []
        for height in np.linspace(low + 0.2 * (high - low), high - 0.05 * (high - low), 4):
            starts = np.column_stack((centre[0] + reach * np.cos(around),
                                      centre[1] + reach * np.sin(around),
                                      np.full(len(around), height)))
            ends = starts + 2.0 * reach * np.column_stack((np.cos(aims), np.sin(aims),
                                                           np.zeros(len(aims))))
            distances = cast_rays(client, starts, ends)
            seen = np.isfinite(distances)
            directions = (ends - starts)[seen] / (2.0 * reach)
            hits.append(starts[seen, :2] + directions[:, :2] * distances[seen, None])
    finally:
        pybullet.disconnect(client)
    points = np.vstack(hits)
    if not len(points):
        return '0/0'
    outside = FootprintSet(floor_slice.footprints).distance(points) > SEEN_MARGIN
    return f'{int(outside.sum())}/{len(points)}'


def model_rows(roots: list[Path], base: Path, robot_shapes) -> list[tuple[str, ...]]:
    rows = []
    for root in roots:
        for folder in sorted(place for place in root.iterdir() if paths.is_model_folder(place)):
            label = str(folder.relative_to(base)) if folder.is_relative_to(base) else str(folder)
            try:
                model = load_model(folder)
            except (ValueError, FileNotFoundError) as error:
                if 'has no <sdf> element' in str(error):  # Gazebo cannot include it either
                    rows.append((label, 'not a model: meshes only, no model file', '', '',
                                 '', '', ''))
                else:
                    rows.append((label, f'ERROR {error}', '', '', '', '', ''))
                continue
            except Exception as error:  # the census records crashes rather than stop at one
                rows.append((label, f'CRASH {type(error).__name__}: {error}', '', '', '', '',
                             ''))
                continue
            try:
                seen = seen_not_blocking(robot_shapes, model.shapes) if model.shapes else '-'
            except Exception as error:  # noqa: B902 - a crash in the slice is a finding
                seen = f'CRASH {type(error).__name__}: {error}'
            rows.append((label, 'loaded', lidar_text(model.lidar), str(len(model.shapes)),
                         area_text(lambda model=model: model.footprints),
                         describe_ignored(model.not_simulated), seen))
    return rows


def world_rows(world_files: list[Path], base: Path, robot: str) -> list[tuple[str, ...]]:
    rows = []
    for world_file in world_files:
        label = (str(world_file.relative_to(base)) if world_file.is_relative_to(base)
                 else str(world_file))
        try:
            try:
                world = World.load(world_file)
                note = ''
            except (ValueError, FileNotFoundError) as error:
                if 'pass one with --robot' not in str(error):
                    rows.append((label, f'ERROR {error}', '', '', '', '', ''))
                    continue
                pose = SPAWN_POSES.get(world_file.stem, (0.0, 0.0, 0.0))
                try:
                    world = World.load(world_file, robot=robot, robot_pose=pose)
                except ValueError as refused:
                    if 'overlaps obstacle' not in str(refused):
                        raise
                    # The world loads; the census's spawn point is taken: a refusal, rightly.
                    rows.append((label, 'loaded (no robot; a spawn at the origin is refused: '
                                 + str(refused).rpartition(': ')[2] + ')', '', '', '', '', ''))
                    continue
                note = f' (no robot: --robot {robot} --robot-pose {pose})'
            rows.append((label, 'loaded' + note, lidar_text(world.robot.lidar),
                         str(len(world.shapes())), area_text(world.footprints),
                         world.ignored.removeprefix('ignored: '), ''))
        except (ValueError, FileNotFoundError) as error:
            rows.append((label, f'ERROR {error}', '', '', '', '', ''))
        except Exception as error:  # the census records crashes rather than stop at one
            rows.append((label, f'CRASH {type(error).__name__}: {error}', '', '', '', '', ''))
    return rows


def robot_rows(robot_files: list[Path]) -> list[tuple[str, ...]]:
    rows = []
    for robot_file in robot_files:
        try:
            world = World.load('room', robot=robot_file, robot_pose=(0.0, 0.0, 0.0))
            rows.append((str(robot_file), 'loaded as robot', lidar_text(world.robot.lidar),
                         str(len(world.robot.shapes)), '', world.ignored, ''))
        except (ValueError, FileNotFoundError) as error:
            rows.append((str(robot_file), f'ERROR {error}', '', '', '', '', ''))
        except Exception as error:  # the census records crashes rather than stop at one
            rows.append((str(robot_file), f'CRASH {type(error).__name__}: {error}', '', '', '',
                         '', ''))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('assets', nargs='?', type=Path, default=ASSETS)
    parser.add_argument('--models', nargs='*', type=Path, default=[])
    parser.add_argument('--worlds', nargs='*', type=Path, default=[])
    parser.add_argument('--robots', nargs='*', type=Path, default=[])
    arguments = parser.parse_args()
    assets = arguments.assets
    if not assets.is_dir():
        print(f'no assets folder at {assets}; nothing to check')
        return 0
    sim, classic, shared = (assets / 'turtlebot3_gazebo_sim' / 'models',
                            assets / 'turtlebot3_gazebo_classic' / 'models',
                            assets / 'gazebo_models')
    # As users set them: Gazebo Sim's path for the Sim folders, Classic's for Classic's.
    os.environ['GZ_SIM_RESOURCE_PATH'] = os.pathsep.join(
        (str(sim), str(shared), *map(str, arguments.models)))
    os.environ['GAZEBO_MODEL_PATH'] = os.pathsep.join(
        (str(classic), str(shared), *map(str, arguments.models)))
    burger = sim / 'turtlebot3_burger'
    robot_shapes = load_model(burger).shapes
    rows = model_rows([sim, classic, shared, *arguments.models], assets, robot_shapes)
    worlds = sorted(assets.glob('*/worlds/*.world')) + list(arguments.worlds)
    rows += world_rows(worlds, assets, str(burger))
    rows += robot_rows(arguments.robots)
    header = ('asset', 'result', 'lidar', 'shapes', 'area m2', 'ignored', 'seen-not-blocking')
    for row in [header, *rows]:
        print(' | '.join(row))
    outcomes = Counter(row[1].split(' ')[0] for row in rows)
    through = sum(1 for row in rows if '/' in row[6] and not row[6].startswith(('0/', 'CRASH')))
    crashes = sum(1 for row in rows if 'CRASH' in row[1] + row[6])
    print(f'\n{len(rows)} rows: ' + ', '.join(f'{n} {kind}' for kind, n in outcomes.items())
          + f'; {through} models seen-not-blocking; {crashes} crashes')
    return 1 if outcomes['ERROR'] or crashes else 0


if __name__ == '__main__':
    sys.exit(main())
