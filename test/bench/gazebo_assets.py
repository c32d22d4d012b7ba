"""
Acceptance check: load every third-party Gazebo model folder and world, unedited, in place.

Reads ``../shared/gazebo_assets`` (next to the repository's folder; see its README) with the
model folders on ``GZ_SIM_RESOURCE_PATH`` and ``GAZEBO_MODEL_PATH``, as a user would set them,
and prints one row per model folder or world: loaded or the error, the lidar it got (samples,
angles in rad, range in m, rate in Hz, frame), the number of collision shapes, the floor
footprint area (m², '-' while the shapes have no 2-D outline), and what was ignored.
Nothing is copied or written.

Run: python test/bench/gazebo_assets.py [ASSETS_FOLDER]
"""

import os
from pathlib import Path
import sys

from sim_bridge.common import paths
from sim_bridge.simulation.sdf import describe_ignored, LidarConfig, load_model
from sim_bridge.simulation.world import World

ASSETS = Path(__file__).resolve().parents[3] / 'shared' / 'gazebo_assets'
#: Where ROBOTIS's launch files spawn the robot (x m, y m, yaw rad) in a world with none.
SPAWN_POSES = {'turtlebot3_world': (-2.0, -0.5, 0.0)}


def lidar_text(lidar: LidarConfig | None) -> str:
    if lidar is None:
        return '-'
    return (f'{lidar.samples} x {lidar.min_angle:g}..{lidar.max_angle:g} rad, '
            f'{lidar.range_min:g}-{lidar.range_max:g} m, {lidar.update_rate:g} Hz, '
            f'{lidar.frame_id}')


def area_text(footprints_of) -> str:
    """Return the area (m²) of the union of some footprints, or '-' when there are none."""
    import shapely
    try:
        footprints = footprints_of()
    except ValueError:
        return '-'
    if not footprints:
        return '-'
    union = shapely.union_all([shapely.Polygon(fp.outline()) for fp in footprints])
    return f'{union.area:.3f}'


def main(assets: Path) -> int:
    if not assets.is_dir():
        print(f'no assets folder at {assets}; nothing to check')
        return 0
    sim, classic, shared = (assets / 'turtlebot3_gazebo_sim' / 'models',
                            assets / 'turtlebot3_gazebo_classic' / 'models',
                            assets / 'gazebo_models')
    # As users set them: Gazebo Sim's path for the Sim folders, Classic's for Classic's.
    os.environ['GZ_SIM_RESOURCE_PATH'] = os.pathsep.join((str(sim), str(shared)))
    os.environ['GAZEBO_MODEL_PATH'] = os.pathsep.join((str(classic), str(shared)))
    model_roots = [sim, classic, shared]
    rows = []
    for root in model_roots:
        for folder in sorted(place for place in root.iterdir() if paths.is_model_folder(place)):
            label = str(folder.relative_to(assets))
            try:
                model = load_model(folder)
            except (ValueError, FileNotFoundError) as error:
                if 'has no <sdf> element' in str(error):  # Gazebo cannot include it either
                    rows.append((label, 'not a model: meshes only, no model file', '', '',
                                 '', ''))
                else:
                    rows.append((label, f'ERROR {error}', '', '', '', ''))
                continue
            rows.append((label, 'loaded', lidar_text(model.lidar), str(len(model.shapes)),
                         area_text(lambda model=model: model.footprints),
                         describe_ignored(model.not_simulated)))
    for world_file in sorted(assets.glob('*/worlds/*.world')):
        label = str(world_file.relative_to(assets))
        try:
            world = World.load(world_file)
            robot = ''
        except (ValueError, FileNotFoundError) as error:
            if 'pass one with --robot' not in str(error):
                rows.append((label, f'ERROR {error}', '', '', '', ''))
                continue
            pose = SPAWN_POSES.get(world_file.stem, (0.0, 0.0, 0.0))
            world = World.load(world_file, robot='turtlebot3_burger', robot_pose=pose)
            robot = f' (no robot: --robot turtlebot3_burger --robot-pose {pose})'
        rows.append((label, 'loaded' + robot, lidar_text(world.robot.lidar),
                     str(len(world.shapes())), area_text(world.footprints),
                     world.ignored.removeprefix('ignored: ')))
    header = ('asset', 'result', 'lidar', 'shapes', 'area m2', 'ignored')
    for row in [header, *rows]:
        print(' | '.join(row))
    failed = sum(1 for row in rows if row[1].startswith('ERROR'))
    print(f'\n{len(rows) - failed} of {len(rows)} loaded, {failed} errors')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main(Path(sys.argv[1]) if len(sys.argv) > 1 else ASSETS))
