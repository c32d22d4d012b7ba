"""
Run a student's node file in its own process, in lockstep with the run's trusted simulator.

``python -m sim_bridge.runner.boundary.inside.agent --in FD --out FD -- TARGET [--ros-args ...]``
runs TARGET's ``main()`` as ``ros2 run`` would (its ``__main__`` block, its console script, or
a Node subclass spun by rclpy), with the command line its process would get. It imports rclpy, the
standard library, the frame codec and the student's code: never the simulator, the scenario or
the grader.

Wherever the student's code would block, control comes here instead (patched in this process
only, sim_bridge.runner.boundary.inside.node_patches; the runner's package docstring lists every
patch): an executor's wait with nothing ready, ``time.sleep``, ``Rate.sleep``;
MultiThreadedExecutor runs single-threaded. The blocking point says ``idle`` to the trusted side
over the ``--out`` pipe, with the messages the nodes published since the last exchange (raw CDR,
taken by a proxy node's raw subscriptions) and the next ROS time it must wake at (its nodes'
first timer, a sleep's end, a wait's timeout), then reads ``advance``: the new sim time and the
messages published on the trusted side (/clock, /scan, ...), which the proxy publishes here, in
this process, where they are delivered before ``publish`` returns. A sleep of s lasts s of
simulated time, as on Gazebo at real-time factor 1. Around each callback the agent writes a
``sync`` frame naming the callback's node: the trusted side cuts the nodes' output (this
process's stdout and stderr, pipes it reads) at those points. ROS discovery is off: the nodes
hear only this process.

main()'s own code that runs on and on (a loop polling ``time.time()``, a ``join`` of the thread
that spins) reaches none of those points: sim time stands still for BUSY_MAIN_S of wall time,
then a pacing thread exchanges in its stead, sim time following the wall clock (real-time
factor 1), each message delivered at its time and handled by the threads that spin.
"""

import argparse
import contextlib
import faulthandler
import math
import os
import random
import signal
import sys
import threading
from time import monotonic_ns, sleep as wall_sleep  # the real ones, before the patches
import traceback
from typing import Any, Callable

from sim_bridge.runner.boundary.inside.channel import Link
from sim_bridge.runner.boundary.inside.node_main import MAX_TRACEBACK_CHARS, prepare, start_failure
from sim_bridge.runner.boundary.inside.node_patches import install, NANOSECONDS_PER_SECOND
from sim_bridge.runner.boundary.inside.proxy import ProxyNode

#: Wall seconds the main thread waits, after a step, for the nodes' other spinning threads to
#: handle it; a thread that takes longer is no longer waited for (it runs at its own pace).
THREAD_DRAIN_S = 2.0
#: A spinning thread's count of steps handled while its code runs, and while it sleeps.
BUSY, ASLEEP = -1, math.inf
#: Wall seconds main()'s own code may run without waiting, sleeping or running a callback
#: before the run is stepped without it (see the module's docstring); the longest step then
#: (s of sim time, so that main() sees each), and the wall seconds between two looks while
#: it paces, and while it does not.
BUSY_MAIN_S = 2.0
PACE_STEP_S = 0.005
PACE_TICK_S = 0.005
LOOK_S = 0.1
#: The seed of Python's ``random`` in a node's process: a node that never seeds it draws the
#: same numbers at every grading, so its marks are the same too.
RANDOM_SEED = 0
#: Most wall seconds the pacing thread waits, after a step, for a main() that polls the clock
#: to read it (under load its thread may not run at once).
SEE_S = 0.05
#: What a run says of a main() that kept the main thread busy (see the module's docstring).
PACED_NOTE = (f'its main() ran its own code for over {BUSY_MAIN_S:g} s of wall time without '
              'waiting, sleeping or spinning: sim time followed the wall clock (real-time '
              'factor 1) while it did')


class Lockstep(ProxyNode):
    """
    The agent's state: sim time, the proxy node, the student's nodes, the frames to send.

    One thread (the main thread, where ``main()`` runs) exchanges with the trusted side, or
    the pacing thread while main()'s own code is busy (:meth:`pace`); other threads' sleeps
    wait for sim time to pass.
    """

    def __init__(self, link: Link):
        self.link = link
        self.now_ns = 0
        self.nodes = []
        self.proxy = None
        self.publishers: dict[str, Any] = {}
        self.taps: dict[str, Any] = {}
        self.graph = None
        self.shape = None
        #: What the trusted side should say of how the nodes ran, and what it was told.
        self.notes: list[str] = []
        self.notes_sent: list[str] = []
        self.running: tuple[str, str] | None = None
        self.failed_in: tuple[str, str] | None = None
        self.shutdown_where = ''
        self.shutdown_in: tuple[str, str] | None = None
        self.time_passed = threading.Condition()
        #: Steps delivered; threads other than the main one that spin an executor, each with
        #: the count of steps it has handled when it last found nothing ready (BUSY, ASLEEP).
        self.steps = 0
        self.spinners: dict[threading.Thread, float] = {}
        #: Writes of the nodes' streams and loggers since the last sync, the last one's stream.
        self.printed = 0
        self.last_stream = ''
        #: Held by the thread that exchanges, until the threads that spin handled the step.
        self.stepping = threading.RLock()
        #: The main thread's calls into the agent under way; the wall and sim time (ns) when
        #: it last left one; when pacing began (main_left then, wall ns, sim ns: see
        #: :meth:`pace`); the wall time (ns) the last step was delivered at.
        self.main_inside = 0
        self.main_left = (monotonic_ns(), 0)
        #: Whether main() ever waited in the agent (spun, slept): a main() that never did, nor
        #: read the clock, with no thread spinning, is still starting (stuck in a constructor,
        #: say), which the trusted side's watchdog names, so it is never paced.
        self.main_entered = False
        self.paced_from: tuple[tuple[int, int], int, int] | None = None
        self.step_wall_ns = monotonic_ns()
        self.clock_lock = threading.Lock()
        self.clock_last_ns = 0
        #: Times main()'s own code read the clock; the count after the last paced step.
        self.main_reads = 0
        self.main_reads_seen = 0

    def sync(self, node: str) -> None:
        """
        Say that what the nodes printed since the last sync was printed by ``node``'s code.

        ('' for none: the process's one node if it has one.) Only when they printed: Python's
        streams count what they write, rcutils' output handler the lines it prints
        (node_patches.ConsoleCounter; a C library's printf is cut at the next sync, the time
        still right). The trusted side answers once it has cut the bytes
        written before the sync, so no byte written after it is cut with them.
        """
        if self.printed:
            self.printed = 0
            if self.link.request('sync', node=node or self.only_node()).kind != 'ack':
                self.stop()  # else the bytes before it are cut: go on

    def only_node(self) -> str:
        """Return the name of the process's one node, whose program main() is; else ''."""
        if len(self.nodes) != 1:
            return ''
        try:
            return self.nodes[0].get_name()
        except Exception:  # noqa: B902 a destroyed node
            return ''

    def note_write(self, stream: str) -> None:
        """
        Count a write to ``stream`` ('STDOUT', 'STDERR'): a sync first when it changes.

        So that the trusted side, which reads the two pipes as their bytes come, keeps the
        lines in the order they were written.
        """
        if self.printed and stream != self.last_stream:
            self.sync(self.running[0] if self.running else '')
        self.last_stream = stream
        self.printed += 1

    def exchange(self, wake_ns: int | None, context=None) -> None:
        """Report idle (next wake ``wake_ns``), take the trusted side's step, deliver it."""
        with self.in_step(), self.stepping:
            self._start_proxy(context)
            graph = self._graph()
            fields = {'wake_ns': wake_ns, 'node': self.only_node() if self.printed else ''}
            self.printed = 0
            if graph != self.graph:
                self.graph = fields['graph'] = graph
            if self.notes != self.notes_sent:
                self.notes_sent = fields['notes'] = list(self.notes)
            frame = self.link.request('idle', self._taken(), **fields)
            if frame.kind == 'stop':
                self.stop()
            with self.time_passed:
                self.now_ns = max(self.now_ns, frame.integer('t_ns'))
                self.step_wall_ns = monotonic_ns()
                self.time_passed.notify_all()
            for message in frame.messages:
                publisher = self._publisher(message)
                if publisher is not None:
                    publisher.publish(message.data)
            self._drain_threads()

    @contextlib.contextmanager
    def in_step(self):
        """Note that the main thread is in the agent's hands (a wait, a callback) in the block."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        self.main_inside += 1
        self.main_entered = True
        try:
            yield
        finally:
            self.main_inside -= 1
            self.main_left = (monotonic_ns(), self.now_ns)

    def clock_ns(self) -> int:
        """
        Return the nodes' clock (ns): sim time, in a callback plus the wall time since its step.

        main()'s own code reads sim time (a loop that polls it is paced: :meth:`pace`); a
        callback, on any thread, reads sim time plus the wall time since its step was
        delivered, so that a callback that waits on the clock ends. Never less than it last
        returned: code that runs longer than the steps sees it stand until sim time catches up.
        The nodes' wall clocks read their start plus this (node_patches.patch_clocks).
        """
        in_main_code = (threading.current_thread() is threading.main_thread()
                        and not self.main_inside)
        self.main_reads += in_main_code
        with self.clock_lock:
            reading = self.now_ns if in_main_code else (
                self.now_ns + monotonic_ns() - self.step_wall_ns)
            self.clock_last_ns = reading = max(reading, self.clock_last_ns)
            return reading

    def pace(self) -> None:
        """
        Step the run while main()'s own code keeps the main thread from the agent (a thread).

        Once it has been BUSY_MAIN_S away (wall time) with nodes made, and main() has waited
        in the agent before, or reads the clock, or another thread spins, sim time follows the
        wall clock from then on, never ahead of it: steps of PACE_STEP_S at most, or to the
        nodes' next timer, each message delivered at its time; the threads that spin handle
        it as ever. A main() that polls the clock gets to read it after each step (SEE_S of
        wall time at most). Pacing ends with the nodes' context.
        """
        import rclpy
        context = rclpy.utilities.get_default_context()
        while True:
            if self._paced_wake() is None:  # the lock untouched while main() is not busy
                pacing = self.paced_from is not None and self.paced_from[0] == self.main_left
                wall_sleep(PACE_TICK_S if pacing and not self.main_inside else LOOK_S)
                continue
            with self.stepping:
                wake_ns = self._paced_wake()
                if wake_ns is None or not context.ok():
                    continue
                if PACED_NOTE not in self.notes:
                    self.notes.append(PACED_NOTE)
                polled = self.main_reads != self.main_reads_seen  # since the last step
                try:
                    self.exchange(wake_ns)
                except Exception:  # noqa: B902 main() shut the context down meanwhile
                    if context.ok():
                        raise
                    return
                self.main_reads_seen = self.main_reads
            deadline_ns = monotonic_ns() + round(SEE_S * NANOSECONDS_PER_SECOND)
            while polled and self.main_reads == self.main_reads_seen and (
                    monotonic_ns() < deadline_ns):
                wall_sleep(SEE_S / 100)

    def _paced_wake(self) -> int | None:
        """Return the sim time (ns) the pacing thread steps to now, or None (see pace)."""
        from sim_bridge.runner.stepping import next_timer_ns
        left = self.main_left
        wall_ns = monotonic_ns()
        if (self.main_inside or not self.nodes
                or not (self.spinners or self.main_reads or self.main_entered)
                or wall_ns - left[0] < BUSY_MAIN_S * NANOSECONDS_PER_SECOND):
            return None
        if self.paced_from is None or self.paced_from[0] != left:
            self.paced_from = (left, wall_ns, self.now_ns)  # sim time follows the wall from now
        _, from_wall_ns, from_sim_ns = self.paced_from
        paced_ns = from_sim_ns + wall_ns - from_wall_ns
        if paced_ns <= self.now_ns:
            return None
        timer_ns = next_timer_ns(self.nodes, after_ns=self.now_ns)
        return min(paced_ns, self.now_ns + round(PACE_STEP_S * NANOSECONDS_PER_SECOND),
                   *([] if timer_ns is None else [timer_ns]))

    def _drain_threads(self) -> None:
        """
        Let the nodes' other spinning threads handle the step just delivered, then go on.

        As the main thread's own callbacks run before it says idle. A thread still busy after
        THREAD_DRAIN_S is no longer waited for until it next finds nothing ready.
        """
        with self.time_passed:
            self.steps += 1
            self.time_passed.notify_all()
            if not self.time_passed.wait_for(self._threads_idle, THREAD_DRAIN_S):
                for thread, handled in list(self.spinners.items()):
                    if handled < self.steps:
                        del self.spinners[thread]

    def _threads_idle(self) -> bool:
        return all(handled >= self.steps for thread, handled in self.spinners.items()
                   if thread.is_alive())

    def thread_wait(self, original_wait: Callable, executor, timeout_sec, nodes, condition):
        """
        Wait as ``original_wait`` for a thread other than the main one, in step with it.

        Each step delivered is handled (every callback it makes ready, handed out one at a
        time) before the thread parks with nothing ready; the main thread waits for that
        (:meth:`_drain_threads`). A timeout lasts its simulated time. A parked thread wakes
        when its executor or its context shuts down, as rclpy's wait does: at once for the
        context (:meth:`shutdown_seen`), within LOOK_S of wall time for the executor.
        """
        from rclpy.executors import TimeoutException
        timeout = getattr(timeout_sec, 'timeout', timeout_sec)
        deadline = (None if timeout is None or timeout < 0
                    else self.now_ns + round(timeout * NANOSECONDS_PER_SECOND))
        thread = threading.current_thread()
        while True:
            with self.time_passed:
                seen = self.steps
            executor.wake()
            try:
                found = original_wait(executor, 0, nodes, condition)
            except TimeoutException:
                found = None
            with self.time_passed:
                if found is not None or getattr(executor, '_lab_ran', False):
                    executor._lab_ran = found is not None  # after callbacks, one more wait
                    self.spinners[thread] = BUSY
                    if found is not None:
                        return found
                    continue
                if deadline is not None and self.now_ns >= deadline:
                    self.spinners[thread] = BUSY
                    raise TimeoutException()
                self.spinners[thread] = seen
                self.time_passed.notify_all()
                self.time_passed.wait_for(lambda: self.steps > seen or (
                    deadline is not None and self.now_ns >= deadline) or (
                    executor._is_shutdown or not executor.context.ok()), LOOK_S)

    def shutdown_seen(self) -> None:
        """Wake the threads parked in a wait: their context shut down (see thread_wait)."""
        with self.time_passed:
            self.time_passed.notify_all()

    def hand_over(self) -> None:
        """
        Send what the nodes published since the last exchange, before saying the process ended.

        As their process would: a message published just before main() returns, or raises,
        is delivered.
        """
        try:
            messages = self._taken()
        except Exception:  # noqa: B902 its context is gone, with what it held
            return
        if messages:
            with self.stepping:
                if self.link.request('idle', messages, wake_ns=self.now_ns).kind == 'stop':
                    self.stop()

    def stop(self) -> None:
        """End this process at the run's end, naming the threads the nodes left running."""
        self.link.send('ended', status='stopped', warnings=thread_warnings()[:20])
        os._exit(0)

    def report_stuck(self, signum: int, frame) -> None:
        """Say where the nodes' code is (a signal from the trusted side: it waited too long)."""
        node, place = self.running or ('', 'its main()')
        where = self.code.stack_origin(traceback.extract_stack(frame))
        self.link.send('stuck', node=node, place=place, where=where[:1000])

    def sleep_until(self, deadline_ns: int, context=None) -> None:
        """Exchange until sim time reaches ``deadline_ns`` (ns); other threads just wait."""
        thread = threading.current_thread()
        if thread is not threading.main_thread():
            with self.time_passed:
                if thread in self.spinners:
                    self.spinners[thread] = ASLEEP
                    self.time_passed.notify_all()
                self.time_passed.wait_for(lambda: self.now_ns >= deadline_ns)
                if thread in self.spinners:
                    self.spinners[thread] = BUSY
            return
        self.exchange(deadline_ns, context)
        while self.now_ns < deadline_ns:
            self.exchange(deadline_ns, context)


def thread_warnings() -> list[str]:
    """
    Name each thread a node left running (not a daemon), where it is, in one line each.

    The run ends without waiting for them, as the process of a node would not.
    """
    from sim_bridge.runner.targets import is_library_frame
    frames = sys._current_frames()
    warnings = []
    for thread in threading.enumerate():
        if thread is threading.main_thread() or thread.daemon or not thread.is_alive():
            continue
        stack = traceback.extract_stack(frames[thread.ident]) if thread.ident in frames else []
        own = [frame for frame in stack if not is_library_frame(frame.filename)]
        where = (f', in {own[-1].name} at {os.path.basename(own[-1].filename)}:'
                 f'{own[-1].lineno}' if own else '')
        warnings.append(f"node thread '{thread.name}'{where} was still running when the run "
                        'ended; it was stopped (a node should join its threads, or make them '
                        'daemons, before it returns)')
    return warnings


def run(target: str, ros_args: list[str], link: Link) -> None:
    """Run TARGET's main() in lockstep; say on ``link`` how it ended."""
    from rclpy.exceptions import InvalidParameterTypeException
    from sim_bridge.runner.targets import describe, module_file, split_target, StudentCode
    lockstep = Lockstep(link)
    path = module_file(split_target(target)[0])
    lockstep.code = code = StudentCode.of([path] if path else [])
    install(lockstep)
    random.seed(RANDOM_SEED)  # a node's own random.seed() still wins
    signal.signal(signal.SIGUSR1, lockstep.report_stuck)
    sys.argv = [path or target, *ros_args]
    link.send('hello', pid=os.getpid())
    threading.Thread(target=lockstep.pace, name='lab_pacer', daemon=True).start()
    try:
        start, path = prepare(target)
    except BaseException as error:  # noqa: B902 SystemExit at import, a syntax error
        link.send('ended', **start_failure(target, error, code))
        return
    try:
        start()
        lockstep.hand_over()
    except InvalidParameterTypeException as error:
        link.send('ended', status='start', error=str(error), parameter=True)
    except BaseException as error:  # noqa: B902 the node's process would have died of it
        node, place = lockstep.failed_in or lockstep.running or (lockstep.only_node(),
                                                                 'its main()')
        lockstep.hand_over()
        link.send('ended', status='error', node=node, place=place,
                  memory=isinstance(error, MemoryError),
                  error=describe(error, code)[:MAX_TRACEBACK_CHARS],
                  traceback=code.traceback(error)[-MAX_TRACEBACK_CHARS:], t_ns=lockstep.now_ns)
    else:
        node, place = lockstep.shutdown_in or ('', 'its main()')
        link.send('ended', status='returned', where=lockstep.shutdown_where[:1000],
                  node=node, place=place, t_ns=lockstep.now_ns)


def main(argv: list[str] | None = None) -> int:
    """Run the agent (see the module's docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    split = argv.index('--ros-args') if '--ros-args' in argv else len(argv)
    if '--' in argv[:split]:  # what follows is the target and its arguments, as given
        split = argv.index('--') + 2
    parser = argparse.ArgumentParser(prog='python -m sim_bridge.runner.boundary.inside.agent')
    parser.add_argument('--in', dest='in_fd', type=int, required=True)
    parser.add_argument('--out', dest='out_fd', type=int, required=True)
    parser.add_argument('target')
    args = parser.parse_args(argv[:split])
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
    sys.stdout.reconfigure(line_buffering=True)
    # A node stuck in its code: the trusted side asks where
    # (sim_bridge.runner.boundary.outside.link); in C code, where Python's handler cannot run,
    # faulthandler says (SIGUSR2).
    faulthandler.register(signal.SIGUSR2, all_threads=False)
    faulthandler.enable()  # a crash's stack, as the trusted side reads it from stderr
    run(args.target, argv[split:], Link(args.in_fd, args.out_fd))
    sys.stdout.flush()
    os._exit(0)  # whatever threads the nodes left running


if __name__ == '__main__':
    sys.exit(main())
