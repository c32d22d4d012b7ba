"""
What a run starts with in its scratch folder: a clean environment and a copy of its files.

The environment is the whole of it (nothing of the grader's passes); the student's files are
copied, symlinks as symlinks, within the scratch folder and its limit in bytes.
"""

import os
from pathlib import Path
import shutil
import sys
from typing import Iterator, Mapping, Sequence

from sim_bridge.common.run_environment import NO_SHARED_MEMORY
from sim_bridge.runner.boundary.outside.sandbox_view import (
    is_within, KIT_PACKAGE, python_roots, SYSTEM_PATHS)

#: What a sourced ROS 2 Jazzy (its setup.bash) puts in a node's environment under ``ros2 run``,
#: given to runs on the PyPI path too (a node may branch on ``ROS_DISTRO``); a sourced
#: installation's own values pass instead.
ROS_JAZZY_VARIABLES = {'ROS_DISTRO': 'jazzy', 'ROS_VERSION': '2', 'ROS_PYTHON_VERSION': '3'}


def clean_environment(scratch: Path, extra: Mapping[str, str] = {},
                      library: Sequence[Path] = ()) -> dict[str, str]:
    """
    Return a run's whole environment: what Python and ROS 2 need, nothing of the grader's.

    HOME and TMPDIR are ``scratch``; library and Python paths keep only the folders a run
    sees (:func:`python_roots` and the system's), and Python's starts with the folders of the
    kit's package and of the ``library`` packages (where a run sees those packages alone:
    they are imported from where the grader imports them, whatever else is installed); ROS 2
    discovery is OFF (a run's DDS stays in its processes), without Fast DDS's shared memory
    (NO_SHARED_MEMORY), and ROS_LOCALHOST_ONLY unset; ROS_DISTRO and its kin as a sourced
    Jazzy sets them (ROS_JAZZY_VARIABLES); PYTHONHASHSEED fixed, so that a set's order is the
    same at every run.
    ``extra`` is added last (it may override).
    """
    roots = [*python_roots(), *SYSTEM_PATHS]
    bin_folder = os.path.dirname(sys.executable)
    env = {'PATH': os.pathsep.join([bin_folder, '/usr/local/bin', '/usr/bin', '/bin']),
           'HOME': str(scratch), 'TMPDIR': str(scratch), 'LANG': 'C.UTF-8',
           'PYTHONUNBUFFERED': '1', 'PYTHONDONTWRITEBYTECODE': '1', 'PYTHONHASHSEED': '0',
           'ROS_AUTOMATIC_DISCOVERY_RANGE': 'OFF', **NO_SHARED_MEMORY,
           'OPENBLAS_NUM_THREADS': '1', 'OMP_NUM_THREADS': '1'}
    if sys.prefix != sys.base_prefix:
        env['VIRTUAL_ENV'] = sys.prefix
    for name in ('PYTHONPATH', 'LD_LIBRARY_PATH', 'AMENT_PREFIX_PATH'):
        kept = [path for path in os.environ.get(name, '').split(os.pathsep)
                if path and is_within(os.path.realpath(path), roots)]
        if name == 'PYTHONPATH':  # the kit's packages, however installed (colcon's too)
            kept[:0] = dict.fromkeys(str(package.parent) for package in [KIT_PACKAGE, *library])
        if kept:
            env[name] = os.pathsep.join(kept)
    env.update(ROS_JAZZY_VARIABLES)
    for name in (*ROS_JAZZY_VARIABLES, 'RMW_IMPLEMENTATION', '_ROS_WHEELS_BOOTSTRAP_COMPLETE'):
        if name in os.environ:
            env[name] = os.environ[name]
    env.update(extra)
    return env


def copy_student_files(files: Mapping[str, Path], scratch: Path, limit_bytes: int) -> None:
    """
    Copy the student's ``files`` (name in the scratch -> path) into ``scratch``.

    Symlinks are copied as symlinks, never followed (a submission's link to /etc/shadow
    stays a link the run cannot follow). ValueError, in one line, for a name that leaves the
    scratch folder or files over ``limit_bytes`` (bytes) in all.
    """
    total = 0
    for name, source in files.items():
        relative = Path(name)
        if relative.is_absolute() or '..' in relative.parts or not relative.parts:
            raise ValueError(f'student file name {name!r} must be a relative path inside the '
                             'scratch folder')
        total += sum(os.lstat(path).st_size for path in walk(Path(source)))
        if total > limit_bytes:
            raise ValueError(f'student files are over the scratch limit of {limit_bytes} bytes '
                             f'(at {name})')
        target = scratch / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        if Path(source).is_dir() and not Path(source).is_symlink():
            shutil.copytree(source, target, symlinks=True)
        else:
            shutil.copy2(source, target, follow_symlinks=False)


def walk(path: Path) -> Iterator[Path]:
    """Yield ``path`` and, for a folder (not a symlink), everything below it."""
    yield path
    if path.is_dir() and not path.is_symlink():
        for folder, names, files in os.walk(path):
            for name in [*names, *files]:
                yield Path(folder) / name
