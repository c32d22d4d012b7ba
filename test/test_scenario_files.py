"""
The shipped scenarios cover every lab task and mark them by the handout's points.

They state their durations; no scenario holds a target the handout does not state.
"""

import math
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores

from sim_bridge.common.paths import world_names
from sim_bridge.grading.scenario import load_scenario, load_scenarios
from sim_bridge.live.lab_tasks import LAB_TASKS
from sim_bridge.runner.run import run_simulation
from sim_bridge.scoring.metrics import offset_path_length
from sim_bridge.simulation.world import World

SCENARIOS = Path(__file__).resolve().parents[1] / 'scenarios'
WALL_FOLLOW_WORLDS = [name for name in world_names() if name.startswith('wall_follow_')]
DIRECTIONS = {'cw': ('right', None, 'laps <= -1', 'clockwise'),
              'ccw': ('left', 'mirrored', 'laps >= 1', 'counterclockwise')}
#: The kit's wall follower's distance (m), its parameter's default: the scenarios' durations
#: are for its loop.
KIT_DISTANCE = 0.5


def criteria(scenario):
    return [criterion.text for criterion in scenario.criteria]


def test_every_scenario_file_loads_and_names_a_world_that_loads():
    scenarios = load_scenarios([SCENARIOS])
    assert scenarios
    for scenario in scenarios:
        World.load(scenario.world)


def test_every_lab_task_has_a_scenario_in_its_world():
    runs = {(node, scenario.world) for scenario in load_scenarios([SCENARIOS])
            for node in scenario.nodes}
    for task in LAB_TASKS.values():
        assert (task.node, task.world) in runs, task


def test_every_scenario_requires_a_run_without_node_errors_or_collisions():
    for scenario in load_scenarios([SCENARIOS]):
        assert {'len(node_errors) == 0', 'collisions == 0'} <= set(criteria(scenario)), \
            scenario.name


@pytest.mark.parametrize('world_name', WALL_FOLLOW_WORLDS)
@pytest.mark.parametrize('direction', DIRECTIONS)
def test_wall_follow_scenarios_are_marked_by_the_handouts_points_on_every_world(world_name,
                                                                                direction):
    side, start, laps, loop_direction = DIRECTIONS[direction]
    scenario = load_scenario(SCENARIOS / f'{world_name}_{direction}.yaml')
    params = scenario.params['wall_follow']
    assert (scenario.world, scenario.nodes) == (world_name, ('wall_follow',))
    assert (params['side'], scenario.start) == (side, start)
    assert (scenario.points, scenario.direction, scenario.directions) == (
        'wall_follow', loop_direction, 'one')
    # The distance is the student's choice: no scenario states one, nor a tolerance.
    assert 'distance' not in params and scenario.setpoint == {}
    assert len(scenario.seeds) == 3
    assert criteria(scenario) == ['len(node_errors) == 0', laps, 'collisions == 0']
    world = World.load(world_name)
    loop = offset_path_length(world.obstacle(world.target).footprints, KIT_DISTANCE)
    assert scenario.duration_s == pytest.approx(2.5 * loop / params['speed'], rel=1e-3)


def test_wanderbot_runs_three_seeds_of_three_minutes_in_the_room():
    scenario = load_scenario(SCENARIOS / 'wanderbot.yaml')
    assert (scenario.world, scenario.nodes, scenario.duration_s, scenario.points) == (
        'room', ('wanderbot',), 180.0, 'wander')
    assert len(scenario.seeds) == 3
    assert {run.params['wanderbot']['seed'] for run in scenario.runs()} == set(scenario.seeds)
    # The handout's turn, not a coverage or a stationary limit it does not state.
    assert criteria(scenario) == ['len(node_errors) == 0', 'collisions == 0',
                                  'min(turns_deg) > 90']


def test_the_shipped_scenarios_carry_the_labs_marks():
    from sim_bridge.grading.marks import task_marks, total
    scenarios = load_scenarios([SCENARIOS])
    tasks = {task.title: task for task in task_marks(scenarios, [])}
    assert {title: (task.scenarios if len(task.scenarios) == 1 else len(task.scenarios),
                    task.marks, task.marking) for title, task in tasks.items()} == {
        'task 1': (('scan_ahead',), 2.0, 'all'),
        'task 2': (('wanderbot',), 3.0, 'proportional'),
        'task 3': (('scan_around',), 2.0, 'all'),
        'task 4': (len(WALL_FOLLOW_WORLDS) * 2, 3.0, 'proportional'),
        'extra': (('closest_obstacle',), None, 'all'),
    }
    assert total(tasks.values())[1] == 10.0


@pytest.mark.parametrize('name, printed', [
    ('scan_ahead', 'range_ahead'), ('scan_around', 'regions'), ('closest_obstacle', 'closest')])
def test_reading_scenarios_grade_what_their_node_prints(name, printed):
    scenario = load_scenario(SCENARIOS / f'{name}.yaml')
    assert scenario.printed == (printed,)
    assert scenario.points == printed


def front_ranges(bag_path: Path) -> list[float]:
    """Return each recorded scan's front-most range (m): beams within one increment of ahead."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    fronts = []
    with Reader(bag_path) as bag:
        for connection, _, raw in bag.messages(
                [c for c in bag.connections if c.topic == '/scan']):
            scan = typestore.deserialize_cdr(raw, connection.msgtype)
            fronts.append(min(value for index, value in enumerate(scan.ranges)
                              if abs(scan.angle_min + index * scan.angle_increment)
                              <= scan.angle_increment))
    return fronts


@pytest.mark.parametrize('name', ['scan_ahead', 'scan_around', 'closest_obstacle'])
def test_the_reading_scenarios_drive_the_robot_towards_and_past_the_obstacles(name, tmp_path):
    scenario = load_scenario(SCENARIOS / f'{name}.yaml')
    assert scenario.drive
    result = run_simulation(scenario.world, list(scenario.nodes), duration_s=scenario.duration_s,
                            seed=scenario.seeds[0], start=scenario.start, out_dir=tmp_path,
                            quiet=True, plot=False, drive=scenario.drive)
    assert result.ok and result.metrics['collisions'] == 0
    fronts = front_ranges(tmp_path / 'run')
    seen = [front for front in fronts if math.isfinite(front)]
    # From metres away to under 0.5 m, and stretches with nothing ahead (out of range).
    assert max(seen) > 2.5 and min(seen) < 0.5
    assert len(seen) < 0.75 * len(fronts)
