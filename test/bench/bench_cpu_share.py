"""
A fair share of the CPU: an honest run's wall time alone, and beside twelve busy loops.

``python test/bench/bench_cpu_share.py [--duration S] [--rounds N] [--loops N]`` (as root, where
runs get control groups) runs an honest node (a spin_once loop, ``--duration`` s of sim time)
in a process of its own, as a grader's ``--jobs 2`` would, alone and then beside a neighbour's
sandbox running fixtures/hostile/busy_crowd.py (a new session, then ``--loops`` busy loops),
each both with the runs' cpu control groups and without them (the cpu controller hidden from
sim_bridge.runner.boundary.outside.sandbox_host, as on a kernel without it): every case once per
round, rounds interleaved, so that all the figures come from one sitting. On a machine with other
load, the bench first moves itself into a cpu group of its own of ``--weight`` shares (cgroup v1: a
weight of several ordinary processes), as if the machine were the grader's alone; the runs'
groups are made below it. Not a test: figures to compare, on the machine of the day.
"""

import argparse
import os
from pathlib import Path
import statistics
import subprocess
import sys
import time

from sim_bridge.runner.boundary.outside import sandbox_host
from sim_bridge.runner.boundary.outside.sandbox import Sandbox, SandboxLimits
from sim_bridge.runner.boundary.outside.scratch import clean_environment

HERE = Path(__file__).parent
FIXTURES = HERE.parent.parent / 'sim_bridge' / 'test' / 'fixtures'
#: The honest run, in a process of its own: its wall time (s) is what it prints last.
HONEST = """
import sys, time
from sim_bridge.runner.boundary.outside import sandbox_host
if sys.argv[3] == 'off':
    found = sandbox_host.v1_folder
    sandbox_host.v1_folder = lambda name: None if name == 'cpu' else found(name)
from sim_bridge.runner.run import run_simulation
start = time.perf_counter()
metrics = run_simulation('obstacles', [sys.argv[1]], duration_s=float(sys.argv[2]),
                         out_dir=sys.argv[4], quiet=True, plot=False, record=False).metrics
assert metrics['node_errors'] == [], metrics['node_errors']
print(time.perf_counter() - start)
"""


def honest_wall_s(duration_s: float, groups: str, out: Path) -> float:
    """Run the honest node in a process of its own; return its run's wall time (s)."""
    result = subprocess.run(
        [sys.executable, '-c', HONEST, str(FIXTURES / 'spin_once_loop.py'), str(duration_s),
         groups, str(out)], capture_output=True, text=True, check=True)
    return float(result.stdout.split()[-1])


def beside_busy_loops(loops: int, groups: str, run) -> float:
    """Return what ``run()`` returns, run while a sandbox runs ``loops`` busy loops."""
    found = sandbox_host.v1_folder
    if groups == 'off':
        sandbox_host.v1_folder = lambda name: None if name == 'cpu' else found(name)
    try:
        with Sandbox({'busy_crowd.py': FIXTURES / 'hostile' / 'busy_crowd.py'},
                     SandboxLimits(cpu_s=600, pids=loops + 8)) as box:
            started = box.popen([sys.executable, 'busy_crowd.py', str(loops)],
                                clean_environment(box.scratch), stdout=subprocess.PIPE)
            started.stdout.readline()  # 'started': the loops run
            return run()
    finally:
        sandbox_host.v1_folder = found


def own_cpu_group(weight: int) -> Path | None:
    """Move this process into a v1 cpu group of its own of ``weight`` shares; its folder."""
    parent = sandbox_host.v1_folder('cpu')
    if parent is None or weight <= 0:
        return None
    folder = parent / f'bench-cpu-share-{os.getpid()}'
    folder.mkdir()
    (folder / 'cpu.shares').write_text(str(weight))
    (folder / 'cgroup.procs').write_text(str(os.getpid()))
    return folder


def leave_cpu_group(folder: Path | None) -> None:
    """Move this process back to its parent group and remove ``folder`` (empty by then)."""
    if folder is not None:
        (folder.parent / 'cgroup.procs').write_text(str(os.getpid()))
        folder.rmdir()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--duration', type=float, default=10.0, help='sim seconds (s)')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--loops', type=int, default=12)
    parser.add_argument('--weight', type=int, default=8192,
                        help="the bench's own cpu shares (0: stay in this process's group)")
    args = parser.parse_args()
    if os.geteuid() != 0:
        print('not root: runs get no control groups here; the figures would say nothing')
    group = own_cpu_group(args.weight)
    try:
        return measure(args)
    finally:
        leave_cpu_group(group)


def measure(args: argparse.Namespace) -> int:
    """Run the cases, every one once a round; print each time, then the medians."""
    out = Path(f'/tmp/bench_cpu_share_{os.getpid()}')
    cases = {(groups, beside): [] for groups in ('on', 'off') for beside in (False, True)}
    for round_index in range(args.rounds):
        for (groups, beside), times in cases.items():
            start = time.perf_counter()
            run = lambda: honest_wall_s(args.duration, groups, out)  # noqa: E731
            times.append(beside_busy_loops(args.loops, groups, run) if beside else run())
            print(f'round {round_index + 1}: cpu groups {groups:3}, '
                  f"{'beside ' + str(args.loops) + ' busy loops' if beside else 'alone':22}"
                  f' {times[-1]:6.2f} s (case {time.perf_counter() - start:.1f} s)', flush=True)
    print(f'\nhonest run, {args.duration:g} s of sim time: median wall time over '
          f'{args.rounds} rounds (s)')
    for groups in ('on', 'off'):
        alone = statistics.median(cases[groups, False])
        beside = statistics.median(cases[groups, True])
        print(f'cpu groups {groups:3}: alone {alone:6.2f}   beside {args.loops} busy loops '
              f'{beside:6.2f}   ratio {beside / alone:5.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
