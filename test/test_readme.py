"""The README documents what the code does: every driving-node parameter is listed."""

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize('node', ['wanderbot', 'wall_follow'])
def test_readme_lists_every_parameter_of_the_driving_nodes(node):
    shipped = yaml.safe_load((ROOT / 'scan_pkg' / 'params' / f'{node}.yaml').read_text())
    readme = (ROOT / 'README.md').read_text()
    section = readme[readme.index(f'`{node}` parameters'):]
    for name in shipped[node]['ros__parameters']:
        assert f'`{name}`' in section, name
