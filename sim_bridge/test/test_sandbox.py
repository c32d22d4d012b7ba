"""
The sandbox holds against hostile runs: each test runs a hostile script of fixtures/hostile.

Each attack runs for real, in bubblewrap as the machine allows (as root here and in CI: a
dedicated uid, namespaces and a cgroup). A test of what only a namespace or a cgroup stops is
skipped where the machine has none; the tests of the dedicated uid also run without
namespaces (the 'uid' mode, as in a Docker container that refuses them).
"""

import dataclasses
import json
import os
from pathlib import Path
import shutil
import signal
import site
import socket
import subprocess
import sys
import tempfile
import time

import pytest

from sim_bridge.runner.boundary.outside import sandbox as sandbox_module, sandbox_host
from sim_bridge.runner.boundary.outside.node_sandbox import isolation_line, NodeSandbox
from sim_bridge.runner.boundary.outside.sandbox import (
    isolation_mode, IsolationMode, python_roots, Sandbox, SandboxLimits)
from sim_bridge.runner.boundary.outside.sandbox_host import (
    grader_folder, lease_folder, lock_exclusive, remove_leftover_scratch, uid_processes)
from sim_bridge.runner.boundary.outside.sandbox_view import KIT_PACKAGE
from sim_bridge.runner.boundary.outside.scratch import clean_environment

HOSTILE = Path(__file__).resolve().parent / 'fixtures' / 'hostile'
REPOSITORY = KIT_PACKAGE.parents[1]
#: Wall seconds a hostile script may take (it starts Python, some rclpy).
RUN_TIMEOUT_S = 120.0
MiB = 2 ** 20

ROOT = os.geteuid() == 0
NAMESPACES = isolation_mode().bwrap
needs_namespaces = pytest.mark.skipif(not NAMESPACES, reason=isolation_mode().why)
needs_root = pytest.mark.skipif(not ROOT, reason='a dedicated uid needs root')


@pytest.fixture(params=['bwrap', 'uid'])
def python(request, monkeypatch):
    """
    Run the test in bubblewrap, then with the dedicated uid alone (root only); return its Python.

    A uid reaches no Python in a folder only root enters (pyenv's in /root): the system's then.
    """
    if request.param == 'uid':
        if not ROOT:
            pytest.skip('a dedicated uid needs root')
        python = next((path for path in (sys.executable, '/usr/bin/python3')
                       if reachable_by_others(path)), None)
        if python is None:
            pytest.skip(f'{sys.executable} is in a folder other users cannot enter')
        monkeypatch.setattr(sandbox_module, 'LAUNCHER_PYTHON', python)
        monkeypatch.setattr(sandbox_module, 'isolation_mode',
                            lambda: IsolationMode('uid', 'namespaces turned off by the test'))
    elif not NAMESPACES:
        pytest.skip(isolation_mode().why)
    return sandbox_module.LAUNCHER_PYTHON


def reachable_by_others(path: str) -> bool:
    """Tell whether users other than its owner reach and run ``path`` (o+x up its folders)."""
    real = Path(os.path.realpath(path))
    return all(os.stat(folder).st_mode & 0o001 for folder in [real, *real.parents])


def hostile(name: str) -> dict[str, Path]:
    """Return the student files of hostile script ``name``."""
    return {f'{name}.py': HOSTILE / f'{name}.py'}


def run(box: Sandbox, name: str, *args, pass_fds=(), timeout=RUN_TIMEOUT_S,
        python=sys.executable):
    """
    Run hostile script ``name`` in ``box`` until it ends; return (exit status, its output).

    Its output goes to a file, not a pipe: what it left running may hold it open.
    """
    with tempfile.TemporaryFile() as output:
        process = box.popen([python, f'{name}.py', *map(str, args)],
                            clean_environment(box.scratch), pass_fds=pass_fds,
                            stdout=output, stderr=subprocess.STDOUT)
        status = process.wait(timeout)
        output.seek(0)
        return status, output.read().decode()


@needs_namespaces
def test_a_run_reads_nothing_of_the_instructor_other_students_or_the_grader(
        tmp_path, monkeypatch):
    monkeypatch.setenv('LAB_SECRET', 'token-of-the-grader')
    instructor = tmp_path / 'instructor'
    instructor.mkdir()
    (instructor / 'secret.txt').write_text('the answers')
    os.chmod(tmp_path, 0o755)
    scenario = REPOSITORY / 'scenarios' / 'scan_ahead.yaml'
    with Sandbox({'answer.py': HOSTILE / 'sleeper.py'}) as other, \
            Sandbox(hostile('snoop')) as box:
        files = [instructor / 'secret.txt', other.scratch / 'answer.py', scenario]
        kit = [KIT_PACKAGE / '__init__.py',
               Path(sys.prefix) / 'lib' / 'sitecustomize.py']
        status, output = run(box, 'snoop', os.getpid(), *files, '--write', *kit)
    assert status == 0, output
    found = json.loads(output.splitlines()[-1])
    # Root's home is there only as the way to a Python installed in it (pyenv's).
    home = found.pop('home')
    on_the_way = sorted({Path(root).relative_to('/root').parts[0]
                         for root in python_roots() if root.startswith('/root/')})
    assert home == f'GOT {json.dumps(on_the_way)}' or not home.startswith('GOT'), home
    assert not [target for target, result in found.items() if result.startswith('GOT')], found
    assert found['scan_pkg.wall_follow'] in ('ModuleNotFoundError', 'ImportError')


def test_a_run_cannot_touch_another_runs_files_or_the_uid_leases(python):
    with Sandbox({'answer.py': HOSTILE / 'sleeper.py'}) as other, \
            Sandbox(hostile('snoop')) as box:
        answer = other.scratch / 'answer.py'
        leases = [lease_folder() / f'uid-{uid}.lock' for uid in (box.uid, other.uid) if uid]
        status, output = run(box, 'snoop', os.getpid(), answer, *leases,
                             '--write', answer, *leases, python=python)
        assert answer.read_text() == (HOSTILE / 'sleeper.py').read_text()
    found = json.loads(output.splitlines()[-1])
    found.pop('home')  # see the test above
    assert not [target for target, result in found.items() if result.startswith('GOT')], found
    if python != sys.executable:
        assert box.isolation.startswith(f'PARTLY sandboxed: uid {box.uid} only'), box.isolation


@needs_namespaces
def test_the_reference_nodes_stay_hidden_in_a_folder_the_run_may_read():
    package = REPOSITORY / 'scan_pkg' / 'scan_pkg'
    with Sandbox(hostile('snoop'), readable=[package.parent]) as box:
        status, output = run(box, 'snoop', os.getpid(), package / 'wall_follow.py', '--write')
    found = json.loads(output.splitlines()[-1])
    assert found['scan_pkg.wall_follow'] == 'ModuleNotFoundError', found
    assert found[str(package / 'wall_follow.py')] == 'FileNotFoundError', found


#: A student's node that reads the kit's library and answers (JSON: what -> what it got).
LIBRARY_READER = """
import importlib, json, sys
def attempt(read):
    try:
        return 'GOT ' + str(read())[:80]
    except Exception as error:
        return type(error).__name__
found = {path: attempt(lambda path=path: open(path).read()) for path in sys.argv[1:]}
for module in ('scan_pkg.report', 'scan_pkg.behaviors.wander'):
    found[module] = attempt(lambda module=module: importlib.import_module(module).__file__)
print(json.dumps(found))
"""


@needs_namespaces
def test_every_copy_of_the_kits_library_a_run_can_read_holds_no_answers(tmp_path, monkeypatch):
    # Gradescope's setup.sh installs the kit in its venv, and run_autograder puts the kit's
    # source first on PYTHONPATH: the grader's scan_pkg is the source, another copy is in a
    # site folder the run reads. Stand-in: a copy of scan_pkg in a site folder of this Python.
    site_folder = tmp_path / 'site-packages'
    shutil.copytree(REPOSITORY / 'scan_pkg' / 'scan_pkg', site_folder / 'scan_pkg')
    monkeypatch.setattr(site, 'getsitepackages',
                        lambda folders=site.getsitepackages(): [*folders, str(site_folder)])
    (tmp_path / 'student').mkdir()
    node = tmp_path / 'student' / 'reader.py'
    node.write_text(LIBRARY_READER)
    answers = [site_folder / 'scan_pkg' / 'wall_follow.py',
               site_folder / 'scan_pkg' / 'behaviors' / 'wander.py']
    where = NodeSandbox(str(node), SandboxLimits())
    with where.sandbox as box, tempfile.TemporaryFile() as output:
        box.popen([sys.executable, where.target, *map(str, answers)], where.environment(),
                  stdout=output, stderr=subprocess.STDOUT).wait(RUN_TIMEOUT_S)
        output.seek(0)
        text = output.read().decode()
    found = json.loads(text.splitlines()[-1])
    # The library is the grader's (the kit's source); the answers cannot be read anywhere.
    assert found.pop('scan_pkg.report') == f"GOT {REPOSITORY / 'scan_pkg' / 'scan_pkg'}/report.py"
    assert not [result for result in found.values() if result.startswith('GOT')], found


#: Run as an ordinary user by the test below: a sandbox in a user namespace, three attacks.
AS_USER = """
import json, os, subprocess, sys, tempfile
from pathlib import Path
from sim_bridge.runner.boundary.outside.sandbox import Sandbox, SandboxLimits
hostile, grader = Path(sys.argv[1]), sys.argv[2]
for name, args in (('fork_bomb', []), ('network', ['1']), ('signals', [grader, '1'])):
    with Sandbox({name + '.py': hostile / (name + '.py')}, SandboxLimits(pids=24)) as box, \\
            tempfile.TemporaryFile() as output:
        box.popen([sys.executable, name + '.py', *args], box.environment(),
                  stdout=output).wait(60)
        output.seek(0)
        print(json.dumps([box.isolation, output.read().decode()]))
"""


@needs_root
def test_as_an_ordinary_user_a_run_gets_a_user_namespace():
    setpriv, python = shutil.which('setpriv'), '/usr/bin/python3'
    project = KIT_PACKAGE.parent
    if not (setpriv and reachable_by_others(python) and reachable_by_others(project)):
        pytest.skip('needs setpriv, and a Python and the kit that user nobody reaches')
    done = subprocess.run(
        [setpriv, '--reuid=65534', '--regid=65534', '--clear-groups', python, '-c', AS_USER,
         str(HOSTILE), str(os.getpid())], capture_output=True, text=True, timeout=RUN_TIMEOUT_S,
        env={'PATH': '/usr/bin:/bin', 'PYTHONPATH': str(project)}, cwd='/')
    results = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(results) == 3, done.stderr
    if not results[0][0].startswith('bubblewrap: user namespace of uid 65534'):
        pytest.skip(f'no user namespaces for nobody here: {results[0][0]}')
    bomb, network, signals = (output.split() for _, output in results)
    assert bomb[:2] == ['refused', 'BlockingIOError'] and int(bomb[-1]) < 24
    assert network == ['tcp', 'ConnectionRefusedError', 'udp', 'OSError']
    assert signals[:2] == ['ProcessLookupError', 'ProcessLookupError']


def test_the_environment_is_clean_and_keeps_dds_in_the_run(tmp_path, monkeypatch):
    monkeypatch.setenv('LAB_SECRET', 'token-of-the-grader')
    monkeypatch.setenv('ROS_LOCALHOST_ONLY', '1')
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'SUBNET')
    monkeypatch.delenv('ROS_DISTRO', raising=False)  # the PyPI path: no ROS 2 sourced
    env = clean_environment(tmp_path, {'ROS_DOMAIN_ID': '7'})
    # As under ros2 run on Jazzy: ROBOTIS's nodes pick Jazzy's TwistStamped by ROS_DISTRO.
    distro = (env['ROS_DISTRO'], env['ROS_VERSION'], env['ROS_PYTHON_VERSION'])
    assert distro == ('jazzy', '2', '3')
    assert 'LAB_SECRET' not in env and 'ROS_LOCALHOST_ONLY' not in env
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'OFF'
    assert env['HOME'] == env['TMPDIR'] == str(tmp_path)
    assert env['ROS_DOMAIN_ID'] == '7'


@needs_namespaces
def test_a_run_has_no_network_but_its_own_loopback():
    with socket.create_server(('127.0.0.1', 0)) as server, Sandbox(hostile('network')) as box:
        status, output = run(box, 'network', server.getsockname()[1])
        server.setblocking(False)
        with pytest.raises(BlockingIOError):
            server.accept()
    assert status == 0, output
    assert output.split() == ['tcp', 'ConnectionRefusedError', 'udp', 'OSError'], output


@needs_root
def test_memory_is_limited_across_the_children_of_a_run():
    limits = SandboxLimits(memory_bytes=256 * MiB)
    with Sandbox(hostile('memory'), limits) as box:
        if box.cgroup is None:
            pytest.skip(f'no cgroup here: {box.isolation}')
        status, output = run(box, 'memory', limits.memory_bytes, 0.6)
    alive = [line for line in output.splitlines() if line.startswith('alive')]
    assert alive and alive[0] != 'alive 3', output


def test_a_fork_bomb_stops_at_the_pid_limit_and_ends_with_the_run(python):
    limits = SandboxLimits(pids=24)
    with Sandbox(hostile('fork_bomb'), limits) as box:
        status, output = run(box, 'fork_bomb', python=python)
        started = int(output.split()[-1])
        assert 'refused BlockingIOError' in output, output
        assert 0 < started < limits.pids
    assert box.uid is None or not uid_processes(box.uid)


def test_writing_past_the_file_and_scratch_size_fails():
    limits = SandboxLimits(file_bytes=1 * MiB, scratch_bytes=4 * MiB)
    with Sandbox(hostile('disk'), limits) as box:
        status, output = run(box, 'disk', 2 * limits.file_bytes, limits.file_bytes // 2)
    assert f'big File too large at {limits.file_bytes}' in output, output
    if NAMESPACES:  # the scratch is a tmpfs of scratch_bytes
        assert 'scratch No space left on device' in output, output
        assert int(output.split()[-1]) < limits.scratch_bytes


def test_a_busy_loop_ends_at_the_cpu_limit():
    with Sandbox(hostile('busy'), SandboxLimits(cpu_s=1)) as box:
        status, output = run(box, 'busy', timeout=30)
    assert status != 0 and output.startswith('looping'), (status, output)


def test_the_wall_time_limit_ends_the_run():
    with Sandbox(hostile('sleeper'), SandboxLimits(wall_s=1)) as box:
        status, output = run(box, 'sleeper', timeout=30)
        assert box.timed_out and status != 0, (status, output)


def test_a_daemon_does_not_outlive_its_run(python, tmp_path):
    trace = tmp_path / 'trace'
    with open(trace, 'ab') as written, Sandbox(hostile('daemon')) as box:
        process = box.popen([python, 'daemon.py', str(written.fileno())],
                            clean_environment(box.scratch), pass_fds=[written.fileno()],
                            stdout=subprocess.PIPE)
        assert process.stdout.readline() == b'daemon writing\n'
        assert process.wait(RUN_TIMEOUT_S) != 0
        process.stdout.close()  # the daemon may hold its other end until close()
    assert box.uid is None or not uid_processes(box.uid)
    assert not holders(trace), 'a process of the run still writes the trace'
    assert trace.stat().st_size > 0


def holders(path: Path) -> list[int]:
    """Return the pids of the processes other than this one that have ``path`` open."""
    found = []
    for entry in os.listdir('/proc'):
        if entry.isdigit() and int(entry) != os.getpid():
            try:
                links = [os.readlink(f'/proc/{entry}/fd/{fd}')
                         for fd in os.listdir(f'/proc/{entry}/fd')]
            except OSError:
                continue
            if str(path) in links:
                found.append(int(entry))
    return found


def test_a_run_cannot_signal_the_grader_or_another_run(python):
    with Sandbox(hostile('sleeper')) as victim, Sandbox(hostile('signals')) as box:
        sleeper = victim.popen([python, 'sleeper.py'], clean_environment(victim.scratch),
                               stdout=subprocess.PIPE)
        assert sleeper.stdout.readline() == b'up\n'
        targets = [os.getpid(), *sorted(victim.alive())]
        status, output = run(box, 'signals', *targets, python=python)
        assert sleeper.poll() is None, 'the other run was killed'
        assert victim.alive() >= set(targets[1:]), 'a process of the other run was killed'
    refusals = output.split()
    assert len(refusals) == 2 * len(targets), output
    assert set(refusals) <= {'ProcessLookupError', 'PermissionError'}, output


def owned_by(uid: int, folders) -> list[str]:
    """Return what ``uid`` owns in ``folders`` (entries, not below) and its System V IPC."""
    found = [entry.path for folder in folders for entry in os.scandir(folder)
             if entry.stat(follow_symlinks=False).st_uid == uid]
    for table in ('shm', 'sem', 'msg'):
        header, *rows = Path('/proc/sysvipc', table).read_text().splitlines()
        columns = header.split()
        found += [f'{table} {row.split()[1]}' for row in rows
                  if str(uid) in (row.split()[columns.index('uid')],
                                  row.split()[columns.index('cuid')])]
    return found


@needs_root
def test_nothing_a_run_without_namespaces_wrote_outlives_it(shared_python, monkeypatch):
    # PARTLY sandboxed, the run's uid writes where any user may, starts Fast DDS and makes
    # System V IPC, then dies by SIGKILL: its uid goes to the next run, which must find none.
    monkeypatch.setattr(sandbox_module, 'LAUNCHER_PYTHON', shared_python)
    monkeypatch.setattr(sandbox_module, 'isolation_mode',
                        lambda: IsolationMode('uid', 'namespaces turned off by the test'))
    shared = Path(tempfile.mkdtemp())  # a folder any user may write to, as /tmp/.X11-unix
    try:
        shared.chmod(0o1777)
        places = [path for path in ('/tmp', '/var/tmp', '/dev/shm') if os.path.isdir(path)]
        with Sandbox(hostile('litter')) as box:
            status, output = run(box, 'litter', *places, shared, python=shared_python)
            made = json.loads(output.splitlines()[-1])
            while_it_ran = owned_by(box.uid, [*places, shared])
        left = owned_by(box.uid, [*places, shared])
    finally:
        shutil.rmtree(shared)
    assert status == -signal.SIGKILL, output
    assert [path for path in made if 'fastrtps' in path], made  # Fast DDS's segments
    assert len(while_it_ran) >= 2 * len(places) + 5, while_it_ran
    assert left == []


#: Publishes 20 messages to itself through rclpy and prints how many it received.
PUBLISH_TO_ITSELF = """
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('neighbour')
got = []
node.create_subscription(String, 'chatter', lambda message: got.append(message.data), 10)
publisher = node.create_publisher(String, 'chatter', 10)
for index in range(20):
    publisher.publish(String(data=str(index)))
    for _ in range(50):
        if len(got) > index:
            break
        rclpy.spin_once(node, timeout_sec=0.1)
print(len(got))
"""
#: Run in a /dev/shm of its own: a squatter's run, then beside it a neighbour's trusted side
#: (in the run environment it gets) and a neighbour's run; prints their exit statuses and
#: outputs (JSON).
SQUAT_BESIDE = """
import json, os, subprocess, sys
from sim_bridge.runner.boundary.outside.sandbox import Sandbox
hostile, publish = sys.argv[1], sys.argv[2]
trusted = ('from sim_bridge.common.run_environment import run_environment\\n'
           'with run_environment():\\n    exec(compile(%r, "neighbour", "exec"))' % publish)
with Sandbox({'squatter.py': hostile}) as squatter, Sandbox({}) as neighbour:
    process = squatter.popen([sys.executable, 'squatter.py'], squatter.environment(),
                             stdout=subprocess.PIPE)
    assert process.stdout.readline() == b'squatted\\n'
    ran = [subprocess.run([sys.executable, '-c', trusted], capture_output=True, text=True,
                          timeout=120)]
    # A run's environment, with the libraries of this test's venv (in a folder of its own).
    libraries = {'LD_LIBRARY_PATH': os.environ.get('LD_LIBRARY_PATH', '')}
    ran.append(subprocess.run(
        neighbour.launcher([sys.executable, '-c', publish]),
        env=neighbour.environment(libraries), capture_output=True, text=True, timeout=120))
print(json.dumps([[done.returncode, done.stdout.strip(), done.stderr[-300:]] for done in ran]))
"""


@needs_root
def test_a_run_squatting_fast_dds_files_crashes_no_neighbour(shared_python):
    # Without namespaces every run and the grader share /dev/shm. In a /dev/shm of its own
    # (the machine's other processes keep theirs), a run squats Fast DDS's port files; the
    # trusted side of a neighbouring run and the neighbouring run itself start rclpy.
    unshare = shutil.which('unshare')
    if unshare is None:
        pytest.skip('needs unshare, for a /dev/shm of its own')
    done = subprocess.run(
        [unshare, '--mount', '--propagation', 'private', 'sh', '-c',
         'mount -t tmpfs tmpfs /dev/shm && exec "$@"', 'sh', shared_python, '-c', SQUAT_BESIDE,
         str(HOSTILE / 'squatter.py'), PUBLISH_TO_ITSELF], capture_output=True, text=True,
        timeout=600, env={**os.environ, sandbox_module.NO_NAMESPACES_VARIABLE: '1'})
    assert done.returncode == 0, done.stderr[-2000:]
    trusted, run = json.loads(done.stdout.splitlines()[-1])
    assert (trusted[:2], run[:2]) == ([0, '20'], [0, '20']), (trusted, run)


@needs_root
def test_what_a_dead_graders_run_left_goes_before_its_uid_is_leased_again(monkeypatch):
    uid = sandbox_host.UID_BASE + sandbox_host.UID_COUNT - 1
    monkeypatch.setattr(sandbox_host, 'UID_BASE', uid)
    monkeypatch.setattr(sandbox_host, 'UID_COUNT', 1)
    folder = Path(tempfile.mkdtemp())  # as a run of the uid made it, in /tmp
    os.chown(folder, uid, uid)
    (folder / 'for the next run').write_text('planted')
    try:
        lease = sandbox_host.UidLease()
        lease.release()
        assert not folder.exists()
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@needs_root
def test_each_run_has_a_private_scratch_and_uid(tmp_path):
    with Sandbox(hostile('sleeper')) as first, Sandbox(hostile('sleeper')) as second:
        assert first.uid != second.uid
        for box in (first, second):
            status = box.scratch.stat()
            assert (status.st_uid, status.st_mode & 0o777) == (box.uid, 0o700)
            assert box.scratch.parent == grader_folder()
    assert not first.scratch.exists()


def test_leftover_cleanup_spares_a_live_graders_folder(tmp_path):
    for name in ('lab-sandbox-live', 'lab-sandbox-dead'):
        (tmp_path / name).mkdir()
        (tmp_path / f'{name}.lock').touch()
    held = lock_exclusive(tmp_path / 'lab-sandbox-live.lock')
    try:
        assert remove_leftover_scratch(tmp_path) == [tmp_path / 'lab-sandbox-dead']
        assert (tmp_path / 'lab-sandbox-live').is_dir()
        assert remove_leftover_scratch(Path(tempfile.gettempdir())).count(grader_folder()) == 0
        assert grader_folder().is_dir()
    finally:
        os.close(held)


def test_rclpy_runs_in_the_sandbox_within_300_mib(capsys):
    with Sandbox(hostile('ros_self')) as box:
        status, output = run(box, 'ros_self')
        peak = box.memory_peak_bytes()
    assert status == 0 and output.split()[0] == 'OK', output
    with capsys.disabled():
        print(f'\nsandboxed rclpy node: peak RSS {int(output.split()[1]) / MiB:.0f} MiB, '
              f'run peak (cgroup) {peak and round(peak / MiB)} MiB; {box.isolation}')
    assert int(output.split()[1]) <= 300 * MiB and (peak is None or peak <= 300 * MiB)


def test_without_isolation_the_sandbox_says_so(monkeypatch):
    monkeypatch.setattr(os, 'geteuid', lambda: 1000)
    monkeypatch.setattr(sandbox_module.shutil, 'which', lambda name: None)
    isolation_mode.cache_clear()
    try:
        mode = sandbox_module.isolation_mode()
        assert mode == IsolationMode('none', 'bubblewrap is not installed '
                                             '(apt-get install bubblewrap)')
        with Sandbox(hostile('sleeper')) as box:
            assert box.isolation.startswith('NOT sandboxed: bubblewrap is not installed')
    finally:
        isolation_mode.cache_clear()


@needs_namespaces
def test_bubblewrap_found_off_a_runs_path_is_run_by_its_own_path(tmp_path, monkeypatch):
    # An instructor's bwrap in a folder of their own PATH (~/bin, say): a run's launcher has
    # a PATH of its own, so the grader runs bwrap by the path it found.
    program, called = tmp_path / 'bwrap', tmp_path / 'called'
    program.write_text(f'#!/bin/sh\necho called > {called}\nexec {shutil.which("bwrap")} "$@"\n')
    program.chmod(0o755)
    mode = dataclasses.replace(isolation_mode(), bwrap_program=str(program))
    monkeypatch.setattr(sandbox_module, 'isolation_mode', lambda: mode)
    with Sandbox(hostile('sleeper')) as box, tempfile.TemporaryFile() as output:
        process = box.popen([sys.executable, '-c', "print('ran')"],
                            clean_environment(box.scratch), stdout=output,
                            stderr=subprocess.STDOUT)
        assert process.wait(RUN_TIMEOUT_S) == 0
        output.seek(0)
        assert output.read().decode() == 'ran\n'
    assert called.read_text() == 'called\n'


@pytest.mark.parametrize('python', ['uid'], indirect=True)
def test_without_namespaces_the_answers_are_closed_to_a_students_run_not_the_kits(python):
    folder = Path(tempfile.mkdtemp())  # a kit that every user reaches, as on Gradescope
    try:
        folder.chmod(0o755)
        answer = folder / 'wall_follow.py'
        answer.write_text('ANSWER = 42\n')
        answer.chmod(0o644)
        with Sandbox(hostile('snoop'), reference_nodes=True, hidden_files=[str(answer)]) as box:
            student = json.loads(run(box, 'snoop', os.getpid(), answer, '--write',
                                     python=python)[1].splitlines()[-1])
        with Sandbox(hostile('snoop'), reference_nodes=True) as box:  # the kit's own node
            kit = json.loads(run(box, 'snoop', os.getpid(), answer, '--write',
                                 python=python)[1].splitlines()[-1])
        status = answer.stat()
    finally:
        shutil.rmtree(folder)
    assert (student[str(answer)], kit[str(answer)]) == ('PermissionError', 'GOT "ANSWER = 42\\n"')
    assert (status.st_mode & 0o777, status.st_gid) == (0o640, sandbox_module.ANSWERS_GID)


@pytest.mark.parametrize('python', ['uid'], indirect=True)
def test_without_namespaces_a_program_the_run_cannot_reach_is_one_clear_line(
        python, monkeypatch):
    folder = Path(tempfile.mkdtemp())
    try:
        folder.chmod(0o755)
        closed = folder / 'closed'  # as pyenv's Python in /root
        closed.mkdir(mode=0o700)
        program = closed / 'python3'
        program.write_text('#!/bin/sh\necho never\n')
        program.chmod(0o755)
        with Sandbox(hostile('sleeper')) as box, \
                pytest.raises(sandbox_module.SandboxError) as refused:
            box.popen([str(program)], clean_environment(box.scratch))
        # The grader says so as it starts, of the Python its node processes would run.
        monkeypatch.setattr(sys, 'executable', str(program))
        line = isolation_line(SandboxLimits())
    finally:
        shutil.rmtree(folder)
    said = (f'cannot reach {program}: {closed} is closed to them (drwx------); install the kit '
            'and its Python where other users can read them')
    assert str(refused.value).startswith(f'PARTLY sandboxed: uid {box.uid} (no namespaces) {said}')
    assert line.startswith('PARTLY sandboxed: uid ') and said in line
    assert line.endswith('(no run can start)')


def test_bad_limits_and_file_names_are_refused_in_one_line():
    with pytest.raises(ValueError, match='memory_bytes must be a positive whole number'):
        SandboxLimits(memory_bytes=0)
    with pytest.raises(ValueError, match=r'memory_bytes .* not 1e\+18'):
        SandboxLimits(memory_bytes=1e18)
    with pytest.raises(ValueError, match='wall_s must be a positive number below 1e\\+15'):
        SandboxLimits(wall_s=-1)
    with pytest.raises(ValueError, match='must be a relative path'):
        Sandbox({'../escape.py': HOSTILE / 'sleeper.py'})
    with pytest.raises(ValueError, match='over the scratch limit'):
        Sandbox(hostile('sleeper'), SandboxLimits(scratch_bytes=10))


def test_a_sigkilled_run_reports_its_signal():
    with Sandbox(hostile('sleeper')) as box:
        process = box.popen([sys.executable, 'sleeper.py'], clean_environment(box.scratch),
                            stdout=subprocess.PIPE)
        assert process.stdout.readline() == b'up\n'
        box.kill()
        assert process.wait(30) == -signal.SIGKILL


def cpu_group(pid: int) -> str | None:
    """Return the cpu control group of process ``pid`` (v1's cpu line, else v2's), or None."""
    try:
        lines = Path(f'/proc/{pid}/cgroup').read_text().splitlines()
    except OSError:
        return None
    groups = {names: path for _, names, path in (line.split(':', 2) for line in lines)}
    return next((path for names, path in groups.items() if 'cpu' in names.split(',')),
                groups.get(''))


@needs_root
def test_busy_loops_in_a_new_session_share_one_cpu_group_of_their_run(tmp_path):
    # Twelve busy loops weigh as one run: the kernel shares the CPUs between runs' groups.
    with Sandbox(hostile('busy_crowd'), SandboxLimits(cpu_s=60)) as box:
        if box.cgroup is None or not box.cgroup.cpu:
            pytest.skip(f'no cgroup cpu controller here: {box.isolation}')
        with (tmp_path / 'output').open('w+') as output:
            box.popen([sys.executable, 'busy_crowd.py'], clean_environment(box.scratch),
                      stdout=output, stderr=subprocess.STDOUT)
            while 'started' not in Path(output.name).read_text():
                assert box.alive(), Path(output.name).read_text()
                time.sleep(0.01)  # a condition waited for, not a pace
            groups = {pid: cpu_group(pid) for pid in box.alive()}
    assert len(groups) >= 13 and len(set(groups.values()) - {None}) == 1
    [group] = set(groups.values()) - {None}
    assert group != cpu_group(os.getpid()) and 'a fair share of the CPU' in box.isolation
