"""
sim_bridge built alone, as a package in someone else's workspace, installs its worlds and models.

A copy of the package's folder (its links to the workspace's ``worlds/``, ``models/``,
``scenarios/`` and ``examples/`` followed, as ``cp -rL`` copies them) is built by colcon in a
workspace of its own: its share folder must hold every world, model folder, shipped scenario
and example node of the kit, its Python package the grading pages' templates (about 15 s).
"""

from pathlib import Path
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
COLCON = Path(sys.executable).parent / 'colcon'


def files_below(folder: Path) -> set[str]:
    return {str(path.relative_to(folder)) for path in folder.rglob('*') if path.is_file()}


@pytest.mark.skipif(not COLCON.is_file(), reason='colcon is not installed beside this Python')
def test_a_copy_of_sim_bridge_built_alone_installs_the_worlds_and_models(tmp_path):
    shutil.copytree(ROOT / 'sim_bridge', tmp_path / 'src' / 'sim_bridge',
                    ignore=shutil.ignore_patterns('__pycache__', '*.egg-info'))
    build = subprocess.run(
        [str(COLCON), '--log-base', 'log', 'build', '--build-base', 'build', '--install-base',
         'install'], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stdout + build.stderr
    share = tmp_path / 'install' / 'sim_bridge' / 'share' / 'sim_bridge'
    for name in ('worlds', 'models', 'scenarios', 'examples'):
        assert files_below(share / name) == files_below(ROOT / name) != set(), name
    # launch files and their params, RViz's display config among them (lab.launch.py rviz:=true)
    for name in ('launch', 'params'):
        assert files_below(share / name) == files_below(ROOT / 'sim_bridge' / name), name
    assert (share / 'params' / 'lab.rviz').is_file()
    # The grading pages' templates are package data beside the modules.
    templates = ROOT / 'sim_bridge' / 'sim_bridge' / 'grading' / 'templates'
    installed = list((tmp_path / 'install' / 'sim_bridge').glob(
        'lib/python*/site-packages/sim_bridge/grading/templates'))
    assert len(installed) == 1 and files_below(installed[0]) == files_below(templates)
