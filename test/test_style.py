"""
Run ament's style checks over the whole workspace with the PyPI tools that implement them.

ament_flake8 and ament_pep257 are not on PyPI; flake8 with the same plugins and pydocstyle with
the same ignore list (both configured in the top-level setup.cfg) judge the code the same way.
"""

from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ['scan_pkg', 'sim_bridge', 'test']


def run_tool(module: str, *arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', module, *arguments], cwd=ROOT,
                          capture_output=True, text=True, check=False)


@pytest.mark.linter
def test_flake8_with_ament_rules_finds_nothing():
    result = run_tool('flake8', *SOURCES)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.linter
def test_pep257_with_ament_rules_finds_nothing():
    result = run_tool('pydocstyle', *SOURCES)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.linter
def test_flake8_is_configured_to_catch_a_violation(tmp_path):
    offending = tmp_path / 'offending.py'
    offending.write_text('import os\nx = "double quotes, unused import and a line too long' +
                         'x' * 99 + '"\n')
    result = run_tool('flake8', '--config', str(ROOT / 'setup.cfg'), str(offending))
    assert result.returncode != 0
    for code in ('F401', 'Q000', 'E501'):
        assert code in result.stdout
