"""
Every test process keeps its ROS 2 traffic to itself (README, How a run works).

``shared_python``: a Python with this one's packages that every user can run (a run's uid
without namespaces sees the host's folders).
"""

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
    every user enters, that reads this one's site folder (``site.addsitedir`` in a .pth) and
    links this one's shared libraries (the ROS wheels' ``lib/*.so``).
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
        subprocess.run([str(system), '-m', 'venv', '--without-pip', str(folder)], check=True)
        python = folder / 'bin' / 'python'
        shared_site = subprocess.run([str(python), '-c', 'import sysconfig; print(sysconfig.'
                                      "get_path('purelib'))"], capture_output=True, text=True,
                                     check=True).stdout.strip()
        Path(shared_site, 'this_venv.pth').write_text(
            f'import site; site.addsitedir({str(site_folder)!r})\n')
        for library in Path(sys.prefix, 'lib').glob('*.so*'):
            (folder / 'lib' / library.name).symlink_to(library)
        yield str(python)
    finally:
        shutil.rmtree(folder)
