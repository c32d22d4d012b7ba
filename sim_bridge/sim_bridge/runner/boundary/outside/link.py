"""
The trust boundary: each student node file in a process of its own, in lockstep over pipes.

The simulator and the runner's nodes run here (sim_bridge.runner.stepped_run); each target
node file runs in a process of its own (sim_bridge.runner.boundary.inside.agent).

Nothing of the node's process runs here and nothing it sends is code: frames
(sim_bridge.runner.boundary.wire.frames) carrying the CDR bytes of its nodes' messages, the ROS
time it wakes at, and what its nodes are (names, topics, parameter names); and its printed text,
read from its stdout and stderr. Each message is checked before it is published here: its topic's
name, its type one of the installed message packages of INTERFACE_PACKAGES, its bytes deserialized
as that type, its size within the caps of sim_bridge.runner.boundary.outside.boundary_checks (as
the graph's). Anything else fails that run, with a one-line reason, and nothing else.

Lockstep: the simulator steps physics; after a step that published something a node process
subscribes to, or reached the ROS time it wakes at, the run sends it ``advance`` (the sim time
and those messages) and waits for ``idle`` (its messages, its next wake). On the steps between,
nothing crosses. The same seed gives the same messages in the same order.
"""

import os
import re
import selectors
import signal
import subprocess
import sys
import time
from typing import Any, Callable, Sequence

from sim_bridge.runner.boundary.outside.boundary_checks import checked_graph, Refused
from sim_bridge.runner.boundary.outside.node_sandbox import NodeSandbox
from sim_bridge.runner.boundary.outside.sandbox import Sandbox
from sim_bridge.runner.boundary.outside.topics import TopicEnds
from sim_bridge.runner.boundary.wire.frames import (
    AGENT_KINDS, encode, Frame, FrameDecoder, FrameError, Message)
from sim_bridge.runner.node_output import StreamLines
from sim_bridge.runner.targets import is_library_frame

#: Wall seconds a node process may take to start (Python, rclpy, its imports, constructors).
START_TIMEOUT_S = 60.0
#: Wall seconds a node process may take to handle one step before the run fails.
EXCHANGE_TIMEOUT_S = 30.0
#: Exchanges in one sim step before the nodes are taken to be in a loop of messages.
MAX_EXCHANGES_PER_STEP = 1000
READ_BYTES = 2 ** 16
READS_AT_ONCE = 16
#: Bytes of a run's output kept (its nodes' stdout and stderr); the rest are counted.
OUTPUT_CAP_BYTES = 8 * 2 ** 20
#: Wall seconds a stuck node process gets to dump its stack; a line of that dump.
STACK_DUMP_S = 2.0
#: Lines of a crashed process's output kept as its failure's traceback.
LAST_LINES = 40
STACK_LINE = re.compile(r'\s*File "(?P<file>[^"]+)", line (?P<line>\d+) in (?P<name>\S+)')
#: Wall seconds a node process that closed its pipe gets to end (its output read meanwhile).
END_GRACE_S = 10.0
#: Wall seconds a node process gets to end when told to, before it is killed.
STOP_GRACE_S = 1.0
NANOSECONDS_PER_SECOND = 10 ** 9


class AgentFailure(Exception):
    """
    A node process that failed or ended; ``node`` is the node named, ``traceback`` its own part.

    ``returned``: its main() returned (rclpy.shutdown() in a callback, a loop that ended),
    as a process that exits with status 0: the run ends there, not as a failure.
    """

    def __init__(self, message: str, node: str = '', traceback: str = '',
                 returned: bool = False, error_line: str = '', place: str = ''):
        super().__init__(message)
        self.node = node
        self.place = place
        #: The node ran out of memory (its process's limit).
        self.memory = False
        self.traceback = traceback
        self.returned = returned
        self.error_line = error_line


class AgentStartError(Exception):
    """A TARGET whose process could not start its nodes; ``traceback`` is the node's part."""

    def __init__(self, message: str, traceback: str = ''):
        super().__init__(message)
        self.traceback = traceback


def start_process(sandbox: Sandbox, argv: Sequence[str], env: dict[str, str],
                  pass_fds: Sequence[int]) -> subprocess.Popen:
    """Start a node process in ``sandbox``; its stdout and stderr are pipes, its stdin nothing."""
    return sandbox.popen(argv, env, pass_fds=pass_fds, stdin=subprocess.DEVNULL,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)


class Agent(TopicEnds):
    """
    One node process seen from the trusted side: its pipes, its graph, its taps and publishers.

    ``node`` is the trusted side's boundary node (taps: raw subscriptions to what the process
    subscribes to; publishers: what it publishes, republished here); ``lines`` its output.
    The process runs in ``box`` (closed with it); what it says names the student's files.
    """

    def __init__(self, box: NodeSandbox, label: str, node_arguments: Sequence[str],
                 node, lines: StreamLines, clock_ns: Callable[[], int]):
        self.box = box
        self.label = label
        self.node = node
        self.lines = lines
        self.clock_ns = clock_ns
        to_agent, self.to_fd = os.pipe()
        self.from_fd, from_agent = os.pipe()
        argv = agent_command(box.target, to_agent, from_agent, node_arguments)
        try:
            self.process = start_process(box.sandbox, argv, box.environment(),
                                         (to_agent, from_agent))
        finally:
            os.close(to_agent)
            os.close(from_agent)
        self.decoder = FrameDecoder(AGENT_KINDS)
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.from_fd, selectors.EVENT_READ, None)
        for stream, pipe in (('STDOUT', self.process.stdout), ('STDERR', self.process.stderr)):
            os.set_blocking(pipe.fileno(), False)
            self.selector.register(pipe.fileno(), selectors.EVENT_READ, stream)
        self.frames: list[Frame] = []
        self.graph: list[dict] = []
        self.wake_ns: int | None = None
        self.notes: list[str] = []
        self.running = ''
        self.taps: dict[str, Any] = {}
        self.publishers: dict[str, tuple[Any, type]] = {}

    # Reading

    def _drain(self, key) -> bool:
        """Read what one pipe holds now (READS_AT_ONCE reads at most); False at its end."""
        fd = key.fd
        for _ in range(READS_AT_ONCE):
            try:
                data = os.read(fd, READ_BYTES)
            except BlockingIOError:
                return True
            if not data:
                self.selector.unregister(fd)
                return False
            if key.data is None:
                try:
                    self.frames += self.decoder.feed(data)
                except FrameError as error:
                    raise self.failure(f'sent a malformed frame ({error})') from None
                return True
            self.lines.take(key.data, self.box.shown_bytes(data))
        return True

    def _drain_output(self) -> None:
        for key in list(self.selector.get_map().values()):
            if key.data is not None:
                self._drain(key)

    def next_frame(self, timeout_s: float) -> Frame:
        """Return the next idle, hello or ended frame; cut the output at each sync on the way."""
        deadline = time.monotonic() + timeout_s
        while True:
            while self.frames:
                frame = self.frames.pop(0)
                self._drain_output()
                node = frame.text('node', default='')
                self.lines.cut(self.clock_ns(), node)
                if frame.kind not in ('sync', 'stuck'):
                    return frame
                if frame.kind == 'sync':
                    self.send(encode('ack'))
            if self.from_fd not in {key.fd for key in self.selector.get_map().values()}:
                raise self.ended_without_word()
            left = deadline - time.monotonic()
            if left <= 0:
                raise AgentFailure(f'no reply for {timeout_s:g} s: {self.where_stuck()}',
                                   self.running)
            for key, _ in self.selector.select(min(left, 1.0)):
                self._drain(key)

    def where_stuck(self) -> str:
        """
        Say which node's code the process is stuck in, and where; then end the process.

        Asked with SIGUSR1 (sim_bridge.runner.boundary.inside.agent answers with a stuck frame);
        code in C, where Python's handler cannot run, is asked with SIGUSR2 (Python's faulthandler
        prints the stack on stderr). Each gets STACK_DUMP_S.
        """
        self.lines.cut(self.clock_ns(), '')
        before = len(self.lines.tail)
        node_pid = self.box.node_pid(self.process.pid)
        for asked in (signal.SIGUSR1, signal.SIGUSR2):
            try:
                os.kill(node_pid, asked)
            except OSError:
                break
            deadline = time.monotonic() + STACK_DUMP_S
            while time.monotonic() < deadline and self.process.poll() is None:
                for key, _ in self.selector.select(deadline - time.monotonic()):
                    self._drain(key)
                stuck = [frame for frame in self.frames if frame.kind == 'stuck']
                if stuck:
                    self.kill()
                    self.running = stuck[0].text('node') or self.label
                    where = stuck[0].text('where', 1000)
                    return self.box.shown(f"node '{self.running}' did not return from "
                                          f"{stuck[0].text('place')}{where}")
                self.lines.cut(self.clock_ns(), '')
                dumped = [match for line in list(self.lines.tail)[before:]
                          if (match := STACK_LINE.match(line))
                          and not is_library_frame(match['file'])]
                if dumped:  # faulthandler prints the innermost call first
                    self.kill()
                    return (f'{self.label} did not return from its code at '
                            f"{self.box.shown(dumped[0]['file'])}:{dumped[0]['line']} in "
                            f"{dumped[0]['name']}")
        self.kill()
        return f'{self.label} did not return from its code'

    def failure(self, what: str) -> AgentFailure:
        """Return the failure of this process that ``what`` says, at the run's sim time."""
        self.kill()
        return AgentFailure(f'{self.label}: at {self.clock_ns() / NANOSECONDS_PER_SECOND:g} s '
                            f'of sim time, the node process {what}', self.running or self.label)

    def ended_without_word(self) -> AgentFailure:
        """
        Return the failure of a process whose protocol pipe closed: it exited or crashed.

        Its last lines (a segfault's stack from faulthandler, a C library's message) are the
        failure's traceback.
        """
        self.wait_for_end(END_GRACE_S)
        try:  # its pipes ended: it is exiting, or it closed them and goes on
            status = self.process.wait(STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            status = None
        self.lines.close(self.clock_ns())  # its last line is whole: nothing more comes
        if status is not None and status > 128 and self.box.sandbox.sandboxed:
            status = 128 - status  # the sandbox's first process says so of a killed node
        if status is None:
            what = 'closed its pipe'
        elif status < 0:
            what = f'was killed by {signal.Signals(-status).name}'
        else:
            what = f'ended (exit status {status})'
        failure = self.failure(what)
        failure.traceback = '\n'.join(list(self.lines.tail)[-LAST_LINES:])
        failure.error_line = next((line for line in reversed(self.lines.tail)
                                   if line.strip()), '')
        return failure

    # Exchanging

    def start(self) -> None:
        """Wait for the process's first idle: its nodes are up."""
        frame = self.next_frame(START_TIMEOUT_S)
        if frame.kind == 'hello':
            frame = self.next_frame(START_TIMEOUT_S)
        self.take_idle(frame)

    def take_idle(self, frame: Frame) -> list[Message]:
        """Read an idle (or ended) frame: its wake time, graph and messages."""
        if frame.kind == 'ended':
            raise self.ended(frame)
        if frame.kind != 'idle':
            raise self.failure(f'sent a {frame.kind} frame out of turn')
        self.wake_ns = frame.integer('wake_ns', optional=True)
        if isinstance(frame.fields.get('notes'), list):
            self.notes = [self.box.shown(str(note)[:300]) for note in frame.fields['notes'][:10]]
        if 'graph' in frame.fields:
            self.graph = self.checked_graph(frame.fields['graph'])
            self.update_taps()
            self.update_publishers()
        return frame.messages

    def ended(self, frame: Frame) -> Exception:
        """
        Return what an ended frame says: a start error, the node's error, or main() returning.

        A start error (TARGET that does not import, names no Node class, a parameter of the
        wrong type) is an AgentStartError, the run's error, not the node's.
        """
        self.kill()
        status = frame.text('status', 16)
        if status == 'start':
            error = self.box.shown(frame.text('error', 40_000))
            if frame.fields.get('parameter') is True:
                error = f'{self.label}: {error}'
            return AgentStartError(error, self.box.shown(frame.text('traceback', 40_000, '')))
        node = frame.text('node', default='') or self.label
        place = frame.text('place', default='its main()')
        if status == 'returned':
            where = self.box.shown(frame.text('where', 1000, ''))
            what = (f"node '{node}' shut ROS down (rclpy.shutdown()) in {place}{where}" if where
                    else f'{self.label}: its main() returned')
            return AgentFailure(what, returned=True)
        error = self.box.shown(frame.text('error', 40_000))
        failure = AgentFailure(f"node '{node}' raised {error}", node,
                               self.box.shown(frame.text('traceback', 40_000, '')),
                               error_line=error.partition(' at ')[0], place=place)
        failure.memory = frame.fields.get('memory') is True
        return failure

    def exchange(self, messages: Sequence[Message],
                 meanwhile: Callable[[], Any] = lambda: None) -> list[Message]:
        """
        Send the step (sim time now and ``messages``); return what the nodes published.

        ``meanwhile()`` runs while the process handles the step (the recorder writes then).
        """
        self.send(encode('advance', messages, t_ns=self.clock_ns()))
        meanwhile()
        return self.take_idle(self.next_frame(EXCHANGE_TIMEOUT_S))

    def send(self, data: bytes) -> None:
        """Write a frame to the process; its failure if it is gone."""
        try:
            while data:
                data = data[os.write(self.to_fd, data):]
        except OSError:  # the process is gone: its last words say why
            raise self.ended_without_word() from None

    def checked_graph(self, graph: Any) -> list[dict]:
        """Return the process's graph (what its nodes are) if well formed; else fail the run."""
        try:
            return checked_graph(graph)
        except Refused as refused:
            raise self.failure(str(refused)) from None
        except (TypeError, KeyError, ValueError, AttributeError):
            raise self.failure('sent a malformed graph') from None

    def kill(self) -> None:
        """End the process, and every process of its session and of its sandbox."""
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            self.process.kill()
        self.box.sandbox.kill()
        self.process.wait()

    def wait_for_end(self, timeout_s: float) -> None:
        """Read the process's pipes until they all end (it exited), for ``timeout_s`` at most."""
        deadline = time.monotonic() + timeout_s
        while self.selector.get_map() and time.monotonic() < deadline:
            for key, _ in self.selector.select(deadline - time.monotonic()):
                try:
                    self._drain(key)
                except AgentFailure:
                    self.selector.unregister(key.fd)

    def close(self) -> list[str]:
        """
        Tell the process to end (killed after STOP_GRACE_S); close its pipes.

        Return its warnings: the threads its nodes left running.
        """
        if self.process.poll() is None:
            try:
                os.write(self.to_fd, encode('stop'))
            except OSError:
                pass
            self.wait_for_end(STOP_GRACE_S)
        self.kill()
        warnings = []
        for frame in self.frames:
            if frame.kind == 'ended' and frame.fields.get('status') == 'stopped':
                listed = frame.fields.get('warnings')
                warnings += [str(text)[:1000] for text in listed[:20]] \
                    if isinstance(listed, list) else []
        self._drain_output()
        self.selector.close()
        for fd in (self.to_fd, self.from_fd):
            os.close(fd)
        self.process.stdout.close()
        self.process.stderr.close()
        self.box.sandbox.close()
        return warnings


def agent_command(target: str, in_fd: int, out_fd: int,
                  node_arguments: Sequence[str]) -> list[str]:
    """Return the command line of the process that runs TARGET with ``node_arguments``."""
    return [sys.executable, '-m', 'sim_bridge.runner.boundary.inside.agent', '--in', str(in_fd),
            '--out', str(out_fd), '--', str(target), *node_arguments]


class Lockstep:
    """
    The run's node processes in lockstep with the simulator: who is due, and the exchanges.

    ``agents`` in the order of the run's targets; ``spin(topics)`` runs the trusted side's
    callbacks of what was republished on ``topics`` until none is ready
    (sim_bridge.runner.stepping.spin_after_publishing); ``meanwhile`` is work
    of the trusted side done while a process handles its step (a recorder's writes: on a
    second CPU they take no time of the run's).
    """

    def __init__(self, agents: list[Agent], spin: Callable[[set[str]], Any]):
        self.agents = agents
        self.spin = spin
        self.meanwhile: Callable[[], Any] = lambda: None
        self.exchanges = 0
        #: The process being exchanged with, while it is.
        self.current: Agent | None = None

    def next_wake_ns(self) -> int | None:
        """Return the earliest ROS time (ns) a node process asked to wake at, or None."""
        wakes = [agent.wake_ns for agent in self.agents if agent.wake_ns is not None]
        return min(wakes) if wakes else None

    def exchange_due(self, now_ns: int, force: bool = False) -> None:
        """Exchange with every process something is due for, until none is."""
        for _ in range(MAX_EXCHANGES_PER_STEP):
            exchanged = False
            for agent in self.agents:
                messages = agent.taken()
                if messages or force or (agent.wake_ns is not None
                                         and agent.wake_ns <= now_ns):
                    self.current = agent
                    published = agent.exchange(messages, self.meanwhile)
                    self.current = None
                    self.exchanges += 1
                    exchanged = True
                    if published:
                        agent.republish(published)
                        self.spin({message.topic for message in published})
            force = False
            if not exchanged:
                return
