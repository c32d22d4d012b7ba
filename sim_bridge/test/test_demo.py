"""The demo's lab tasks: the scan readers see the obstacles come and go as the robot drives."""

import json

from sim_bridge.commands.demo import run_tasks


def test_the_demo_drives_the_scan_readers_past_the_obstacles(tmp_path, capfd):
    assert run_tasks(tmp_path)
    for task in ('scan_ahead', 'scan_around', 'closest_obstacle'):
        metrics = json.loads((tmp_path / task / 'metrics.json').read_text())
        assert metrics['distance_m'] > 2.0 and metrics['collisions'] == 0, task
    lines = (tmp_path / 'scan_ahead' / 'log.jsonl').read_text().splitlines()
    # 'Range ahead: 2.83 m': from metres away to under half a metre, and nothing ahead (10 m).
    ranges = [float(json.loads(line)['text'].split()[2]) for line in lines]
    assert 2.5 < ranges[0] < 3.5 and min(ranges) < 0.5 and max(ranges) == 10.0
