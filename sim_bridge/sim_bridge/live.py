"""
Run a lab task live: the simulator and the task's node as two ROS 2 processes, as launch does.

``python -m sim_bridge.live TASK [--world W] [--robot NAME [--robot-pose X Y YAW]] [--duration S]
[--gui] [--rtf F]`` (``./lab live``)
starts what ``ros2 launch sim_bridge lab.launch.py task:=TASK`` starts on a ROS 2 machine, on a
machine that has only Python (launch and launch_ros are not on PyPI):

- ``sim_bridge-1``: ``python -m sim_bridge.bridge --ros-args --params-file <sim.yaml>
  -p world:=W -p gui:=... -p real_time_factor:=F [-p robot:=NAME -p robot_pose:=[X, Y, YAW]]``,
  the simulator (with the robot model NAME spawned at the pose) stepping its physics on its
  own steady-clock timer, publishing /scan, /odom and /clock;
- ``<node>-2``: the task's scan_pkg node (the console script's module, ``python -m
  scan_pkg.<node>``) with ``--ros-args --params-file <params/<node>.yaml> -p
  use_sim_time:=true`` (the params file where scan_pkg ships one).

The task table (node and world of each task) is sim_bridge.lab_tasks, the one the launch file
reads. The two processes talk over DDS like any two ROS 2 processes: each gets this
environment with ``PYTHONUNBUFFERED=1`` and ``RCUTILS_LOGGING_BUFFERED_STREAM=1`` (every
line is written when it ends), the user's ``ROS_DOMAIN_ID``, and automatic discovery on:
``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` (which hides a process from every other) becomes
``LOCALHOST``, with a warning.

Output is ros2 launch's with ``output='screen'``: each line a child writes (stdout and stderr,
in the order written) is printed as it arrives, prefixed with the process's name,
``[wall_follow-2] [INFO] [1795499925.029450212] [wall_follow]: following the wall on the
right``; the lines of this module are launch's, ``[INFO] [sim_bridge-1]: process started with
pid [1234]``, ``[INFO] [wall_follow-2]: process has finished cleanly [pid 1235]`` or ``[ERROR]
[wall_follow-2]: process has died [pid 1235, exit code 1, cmd '...'].``

Stopping, at Ctrl-C or after ``--duration`` wall seconds: SIGINT to the processes in reverse
order of start, each waited for before the next, so the node's last zero command reaches a
simulator that still runs (the driving nodes send one when interrupted; SIGTERM would end them
without it). A process still running ``sigterm_timeout`` (5 s) after SIGINT gets SIGTERM, and
``sigkill_timeout`` (5 s) later SIGKILL, as launch does. Exit status: 0 when every process
ended cleanly (status 0) after being asked to; 1 when one ended before the run did (the others
are stopped, and the last line names it) or did not end cleanly; 2 for a bad command line.

Unlike launch, the children run in a session of their own: Ctrl-C in the terminal reaches this
process only, which stops them in order (launch's children get the terminal's SIGINT all at
once). SIGINT and SIGTERM are at their default actions in the children even when this process
was started with them ignored (in the background); on Linux each child also gets SIGINT if this
process dies without stopping it.

The pure parts, the command lines of a task and the lines printed, are plain functions;
:class:`LiveRun` runs processes, and :func:`run_live` is the whole command.
"""

import argparse
from importlib import metadata
import math
import os
from pathlib import Path
import queue
import signal
import subprocess
import sys
import threading
import time
from typing import Callable, Iterable, Mapping, NamedTuple, Sequence

from sim_bridge import paths
from sim_bridge.lab_tasks import LAB_TASKS

#: The name of this module's own log lines (launch's are ``[launch]``).
LOGGER = 'live'
#: The simulator's executable name (its console script), as launch names its process.
BRIDGE_EXECUTABLE = 'sim_bridge'
#: Wall seconds after SIGINT before SIGTERM, and after SIGTERM before SIGKILL (launch's).
SIGTERM_TIMEOUT_S = 5.0
SIGKILL_TIMEOUT_S = 5.0
#: Wall seconds the next process keeps running after one stopped: the zero command it sent
#: on the way out reaches the simulator and acts.
SETTLE_S = 0.3
#: Wall seconds to wait for a dead process's last output before reporting its end anyway.
OUTPUT_GRACE_S = 1.0
#: Longest wait (s) for output before checking the processes again.
POLL_S = 0.05
#: Most lines printed before checking the processes again.
MAX_LINES_PER_POLL = 1000
DISCOVERY_VARIABLE = 'ROS_AUTOMATIC_DISCOVERY_RANGE'

Output = Callable[[str], None]


class ProcessSpec(NamedTuple):
    """One process to start: its executable's name (for the prefix) and its command line."""

    executable: str
    cmd: tuple[str, ...]


# ---------------------------------------------------------------------------------------------
# The pure parts: lines printed, environments and command lines.

def process_names(specs: Sequence[ProcessSpec]) -> list[str]:
    """Return launch's names of ``specs``' processes: ``<executable>-<n>``, n from 1."""
    return [f'{spec.executable}-{number}' for number, spec in enumerate(specs, start=1)]


def prefixed(name: str, line: str) -> str:
    """Return a child's output ``line`` as launch prints it: ``[name] line``."""
    return f'[{name}] {line}'


def log_line(level: str, logger: str, message: str) -> str:
    """Return a line of launch's own log: ``[LEVEL] [logger]: message``."""
    return f'[{level}] [{logger}]: {message}'


def started_line(name: str, pid: int) -> str:
    """Return launch's line for a process that started."""
    return log_line('INFO', name, f'process started with pid [{pid}]')


def ended_line(name: str, pid: int, returncode: int, cmd: Sequence[str]) -> str:
    """Return launch's line for a process that ended (status 0: cleanly; else died)."""
    if returncode == 0:
        return log_line('INFO', name, f'process has finished cleanly [pid {pid}]')
    command = ' '.join(cmd)
    return log_line('ERROR', name, f'process has died [pid {pid}, exit code {returncode}, '
                                   f"cmd '{command}'].")


def signal_line(name: str, signal_name: str) -> str:
    """Return launch's line for a signal sent to a process."""
    return log_line('INFO', name, f"sending signal '{signal_name}' to process[{name}]")


def escalation_line(name: str, timeout_s: float, sent: str, next_signal: str) -> str:
    """Return launch's line for a process still running ``timeout_s`` (s) after ``sent``."""
    return log_line('ERROR', name, f"process[{name}] failed to terminate '{timeout_s:g}' seconds "
                                   f"after receiving '{sent}', escalating to '{next_signal}'")


def child_environment(base: Mapping[str, str]) -> tuple[dict[str, str], str | None]:
    """
    Return the environment of a live child made from ``base``, and a warning or None.

    Output line-buffered (Python's and rcutils' logging); discovery on across processes:
    ``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` becomes ``LOCALHOST`` (the warning says so). The rest,
    ``ROS_DOMAIN_ID`` included, is ``base``'s.
    """
    env = dict(base)
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '1'
    warning = None
    if env.get(DISCOVERY_VARIABLE, '').upper() == 'OFF':
        env[DISCOVERY_VARIABLE] = 'LOCALHOST'
        warning = (f'{DISCOVERY_VARIABLE}=OFF hides each process from every other: the live '
                   'processes run with LOCALHOST (this machine only)')
    return env, warning


def package_params_file(package: str, name: str) -> Path | None:
    """
    Return ``params/<name>`` of ``package`` (scan_pkg, sim_bridge), or None when it has none.

    From the source checkout (``<repo>/<package>/params``) when this module runs from one,
    else from the package's installed share directory (a colcon or pip install).
    """
    root = paths.repo_root()
    if root is not None and (root / package).is_dir():
        path = root / package / 'params' / name
        return path if path.is_file() else None
    share = None
    if os.environ.get('AMENT_PREFIX_PATH'):
        from ament_index_python.packages import get_package_share_directory
        from ament_index_python.packages import PackageNotFoundError
        try:
            share = Path(get_package_share_directory(package))
        except PackageNotFoundError:
            pass
    if share is None:
        share = Path(sys.prefix) / 'share' / package
    path = share / 'params' / name
    return path if path.is_file() else None


def node_module(executable: str) -> tuple[str, str]:
    """
    Return (module, function) of the console script ``executable`` (a scan_pkg node).

    Read from the installed entry points; ``scan_pkg.<executable>``'s ``main`` when the script
    is not installed (a checkout on the path).
    """
    for entry in metadata.entry_points(group='console_scripts', name=executable):
        module, _, function = entry.value.partition(':')
        return module.strip(), (function.strip() or 'main')
    return f'scan_pkg.{executable}', 'main'


def python_command(module: str, function: str = 'main', python: str = sys.executable
                   ) -> list[str]:
    """Return the command line running ``module.function()`` as its console script would."""
    if function == 'main':
        return [python, '-m', module]  # each node module calls main() when run as a script
    return [python, '-c', f'import sys; from {module} import {function}; sys.exit({function}())']


def ros_overrides(params: Mapping[str, str]) -> list[str]:
    """Return ``-p name:=value`` arguments for ``params`` (values as --ros-args types them)."""
    arguments = []
    for name, value in params.items():
        arguments += ['-p', f'{name}:={value}']
    return arguments


def bridge_spec(world: str, *, gui: bool = False, real_time_factor: float = 1.0,
                robot: str | None = None, robot_pose: Sequence[float] | None = None,
                params: Mapping[str, str] | None = None, python: str = sys.executable
                ) -> ProcessSpec:
    """
    Return the simulator's process: ``world`` (a name or a path), its window, its pace.

    As sim.launch.py starts it: the params file ``sim.yaml``, then ``world`` and ``gui``;
    here also ``real_time_factor`` (× wall-clock speed), the robot model ``robot`` to spawn
    instead of the world's and its ``robot_pose`` (x m, y m, yaw rad), and ``params``
    overrides.
    """
    cmd = [*python_command('sim_bridge.bridge', python=python), '--ros-args']
    params_file = package_params_file('sim_bridge', 'sim.yaml')
    if params_file is not None:
        cmd += ['--params-file', str(params_file)]
    spawn = {}
    if robot is not None:
        spawn['robot'] = robot
    if robot_pose is not None:
        spawn['robot_pose'] = f"[{', '.join(repr(float(value)) for value in robot_pose)}]"
    cmd += ros_overrides({'world': world, 'gui': 'true' if gui else 'false',
                          'real_time_factor': repr(float(real_time_factor)), **spawn,
                          **(params or {})})
    return ProcessSpec(BRIDGE_EXECUTABLE, tuple(cmd))


def node_spec(executable: str, *, params: Mapping[str, str] | None = None,
              python: str = sys.executable) -> ProcessSpec:
    """
    Return a scan_pkg node's process, as lab.launch.py starts it, with ``params`` overrides.

    ``--ros-args --params-file params/<executable>.yaml`` (when scan_pkg ships one)
    ``-p use_sim_time:=true``, then ``-p name:=value`` for each of ``params``.
    """
    cmd = [*python_command(*node_module(executable), python=python), '--ros-args']
    params_file = package_params_file('scan_pkg', executable + '.yaml')
    if params_file is not None:
        cmd += ['--params-file', str(params_file)]
    cmd += ros_overrides({'use_sim_time': 'true', **(params or {})})
    return ProcessSpec(executable, tuple(cmd))


def task_specs(task: str, *, world: str | None = None, gui: bool = False,
               real_time_factor: float = 1.0, robot: str | None = None,
               robot_pose: Sequence[float] | None = None,
               params: Mapping[str, Mapping[str, str]] | None = None,
               python: str = sys.executable) -> list[ProcessSpec]:
    """
    Return the processes of lab task ``task``: the simulator, then the task's node.

    ``world`` replaces the task's world, ``robot`` (a model name) the world's robot (the lab
    robot in every task's world), ``robot_pose`` (x m, y m, yaw rad) its start; ``params``
    maps a node name (``sim_bridge`` or the task's node) to its parameter overrides.
    ValueError for an unknown task or for ``params`` naming another node.
    """
    if task not in LAB_TASKS:
        raise ValueError(f"unknown task '{task}': choose one of {', '.join(LAB_TASKS)}")
    lab_task = LAB_TASKS[task]
    params = dict(params or {})
    unknown = set(params) - {BRIDGE_EXECUTABLE, lab_task.node}
    if unknown:
        raise ValueError(f"parameters for {', '.join(sorted(unknown))}: task '{task}' runs "
                         f'the nodes {BRIDGE_EXECUTABLE} and {lab_task.node}')
    return [bridge_spec(world or lab_task.world, gui=gui, real_time_factor=real_time_factor,
                        robot=robot, robot_pose=robot_pose,
                        params=params.get(BRIDGE_EXECUTABLE), python=python),
            node_spec(lab_task.node, params=params.get(lab_task.node), python=python)]


def print_line(line: str) -> None:
    """Print ``line`` on stdout at once (the default output of a live run)."""
    print(line, flush=True)


# ---------------------------------------------------------------------------------------------
# Running processes.

def _child_setup() -> Callable[[], None] | None:
    """
    Return a function to run in each child before its program starts, or None.

    It sets SIGINT and SIGTERM back to their default action: a child inherits an ignored
    signal, and a command started in the background has SIGINT ignored, which would leave the
    driving nodes (whose Ctrl-C handler is Python's, installed only where SIGINT is not
    ignored) deaf to the SIGINT that stops them. On Linux the child also gets SIGINT when this
    process dies (prctl PR_SET_PDEATHSIG).
    """
    import ctypes
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        set_action = libc.signal
    except (OSError, AttributeError):
        return None
    set_action.restype = ctypes.c_void_p
    set_action.argtypes = (ctypes.c_int, ctypes.c_void_p)
    prctl = getattr(libc, 'prctl', None) if sys.platform.startswith('linux') else None
    pr_set_pdeathsig = 1

    def setup() -> None:
        for signal_number in (signal.SIGINT, signal.SIGTERM):
            set_action(int(signal_number), None)  # NULL: SIG_DFL
        if prctl is not None:
            prctl(pr_set_pdeathsig, int(signal.SIGINT))

    return setup


class LiveRun:
    """
    Start processes, print their output interleaved, stop them in order.

    ``specs``' processes are started by :meth:`start` with :func:`child_environment` of
    ``env`` (default: this process's). Each line they write, and each of launch's lines about
    them, goes to ``out`` as it comes (default: stdout). With ``on_line``, each process's
    stdout and stderr are read apart, and ``on_line(index, stream, line)`` ('STDOUT' or
    'STDERR') is called in a reader thread as each line arrives, before ``out`` prints it. As a
    context manager it stops every process still running when the block ends, however it ends.
    """

    def __init__(self, specs: Iterable[ProcessSpec], *, env: Mapping[str, str] | None = None,
                 out: Output = print_line, sigterm_timeout_s: float = SIGTERM_TIMEOUT_S,
                 sigkill_timeout_s: float = SIGKILL_TIMEOUT_S, settle_s: float = SETTLE_S,
                 on_line: Callable[[int, str, str], None] | None = None):
        self.specs = list(specs)
        self.names = process_names(self.specs)
        self.env, self.env_warning = child_environment(os.environ if env is None else env)
        self.out = out
        self.on_line = on_line
        self.sigterm_timeout_s = sigterm_timeout_s
        self.sigkill_timeout_s = sigkill_timeout_s
        self.settle_s = settle_s
        self.processes: list[subprocess.Popen] = []
        #: Exit status of each process that ended, by name.
        self.returncodes: dict[str, int] = {}
        self._lines: queue.Queue = queue.Queue()
        self._eof: set[int] = set()
        self._open_streams: dict[int, int] = {}
        self._exit_seen: dict[int, float] = {}
        self._stopping: set[int] = set()
        self._readers: list[threading.Thread] = []

    def __enter__(self) -> 'LiveRun':
        return self

    def __exit__(self, *exc_info) -> None:
        self.stop_all()

    def start(self) -> None:
        """Start every process in order; print launch's 'process started' line for each."""
        if self.env_warning:
            self.out(log_line('WARNING', LOGGER, self.env_warning))
        preexec = _child_setup()
        for index, (spec, name) in enumerate(zip(self.specs, self.names)):
            apart = self.on_line is not None
            process = subprocess.Popen(
                spec.cmd, env=self.env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                stderr=subprocess.PIPE if apart else subprocess.STDOUT,
                start_new_session=True, preexec_fn=preexec)
            self.processes.append(process)
            self.out(started_line(name, process.pid))
            streams = [('STDOUT', process.stdout), ('STDERR', process.stderr)][:1 + apart]
            self._open_streams[index] = len(streams)
            for stream_name, stream in streams:
                reader = threading.Thread(target=self._read, args=(index, stream_name, stream),
                                          name=f'live-output-{name}', daemon=True)
                reader.start()
                self._readers.append(reader)

    def _read(self, index: int, stream_name: str, stream) -> None:
        for raw in iter(stream.readline, b''):
            line = raw.decode('utf-8', errors='replace').rstrip('\r\n')
            if self.on_line is not None:
                self.on_line(index, stream_name, line)
            self._lines.put((index, line))
        stream.close()
        self._lines.put((index, None))

    def running(self) -> list[str]:
        """Return the names of the started processes whose end is not reported yet."""
        return [self.names[index] for index in range(len(self.processes))
                if self.names[index] not in self.returncodes]

    def pump(self, timeout_s: float) -> list[str]:
        """
        Print output and report ends for up to ``timeout_s`` (s) or until a process ends.

        Return the names of the processes whose end was reported in this call.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            ended = self._report_ends()
            remaining = deadline - time.monotonic()
            if ended or remaining <= 0.0:
                return ended
            try:
                index, line = self._lines.get(timeout=min(remaining, POLL_S))
            except queue.Empty:
                continue
            for count in range(MAX_LINES_PER_POLL):
                if count:
                    try:
                        index, line = self._lines.get_nowait()
                    except queue.Empty:
                        break
                if line is None:
                    self._open_streams[index] -= 1
                    if not self._open_streams[index]:
                        self._eof.add(index)
                else:
                    self.out(prefixed(self.names[index], line))

    def _report_ends(self) -> list[str]:
        ended = []
        now = time.monotonic()
        for index, process in enumerate(self.processes):
            name = self.names[index]
            if name in self.returncodes or process.poll() is None:
                continue
            seen = self._exit_seen.setdefault(index, now)
            # Its last lines first: they are still in the pipe until its end of file.
            if index in self._eof or now - seen >= OUTPUT_GRACE_S:
                self.returncodes[name] = process.returncode
                self.out(ended_line(name, process.pid, process.returncode, process.args))
                ended.append(name)
        return ended

    def wait(self, duration_s: float | None = None) -> str | None:
        """
        Print output for ``duration_s`` wall seconds (None: no limit) or until a process ends.

        Return the name of a process that ended on its own (not stopped here), or None when
        the time was up.
        """
        deadline = math.inf if duration_s is None else time.monotonic() + duration_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return None
            for name in self.pump(min(remaining, 1.0)):
                if self.names.index(name) not in self._stopping:
                    return name

    def stop(self, name: str) -> int | None:
        """
        Stop the process ``name`` as launch does: SIGINT, then SIGTERM, then SIGKILL.

        Each signal is sent only if the process still runs after the previous one's timeout;
        output keeps being printed meanwhile. A Ctrl-C here skips to the next signal. Return
        its exit status (None if it was never started).
        """
        index = self.names.index(name)
        if index >= len(self.processes):
            return None
        self._stopping.add(index)
        steps = [(signal.SIGINT, self.sigterm_timeout_s, 'SIGTERM'),
                 (signal.SIGTERM, self.sigkill_timeout_s, 'SIGKILL'),
                 (signal.SIGKILL, self.sigkill_timeout_s, None)]
        for signal_number, timeout_s, next_signal in steps:
            if name in self.returncodes:
                break
            self._signal(index, signal_number)
            deadline = time.monotonic() + timeout_s
            try:
                while name not in self.returncodes and time.monotonic() < deadline:
                    self.pump(deadline - time.monotonic())
            except KeyboardInterrupt:
                continue
            if name not in self.returncodes and next_signal is not None:
                self.out(escalation_line(name, timeout_s, signal_number.name, next_signal))
        return self.returncodes.get(name)

    def _signal(self, index: int, signal_number: signal.Signals) -> None:
        process = self.processes[index]
        if process.poll() is not None:
            return
        self.out(signal_line(self.names[index], signal_number.name))
        try:
            process.send_signal(signal_number)
        except ProcessLookupError:
            pass

    def stop_all(self) -> None:
        """Stop every running process, the last started first, letting each settle."""
        stopped_one = False
        for name in reversed(self.names[:len(self.processes)]):
            if name in self.returncodes:
                continue
            if stopped_one and self.settle_s > 0.0:
                try:
                    self.pump(self.settle_s)
                except KeyboardInterrupt:
                    pass
                if name in self.returncodes:
                    continue
            self.stop(name)
            stopped_one = True
        for reader in self._readers:
            reader.join(timeout=OUTPUT_GRACE_S)
        self.pump(0.0)

    def clean(self) -> bool:
        """Tell whether every started process ended with status 0."""
        return (len(self.returncodes) == len(self.processes)
                and all(code == 0 for code in self.returncodes.values()))


class _Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP received: stop as at Ctrl-C."""


def _raise_interrupt(signal_number, frame) -> None:
    raise _Interrupted(signal.Signals(signal_number).name)


def run_live(specs: Sequence[ProcessSpec], duration_s: float | None = None, *,
             env: Mapping[str, str] | None = None, out: Output = print_line,
             sigterm_timeout_s: float = SIGTERM_TIMEOUT_S,
             sigkill_timeout_s: float = SIGKILL_TIMEOUT_S) -> int:
    """
    Run ``specs``' processes for ``duration_s`` wall seconds (None: until Ctrl-C); stop them.

    Return 0 when every process ended cleanly when asked to, 1 when one ended early (the last
    line names it) or any did not end cleanly. SIGTERM and SIGHUP stop the run as Ctrl-C does
    (in the main thread).
    """
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for signal_number in (signal.SIGTERM, signal.SIGHUP):
            handlers[signal_number] = signal.signal(signal_number, _raise_interrupt)
    ended = None
    try:
        with LiveRun(specs, env=env, out=out, sigterm_timeout_s=sigterm_timeout_s,
                     sigkill_timeout_s=sigkill_timeout_s) as run:
            try:
                run.start()
                ended = run.wait(duration_s)
            except KeyboardInterrupt as interrupt:
                message = (f'{interrupt} received' if isinstance(interrupt, _Interrupted)
                           else 'user interrupted with ctrl-c (SIGINT)')
                out(log_line('WARNING', LOGGER, message))
    finally:
        for signal_number, handler in handlers.items():
            signal.signal(signal_number, handler)
    if ended is not None:
        out(log_line('ERROR', LOGGER, f'{ended} ended before the run did (exit code '
                                      f'{run.returncodes[ended]}): stopped the others'))
        return 1
    if not run.clean():
        unclean = [name for name in run.names if run.returncodes.get(name) != 0]
        out(log_line('ERROR', LOGGER, f"{', '.join(unclean)} did not end cleanly"))
        return 1
    return 0


# ---------------------------------------------------------------------------------------------
# The command line.

def parse_param(text: str) -> tuple[str, str, str]:
    """Split ``NODE:NAME=VALUE`` into its parts; ValueError when it is not of that form."""
    node, colon, rest = text.partition(':')
    name, equals, value = rest.partition('=')
    if not (colon and equals and node and name):
        raise ValueError(f"parameter '{text}' is not NODE:NAME=VALUE")
    return node, name, value


def positive_float(text: str) -> float:
    """Return ``text`` as a positive finite float (argparse type)."""
    value = float(text)
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f'must be positive and finite, got {text}')
    return value


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line of ``./lab live``."""
    parser = argparse.ArgumentParser(
        prog='./lab live', description=__doc__.strip().splitlines()[0],
        epilog='Stop with Ctrl-C: the node first, then the simulator.')
    parser.add_argument('task', choices=list(LAB_TASKS), help='lab task')
    parser.add_argument('--world', help="world name or path instead of the task's")
    parser.add_argument('--robot', metavar='NAME',
                        help="robot model to spawn instead of the world's (a model folder, "
                             'also from GZ_SIM_RESOURCE_PATH / GAZEBO_MODEL_PATH)')
    parser.add_argument('--robot-pose', type=float, nargs=3, metavar=('X', 'Y', 'YAW'),
                        help="the robot's start pose (m, m, rad; default: the world's)")
    parser.add_argument('--duration', type=positive_float, metavar='S',
                        help='stop after this many wall seconds (default: at Ctrl-C)')
    parser.add_argument('--gui', action='store_true', help='open the pybullet window')
    parser.add_argument('--rtf', type=positive_float, default=1.0, metavar='F',
                        help='real-time factor of the simulator (default 1.0)')
    parser.add_argument('--param', action='append', default=[], metavar='NODE:NAME=VALUE',
                        help='parameter override for the node NODE (sim_bridge or the '
                             "task's), typed as --ros-args -p types it (repeatable)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Run a lab task live from the command line; return the exit status."""
    args = parse_args(argv)
    try:
        params: dict[str, dict[str, str]] = {}
        for text in args.param:
            node, name, value = parse_param(text)
            params.setdefault(node, {})[name] = value
        if args.world is not None:
            paths.find_world(args.world)
        if args.robot is not None:
            paths.find_model(args.robot)
        specs = task_specs(args.task, world=args.world, gui=args.gui,
                           real_time_factor=args.rtf, robot=args.robot,
                           robot_pose=args.robot_pose, params=params)
    except (ValueError, FileNotFoundError) as error:
        print(f'error: {error}', file=sys.stderr)
        return 2
    duration = f'for {args.duration:g} s' if args.duration else 'until Ctrl-C'
    print_line(log_line('INFO', LOGGER, f'task {args.task} live, {duration}: '
                                        f"{', '.join(process_names(specs))}"))
    return run_live(specs, args.duration)


if __name__ == '__main__':
    sys.exit(main())
