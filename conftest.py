"""
Run from the workspace root, pytest collects both packages' tests and the workspace's own.

pytest imports test files by their path from here (``--import-mode=importlib``, pytest.ini),
so that the two packages' ament test files of the same name (test_flake8.py, test_pep257.py)
do not clash. Named so, ``sim_bridge/test/test_run.py`` is ``sim_bridge.test.test_run``: the
packages are imported first, or pytest would take the folders ``sim_bridge/`` and
``scan_pkg/`` for them. colcon tests one package at a time, perhaps with the other not built.
"""

import contextlib
import importlib

for package in ('scan_pkg', 'sim_bridge'):
    with contextlib.suppress(ImportError):
        importlib.import_module(package)
