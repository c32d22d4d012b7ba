"""
How fast runs go through the trust boundary (runner.boundary.outside.link): figures side by side.

``python test/bench/bench_boundary.py [--duration S] [--case NAME ...] [--before CHECKOUT]``
runs, recorded, each node in its own process in lockstep with the simulator: the lab's
wall_follow (36 beams), a spin_once loop, a main() paced by time.sleep, and an idle node in
wall_follow's world (what the simulator and the recorder cost alone). For each: sim time over
wall time (x real time), the exchanges with the node's process (per sim s, and wall us each:
the round trip and the node's own work; physics steps need none), the CPU seconds of this
(the trusted) process and of the node's, and the peak memory (PSS, MiB) of the whole tree:
this process, the sandbox's and the node's. With ``--before CHECKOUT`` (another checkout of
the kit with the boundary, with its .venv: main's), each case also runs with that checkout's
code (this script, under its Python), and the ratio of the two is printed. Not a test: figures
to compare, on the machine of the day.
"""

import argparse
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import threading
import time

from sim_bridge.common.run_environment import keep_dds_in_process
from sim_bridge.runner.boundary.outside import link
from sim_bridge.runner.run import run_simulation

HERE = Path(__file__).parent
FIXTURES = HERE.parent.parent / 'sim_bridge' / 'test' / 'fixtures'
CASES = (('wall_follow', 'wall_follow_box', 'wall_follow'),
         ('spin_once loop', 'obstacles', str(FIXTURES / 'spin_once_loop.py')),
         ('time.sleep loop', 'obstacles', str(HERE / 'boundary_sleeper.py')),
         ('idle node', 'wall_follow_box', str(HERE / 'boundary_idle.py')))
#: Wall seconds between two reads of the tree's memory.
MEMORY_PERIOD_S = 0.25
CLOCK_TICKS = 100


def tree_pids(root: int) -> list[int]:
    """Return ``root`` and every process below it (the sandbox's and the node's)."""
    pids, index = [root], 0
    while index < len(pids):
        pid = pids[index]
        index += 1
        try:
            for task in Path(f'/proc/{pid}/task').iterdir():
                pids += map(int, (task / 'children').read_text().split())
        except OSError:
            continue
    return pids


def pss_kib(pid: int) -> int:
    """Return a process's proportional set size (KiB), 0 when it is gone."""
    try:
        rollup = Path(f'/proc/{pid}/smaps_rollup').read_text()
    except OSError:
        return 0
    return next((int(line.split()[1]) for line in rollup.splitlines()
                 if line.startswith('Pss:')), 0)


def cpu_s(pid: int) -> float:
    """Return the user + system CPU seconds a process has used so far (0 when it is gone)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rpartition(')')[2].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


class Meter:
    """Count the exchanges and their wall time; the node process's CPU; the tree's peak PSS."""

    def __init__(self):
        self.exchanges = 0
        self.exchange_s = 0.0
        self.node_cpu_s = 0.0
        self.peak_pss_kib = 0
        self.done = threading.Event()
        self.sampler = threading.Thread(target=self.sample, daemon=True)
        self.originals = link.Agent.exchange, link.Agent.close
        exchange, close = self.originals
        meter = self

        def timed_exchange(agent, *args):
            start = time.perf_counter()
            try:
                return exchange(agent, *args)
            finally:
                meter.exchanges += 1
                meter.exchange_s += time.perf_counter() - start

        def measured_close(agent):
            meter.node_cpu_s += cpu_s(agent.box.node_pid(agent.process.pid))
            return close(agent)
        link.Agent.exchange = timed_exchange
        link.Agent.close = measured_close

    def sample(self) -> None:
        """Read the whole tree's PSS every MEMORY_PERIOD_S until the run ends; keep the peak."""
        while not self.done.wait(MEMORY_PERIOD_S):
            total = sum(pss_kib(pid) for pid in tree_pids(os.getpid()))
            self.peak_pss_kib = max(self.peak_pss_kib, total)

    def __enter__(self) -> 'Meter':
        self.sampler.start()
        return self

    def __exit__(self, *exc_info) -> None:
        self.done.set()
        self.sampler.join()
        link.Agent.exchange, link.Agent.close = self.originals


def before(checkout: Path, name: str, duration_s: float) -> float | None:
    """
    Return the x real time of case ``name`` run by ``checkout``'s code, or None.

    This same script runs under that checkout's Python (its own sim_bridge, the same node
    files, measured the same way); a checkout without the trust boundary cannot run it.
    """
    # This venv's library paths out: that checkout's Python sets its own when it starts
    # (the ROS wheels' bootstrapper, unless told it already ran).
    own = os.path.join(sys.prefix, '')
    env = {variable: kept for variable, value in os.environ.items()
           if (kept := os.pathsep.join(part for part in value.split(os.pathsep)
                                       if not part.startswith(own)))
           and variable != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    result = subprocess.run(
        [str(checkout / '.venv' / 'bin' / 'python'), str(Path(__file__).resolve()),
         '--case', name, '--duration', str(duration_s)], cwd=checkout, env=env,
        capture_output=True, text=True, timeout=10 * duration_s + 120)
    rows = [line[len(name):].split() for line in result.stdout.splitlines()
            if line.startswith(name)]
    return float(rows[0][2]) if rows else None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0, help='sim s of each run')
    parser.add_argument('--case', action='append', choices=[name for name, *_ in CASES],
                        help='run only this case (again for more); all by default')
    parser.add_argument('--before', type=Path, metavar='CHECKOUT',
                        help="also run each case with this checkout's code")
    args = parser.parse_args()
    keep_dds_in_process()
    print(f"{'node':16} {'sim s':>6} {'wall s':>7} {'x real':>7} {'exch/sim s':>10} "
          f"{'us/exch':>8} {'run cpu s':>9} {'node cpu s':>10} {'tree MiB':>8}"
          + (f" {'before x':>8} {'now/before':>10}" if args.before else ''))
    for name, world, target in CASES:
        if args.case and name not in args.case:
            continue
        then = before(args.before, name, args.duration) if args.before else None
        with tempfile.TemporaryDirectory() as out, Meter() as meter:
            cpu = resource.getrusage(resource.RUSAGE_SELF)
            metrics = run_simulation(world, [target], duration_s=args.duration, out_dir=out,
                                     quiet=True, plot=False, record=True).metrics
            used = resource.getrusage(resource.RUSAGE_SELF)
        wall = metrics['wall_time_s']  # the run's own count, as the before checkout's
        run_cpu = used.ru_utime + used.ru_stime - cpu.ru_utime - cpu.ru_stime
        sim = metrics['sim_time_s']
        errors = '; '.join(e['error'] for e in metrics['node_errors'])
        per_exchange_us = 1e6 * meter.exchange_s / max(1, meter.exchanges)
        print(f'{name:16} {sim:6.0f} {wall:7.2f} {sim / wall:7.1f} '
              f'{meter.exchanges / sim:10.1f} {per_exchange_us:8.0f} {run_cpu:9.2f} '
              f'{meter.node_cpu_s:10.2f} {meter.peak_pss_kib / 1024:8.0f}'
              + (f' {then:8.1f} {sim / wall / then:10.2f}' if then else '')
              + (f'  ERROR {errors}' if errors else ''), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
