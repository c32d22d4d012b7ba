"""
How fast runs go through the trust boundary (sim_bridge.runner.boundary): figures side by side.

``python test/bench/bench_boundary.py [--duration S]`` runs, recorded, each node in
its own process in lockstep with the simulator: the lab's wall_follow (36 beams), a spin_once
loop, a main() paced by time.sleep, and an idle node (what the simulator and the recorder cost
alone). For each: sim time over wall time (x real time), the exchanges with the node's process
(per sim s, and wall us each: the round trip and the node's own work; physics steps need
none), and the node process's peak memory. With ``--before CHECKOUT`` (a checkout of the
kit from before the boundary, with its .venv), each case also runs there, as it ran then
(stepped in the runner's process, or a process at real time), and the ratio of the two is
printed. Not a test: figures to compare, on the machine of the day.
"""

import argparse
from pathlib import Path
import re
import subprocess
import sys
import tempfile
import time

from sim_bridge.common.run_environment import keep_dds_in_process
from sim_bridge.runner import boundary
from sim_bridge.runner.run import run_simulation

HERE = Path(__file__).parent
FIXTURES = HERE.parent.parent / 'sim_bridge' / 'test' / 'fixtures'
CASES = (('wall_follow (scan_pkg)', 'wall_follow_box', 'wall_follow'),
         ('spin_once loop', 'obstacles', str(FIXTURES / 'spin_once_loop.py')),
         ('time.sleep loop', 'obstacles', str(HERE / 'boundary_sleeper.py')),
         ('idle node (baseline)', 'obstacles', str(HERE / 'boundary_idle.py')))


class Meter:
    """Count the exchanges, their wall time, and the node process's peak memory."""

    def __init__(self):
        self.exchanges = 0
        self.exchange_s = 0.0
        self.peak_kib = 0
        exchange, close = boundary.Agent.exchange, boundary.Agent.close
        meter = self

        def timed_exchange(agent, messages):
            start = time.perf_counter()
            try:
                return exchange(agent, messages)
            finally:
                meter.exchanges += 1
                meter.exchange_s += time.perf_counter() - start

        def measured_close(agent):
            try:
                status = Path(f'/proc/{agent.process.pid}/status').read_text()
                meter.peak_kib = max(meter.peak_kib, int(status.split('VmHWM:')[1].split()[0]))
            except (OSError, IndexError):
                pass
            return close(agent)
        boundary.Agent.exchange = timed_exchange
        boundary.Agent.close = measured_close


def before(checkout: Path, world: str, target: str, duration_s: float) -> float | None:
    """Return the x real time of the case run by ``checkout``'s runner, or None."""
    with tempfile.TemporaryDirectory() as out:
        result = subprocess.run(
            [str(checkout / '.venv' / 'bin' / 'python'), '-m', 'sim_bridge.run', '--world',
             world, '--node', target, '--duration', str(duration_s), '--quiet', '--no-plot',
             '--out', out], cwd=checkout / 'sim_bridge', capture_output=True, text=True,
            timeout=10 * duration_s + 120)
    found = re.search(r'wall time\s+([\d.]+) s', result.stdout)
    return duration_s / float(found[1]) if found else None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0, help='sim s of each run')
    parser.add_argument('--before', type=Path, metavar='CHECKOUT',
                        help='also run each case with the runner of this checkout')
    args = parser.parse_args()
    keep_dds_in_process()
    print(f"{'node':24} {'sim s':>6} {'wall s':>7} {'x real':>7} {'exch/sim s':>10} "
          f"{'us/exch':>8} {'exch s':>7} {'node MiB':>8}"
          + (f" {'before x':>8} {'now/before':>10}" if args.before else ''))
    for name, world, target in CASES:
        meter = Meter()
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            metrics = run_simulation(world, [target], duration_s=args.duration, out_dir=out,
                                     quiet=True, plot=False, record=True).metrics
            wall = time.perf_counter() - start
        sim = metrics['sim_time_s']
        then = before(args.before, world, target, args.duration) if args.before else None
        errors = '; '.join(e['error'] for e in metrics['node_errors'])
        per_exchange_us = 1e6 * meter.exchange_s / max(1, meter.exchanges)
        print(f'{name:24} {sim:6.0f} {wall:7.2f} {sim / wall:7.1f} '
              f'{meter.exchanges / sim:10.1f} {per_exchange_us:8.0f} '
              f'{meter.exchange_s:7.2f} {meter.peak_kib / 1024:8.0f}'
              + (f' {then:8.1f} {sim / wall / then:10.2f}' if then else '')
              + (f'  ERROR {errors}' if errors else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
