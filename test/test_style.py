"""
The real ament linters over the workspace's top-level ``test/`` folder.

``colcon test`` runs each package's ``test_flake8.py`` and ``test_pep257.py`` (ament's templates)
over that package; this folder belongs to no package, so it is checked here, with the same
tools and their own configuration.
"""

from pathlib import Path

from ament_flake8.main import main_with_errors
from ament_pep257.main import main
import pytest

TOP_LEVEL_TESTS = str(Path(__file__).resolve().parent)


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    rc, errors = main_with_errors(argv=[TOP_LEVEL_TESTS])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + \
        '\n'.join(errors)


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=[TOP_LEVEL_TESTS])
    assert rc == 0, 'Found code style errors / warnings'
