"""
The README and docs/ document what the code does, and its commands work.

Every driving-node parameter is listed (docs/students.md); ``./lab test PYTEST_OPTIONS``
(pytest alone over the three test folders) collects, and ``./lab test`` prints its one-line
total, pass or fail.
"""

import os
from pathlib import Path
import subprocess
import sys

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize('node', ['wanderbot', 'wall_follow'])
def test_the_students_page_lists_every_parameter_of_the_driving_nodes(node):
    shipped = yaml.safe_load((ROOT / 'scan_pkg' / 'params' / f'{node}.yaml').read_text())
    students = (ROOT / 'docs' / 'students.md').read_text()
    section = students[students.index(f'`{node}` parameters'):]
    for name in shipped[node]['ros__parameters']:
        assert f'`{name}`' in section, name


@pytest.mark.parametrize('folder, arguments', [
    ('.', ['scan_pkg/test', 'sim_bridge/test', 'test']),  # ./lab test -k laser, say
    ('scan_pkg', []), ('sim_bridge', []),  # as colcon test runs each package
])
def test_pytest_collects_every_test_folder_without_an_error(folder, arguments):
    """Both packages have ament's test_flake8.py and test_pep257.py: the names must not clash."""
    collected = subprocess.run(
        [sys.executable, '-m', 'pytest', '--collect-only', '-q', *arguments],
        cwd=ROOT / folder, capture_output=True, text=True, timeout=120)
    assert collected.returncode == 0, collected.stdout[-3000:] + collected.stderr[-3000:]
    assert ' tests collected in ' in collected.stdout.splitlines()[-1]
    assert 'error' not in collected.stdout.splitlines()[-1]


COLCON_STUB = """#!/bin/sh
# colcon as ./lab test calls it, its tests failed: test and test-result exit 1.
case "$*" in
    *test-result*--verbose*) echo "1 failure in sim_bridge"; exit 1 ;;
    *test-result*) echo "pytest.xml: 4 tests, 0 errors, 1 failure, 0 skipped"
                   echo "Summary: 10 tests, 1 error, 2 failures, 3 skipped"; exit 1 ;;
    *" test "*) exit 1 ;;
esac
"""


def test_lab_test_prints_its_total_when_tests_fail(tmp_path):
    """``colcon test-result`` exits 1 then; ``set -euo pipefail`` must not lose the total."""
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    (venv / 'bin' / 'colcon').write_text(COLCON_STUB)
    (venv / 'bin' / 'python').write_text('#!/bin/sh\nexit 1\n')  # pytest test/ fails too
    for stub in (venv / 'bin').iterdir():
        stub.chmod(0o755)
    done = subprocess.run(
        ['bash', '-c', 'source "$1"; venv=$2; run_tests', 'bash', ROOT / 'lab', venv],
        cwd=tmp_path, capture_output=True, text=True, timeout=60,
        env={**os.environ, 'PATH': '/usr/bin:/bin'})
    assert done.returncode == 1, done.stderr
    assert done.stdout.splitlines()[-2:] == [
        'lab test: colcon test of scan_pkg and sim_bridge, then pytest test/: 0 s in all',
        '4 passed, 3 failed, 3 skipped']


def ensure_bubblewrap(tmp_path: Path, uid: int, apt_works: bool | None) -> tuple[str, str]:
    """
    Run ./lab's ensure_bubblewrap with no bwrap on PATH; return its stderr and what apt did.

    ``uid`` is what ``id -u`` says; ``apt_works`` None: no apt-get, else whether it succeeds.
    """
    tools = tmp_path / 'bin'
    tools.mkdir()
    (tools / 'dirname').symlink_to('/usr/bin/dirname')  # ./lab finds its folder with it
    (tools / 'id').write_text(f'#!/bin/sh\necho {uid}\n')
    if apt_works is not None:
        (tools / 'apt-get').write_text(f'#!/bin/sh\necho "$@" >> "{tmp_path}/apt.log"\n'
                                       f'exit {0 if apt_works else 100}\n')
    for tool in ('id', 'apt-get'):
        if (tools / tool).exists():
            (tools / tool).chmod(0o755)
    done = subprocess.run(['/bin/bash', '-c', 'source "$1"; ensure_bubblewrap', 'bash',
                           ROOT / 'lab'], capture_output=True, text=True, timeout=60,
                          env={'PATH': str(tools)})
    assert done.returncode == 0, done.stderr
    log = tmp_path / 'apt.log'
    return done.stderr, log.read_text() if log.exists() else ''


@pytest.mark.parametrize('uid, apt_works, says, apt', [
    (0, True, "lab: installing bubblewrap with apt-get (the sandbox of students' runs)\n",
     'install -y -qq bubblewrap'),
    (0, False, "apt-get could not install bubblewrap: students' runs are PARTLY sandboxed", ''),
    (0, None, "bubblewrap is not installed: students' runs are PARTLY sandboxed", None),
    (1000, True, "bubblewrap is not installed: students' runs are NOT sandboxed", None),
], ids=['root with apt', 'apt fails', 'root without apt', 'ordinary user'])
def test_lab_installs_bubblewrap_as_root_with_apt_else_says_what_runs_get(
        tmp_path, uid, apt_works, says, apt):
    stderr, apt_log = ensure_bubblewrap(tmp_path, uid, apt_works)
    assert says in stderr and len(stderr.splitlines()) == (2 if apt_works is False else 1)
    if apt is None:
        assert apt_log == ''
    elif apt:
        assert apt_log.splitlines() == ['update -qq', apt]
