"""
Grade one whole-lab submission as Gradescope would, on one CPU: wall time, CPU time, memory.

Builds autograder.zip from the scenarios, lays out a Gradescope root (``source/`` from the zip,
``submission/``, ``results/``), and runs its ``run_autograder`` pinned to CPU 0 (as
``taskset -c 0``: ``nproc`` then says 1, so it grades one run at a time). The whole process
tree is sampled every SAMPLE_S: its memory (the sum of each process's proportional set size,
PSS, which counts a page shared by N processes 1/N in each; and the sum of RSS, which counts it
N times) and its CPU time (each process's user + system time, the last value seen). A process
that leaves the tree (a double fork) is still counted while it lives. Gradescope's limits:
https://gradescope-autograders.readthedocs.io/en/latest/specs/ (default 768 MB per container).

    .venv/bin/python test/bench/bench_gradescope.py [--submission DIR] [SCENARIO ...]

Without ``--submission``, a whole lab is handed in: the kit's scan_ahead and scan_around (they
import only the kit's library) and the careful wanderbot and wall follower of ``examples/``
(a student's sandbox holds the kit's answers to tasks 2 and 4 empty).
"""

import argparse
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

WORKSPACE = Path(__file__).resolve().parents[2]
SAMPLE_S = 0.05
PAGE_KIB = os.sysconf('SC_PAGE_SIZE') // 1024
TICKS = os.sysconf('SC_CLK_TCK')
LAB_SUBMISSION = {'scan_ahead.py': WORKSPACE / 'scan_pkg' / 'scan_pkg' / 'scan_ahead.py',
                  'scan_around.py': WORKSPACE / 'scan_pkg' / 'scan_pkg' / 'scan_around.py',
                  'wanderbot.py': WORKSPACE / 'examples' / 'careful_wanderbot.py',
                  'wall_follow.py': WORKSPACE / 'examples' / 'careful_wall_follow.py'}


def process_table() -> dict[int, tuple[int, float]]:
    """Return each process's (parent pid, CPU seconds so far)."""
    table = {}
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            fields = Path(f'/proc/{entry}/stat').read_text().rpartition(')')[2].split()
        except OSError:
            continue
        table[int(entry)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / TICKS)
    return table


def memory_kib(pid: int) -> tuple[int, int]:
    """Return (PSS, RSS) of a process in KiB, (0, 0) once it is gone."""
    try:
        text = Path(f'/proc/{pid}/smaps_rollup').read_text()
    except OSError:
        return 0, 0
    values = {line.split(':')[0]: int(line.split()[1]) for line in text.splitlines()[1:]
              if line.split()[-1] == 'kB'}
    return values.get('Pss', 0), values.get('Rss', 0)


def run_sampled(command: list[str], environment: dict[str, str]) -> dict[str, float]:
    """Run ``command`` on CPU 0; return its wall time, tree CPU time and peak memory."""
    start = time.perf_counter()
    process = subprocess.Popen(command, env=environment, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL,
                               preexec_fn=lambda: os.sched_setaffinity(0, {0}))
    seen: dict[int, float] = {}
    peak_pss = peak_rss = 0
    while process.poll() is None:
        table = process_table()
        tree = {process.pid} | {pid for pid in seen if pid in table}
        grown = True
        while grown:
            below = {pid for pid, (parent, _) in table.items() if parent in tree} - tree
            grown = bool(below)
            tree |= below
        for pid in tree:
            seen[pid] = max(seen.get(pid, 0.0), table.get(pid, (0, 0.0))[1])
        usage = [memory_kib(pid) for pid in tree]
        peak_pss = max(peak_pss, sum(pss for pss, _ in usage))
        peak_rss = max(peak_rss, sum(rss for _, rss in usage))
        time.sleep(SAMPLE_S)
    return {'wall_s': time.perf_counter() - start, 'cpu_s': sum(seen.values()),
            'peak_pss_mib': peak_pss / 1024, 'peak_rss_mib': peak_rss / 1024,
            'processes': len(seen)}


def main() -> int:
    """Grade the submission and print the figures; 0 when within 5 min and 512 MiB."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('scenarios', nargs='*', default=[str(WORKSPACE / 'scenarios')])
    parser.add_argument('--submission', type=Path)
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix='gradescope_'))
    subprocess.run([sys.executable, '-m', 'sim_bridge.commands.autograder', 'build',
                    *args.scenarios, '-o', str(root / 'autograder.zip')],
                   check=True, stdout=subprocess.DEVNULL)
    shutil.unpack_archive(root / 'autograder.zip', root / 'source')
    (root / 'source' / 'run_autograder').chmod(0o755)
    if args.submission:
        shutil.copytree(args.submission, root / 'submission')
    else:
        (root / 'submission').mkdir()
        for name, source in LAB_SUBMISSION.items():
            shutil.copy(source, root / 'submission' / name)
    environment = {**os.environ, 'AUTOGRADER_ROOT': str(root),
                   'AUTOGRADER_PYTHON': sys.executable}
    figures = run_sampled([str(root / 'source' / 'run_autograder')], environment)
    results = json.loads((root / 'results' / 'results.json').read_text())
    runs = len(list((root / 'results' / 'graded').rglob('result.json')))
    print(f"{runs} runs, score {results['score']}: wall {figures['wall_s']:.0f} s on CPU 0 "
          f"(CPU time of the tree {figures['cpu_s']:.0f} s), peak memory of the tree "
          f"{figures['peak_pss_mib']:.0f} MiB PSS ({figures['peak_rss_mib']:.0f} MiB RSS), "
          f"{figures['processes']} processes; outputs in {root}")
    return 0 if figures['cpu_s'] <= 300 and figures['peak_pss_mib'] <= 512 else 1


if __name__ == '__main__':
    sys.exit(main())
