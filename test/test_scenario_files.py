"""The shipped scenarios cover every lab task and state issue 5's pass criteria and durations."""

from pathlib import Path

import pytest

from sim_bridge.lab_tasks import LAB_TASKS
from sim_bridge.metrics import offset_path_length
from sim_bridge.paths import world_names
from sim_bridge.scenario import load_scenario, load_scenarios
from sim_bridge.simulation.world import World

SCENARIOS = Path(__file__).resolve().parent / 'scenarios'
WALL_FOLLOW_WORLDS = [name for name in world_names() if name.startswith('wall_follow_')]
DIRECTIONS = {'cw': ('right', None, 'laps <= -1'), 'ccw': ('left', 'mirrored', 'laps >= 1')}


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
def test_wall_follow_scenarios_hold_issue_5_criteria_on_every_world(world_name, direction):
    side, start, laps = DIRECTIONS[direction]
    scenario = load_scenario(SCENARIOS / f'{world_name}_{direction}.yaml')
    params = scenario.params['wall_follow']
    assert (scenario.world, scenario.nodes) == (world_name, ('wall_follow',))
    assert (params['side'], scenario.start) == (side, start)
    # The setpoint is the scenario's, not read from whatever a graded node calls its parameter.
    assert scenario.setpoint == {'wall_distance_m': params['distance']}
    assert len(scenario.seeds) == 3
    assert criteria(scenario) == ['len(node_errors) == 0', laps, 'collisions == 0',
                                  'wall_distance_m.mae <= 0.10', 'min_clearance_m >= 0.15']
    world = World.load(world_name)
    loop = offset_path_length(world.obstacle(world.target).footprints, params['distance'])
    assert scenario.duration_s == pytest.approx(2.5 * loop / params['speed'], rel=1e-3)


def test_wanderbot_runs_five_seeds_of_ten_minutes_in_the_room():
    scenario = load_scenario(SCENARIOS / 'wanderbot.yaml')
    assert (scenario.world, scenario.nodes, scenario.duration_s) == (
        'room', ('wanderbot',), 600.0)
    assert len(scenario.seeds) == 5
    assert {run.params['wanderbot']['seed'] for run in scenario.runs()} == set(scenario.seeds)
    assert {'min(turns_deg) > 90', 'max_stationary_s <= 5'} <= set(criteria(scenario))


@pytest.mark.parametrize('name, printed', [
    ('scan_ahead', 'range_ahead'), ('scan_around', 'regions'), ('closest_obstacle', 'closest')])
def test_reading_scenarios_grade_what_their_node_prints(name, printed):
    assert load_scenario(SCENARIOS / f'{name}.yaml').printed == (printed,)
