"""
Every test process keeps its ROS 2 traffic to itself (docs/internals.md, How a run works).

``shared_python``: a Python with this one's packages that every user can run (a run's uid
without namespaces sees the host's folders). ``answer_hunt``: the hostile node that names the
files it can read holding an answer of the kit. ``run_warnings``: a run's own warnings, without
the machine's sandbox warning.
"""

import importlib.util
import os
from pathlib import Path
import shutil
import stat
import subprocess
import sys
import sysconfig
import tempfile

import pytest
from sim_bridge.common.run_environment import keep_dds_in_process

keep_dds_in_process()

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
#: Makes a venv every user can run with this Python's packages.
SHARED_VENV = FIXTURES / 'shared_venv.py'


def reachable_by_others(path: Path) -> bool:
    """Tell whether users other than its owner reach ``path`` (o+x up its folders, o+r)."""
    real = Path(os.path.realpath(path))
    return bool(os.stat(real).st_mode & stat.S_IROTH) and all(
        os.stat(folder).st_mode & stat.S_IXOTH for folder in real.parents)


@pytest.fixture(scope='module')
def shared_python():
    """
    Return a Python with this one's packages that every user can run, as Gradescope's venv.

    This one when it can; else a venv of the system's Python of the same version, in a folder
    every user enters (fixtures/shared_venv.py).
    """
    site_folder = Path(sysconfig.get_path('purelib'))
    if reachable_by_others(Path(sys.executable)) and reachable_by_others(site_folder):
        yield sys.executable
        return
    system = Path('/usr/bin/python3')
    version = subprocess.run([str(system), '-c', 'import sys; print(sys.version_info[:2])'],
                             capture_output=True, text=True) if system.exists() else None
    if (version is None or version.stdout.strip() != str(sys.version_info[:2])
            or not reachable_by_others(site_folder)):
        pytest.skip(f'no Python {sys.version_info[:2]} that every user can run with these '
                    'packages')
    folder = Path(tempfile.mkdtemp(prefix='shared-python-'))
    try:
        folder.chmod(0o755)
        subprocess.run([sys.executable, str(SHARED_VENV), str(folder)], check=True)
        python = folder / 'bin' / 'python'
        yield str(python)
    finally:
        shutil.rmtree(folder)


@pytest.fixture(scope='session')
def answer_hunt():
    """Return fixtures/hostile/answer_hunt.py as a module (its ``wanted`` describes answers)."""
    spec = importlib.util.spec_from_file_location('answer_hunt',
                                                  FIXTURES / 'hostile' / 'answer_hunt.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: How a run's warning about the machine begins where runs are not fully sandboxed
#: (node_sandbox.isolation_warning): as root without bubblewrap, as a user without it.
SANDBOX_WARNINGS = ('runs PARTLY sandboxed: ', 'runs NOT sandboxed: ')


@pytest.fixture
def run_warnings():
    """
    Return a function that gives a run's own warnings: the machine's sandbox warning left out.

    That one says what the machine allows, the same for every run there; a test of a run's
    warnings compares the others.
    """
    return lambda warnings: [warning for warning in warnings
                             if not warning.startswith(SANDBOX_WARNINGS)]
