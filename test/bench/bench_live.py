"""
Benchmark live runs: the simulator bridge's CPU use and pace, and /scan across processes.

Run: ``python test/bench/bench_live.py [--quick]`` (about a minute; less with --quick). Each
measurement starts, with sim_bridge.live.live, the processes of ``./lab live wall_follow`` (the
bridge in wall_follow_box with 100 Hz physics, 10 Hz 36-beam scans and 50 Hz odometry, and the
wall_follow node driving) plus this script as a listener in a third process, on a
ROS_DOMAIN_ID of this process's own. The window starts once the listener has /clock and the
run has warmed up.

1. CPU at real_time_factor 1: CPU seconds (utime + stime of /proc/<pid>/stat) per wall second
   of the bridge, and of the node, over the window.
2. Pace: for each real_time_factor, the sim seconds per wall second that reach the listener on
   /clock (the sim time advance between the first and the last /clock received in the window
   over their receipt times' difference), against the requested factor: sustained at >= 95 %.
   With the bridge's CPU share at that factor.
3. /scan at real_time_factor 1, received in the listener's process (sensor data QoS): the rate
   and the inter-arrival times; the stamp increments; the latency, publish to receipt. The
   bridge's physics timer (steady clock, drift-free: step k is due k / (physics_rate x rtf) s
   after the timer's creation) publishes scan k at sim time k x 10 ms, so a scan stamped s was
   due at t0 + s / rtf of wall time. t0 is taken from the wall-clock stamp of the bridge's log
   line written just before it creates the timer (the tf2_ros notice), so the latency includes
   the timer's own lateness and is overstated by the ~1 ms between that line and the timer.
   As a cross-check without that line: the latency above the fastest /clock delivery
   (t0 + its latency aligned as the minimum of receipt - sim time / rtf over every /clock).
"""

import argparse
import json
import os
from pathlib import Path
import re
import sys
import time

import numpy as np

from sim_bridge.live import live
from sim_bridge.runner import processes

WORLD, NODE = 'wall_follow_box', 'wall_follow'
FACTORS = (1, 2, 5, 10, 20, 50)
SUSTAINED = 0.95
LISTENER = 'listener-3'
START_NOTICE = re.compile(r'^\[sim_bridge-1\] \[WARN\] \[(\d+\.\d+)\] \[sim_bridge\]: tf2_ros')
#: Longest wait (s) for the listener's first /clock.
START_TIMEOUT_S = 60.0


def listen() -> None:
    """Record /scan and /clock receipts (wall s, stamp s) until SIGINT; print them as JSON."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan

    seen = {'scan': [], 'clock': []}

    def on_scan(msg):
        seen['scan'].append((time.time(), msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9))

    def on_clock(msg):
        if not seen['clock']:
            print('first clock', flush=True)
        seen['clock'].append((time.time(), msg.clock.sec + msg.clock.nanosec * 1e-9))

    rclpy.init()
    node = Node('bench_listener')
    node.create_subscription(LaserScan, 'scan', on_scan, qos_profile_sensor_data)
    node.create_subscription(Clock, 'clock', on_clock, 10)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(json.dumps(seen), flush=True)
        node.destroy_node()
        rclpy.try_shutdown()


def cpu_seconds(pid: int) -> float:
    """Return the CPU time (s, user + system) process ``pid`` has used so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def bench_env() -> dict:
    """Return this environment on a domain of this process's own, discovery on."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(120 + os.getpid() % 80))
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    return env


def live_window(real_time_factor: float, warmup_s: float, window_s: float) -> dict:
    """
    Run bridge, node and listener; measure over ``window_s`` wall s after ``warmup_s``.

    Return the listener's JSON plus ``window`` (wall start, end), ``cpu`` (bridge, node,
    listener: CPU s per wall s over the window) and ``t0`` (the wall stamp of the bridge's start
    notice, or None).
    """
    specs = [live.bridge_spec(WORLD, real_time_factor=real_time_factor),
             live.node_spec(NODE),
             processes.ProcessSpec('listener', (sys.executable, __file__, '--listen'))]
    lines = []
    with processes.LiveRun(specs, env=bench_env(), out=lines.append) as run:
        run.start()
        deadline = time.monotonic() + START_TIMEOUT_S
        while f'[{LISTENER}] first clock' not in lines:
            if time.monotonic() > deadline or len(run.running()) < len(specs):
                raise RuntimeError('the live run did not start:\n' + '\n'.join(lines))
            run.pump(0.1)
        run.wait(warmup_s)
        pids = [process.pid for process in run.processes]
        start_cpu = [cpu_seconds(pid) for pid in pids]
        start = time.time()
        ended = run.wait(window_s)
        end = time.time()
        end_cpu = [cpu_seconds(pid) for pid in pids]
        if ended is not None:
            raise RuntimeError(f'{ended} ended during the window:\n' + '\n'.join(lines))
    prefix = f'[{LISTENER}] {{'
    result = json.loads(next(line for line in lines if line.startswith(prefix))[len(prefix) - 1:])
    result['window'] = (start, end)
    result['cpu'] = [(after - before) / (end - start)
                     for before, after in zip(start_cpu, end_cpu)]
    notices = [START_NOTICE.match(line) for line in lines]
    result['t0'] = next((float(match.group(1)) for match in notices if match), None)
    return result


def in_window(samples: list, window: tuple[float, float]) -> np.ndarray:
    """Return the (receipt s, stamp s) ``samples`` received in ``window`` as an array."""
    array = np.array(samples, dtype=float).reshape(-1, 2)
    return array[(array[:, 0] >= window[0]) & (array[:, 0] <= window[1])]


def pace(result: dict, topic: str = 'clock') -> float:
    """Return the sim seconds per wall second of ``topic``'s stamps received in the window."""
    stamps = in_window(result[topic], result['window'])
    return (stamps[-1, 1] - stamps[0, 1]) / (stamps[-1, 0] - stamps[0, 0])


def stats_ms(values: np.ndarray) -> str:
    """Return mean, p50, p95 and max of ``values`` (s) in ms, formatted."""
    values = np.asarray(values) * 1e3
    return (f'mean {values.mean():6.2f}  p50 {np.percentile(values, 50):6.2f}  '
            f'p95 {np.percentile(values, 95):6.2f}  max {values.max():6.2f} ms')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='shorter windows')
    parser.add_argument('--listen', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.listen:
        listen()
        return
    scale = 0.5 if args.quick else 1.0
    print(f'Live benchmark: {WORLD} with {NODE}, bridge + node + listener processes, '
          f'{os.cpu_count()} CPUs')

    base = live_window(1.0, warmup_s=2.0, window_s=10.0 * scale)
    seconds = base['window'][1] - base['window'][0]
    print(f'\n1. CPU at real_time_factor 1 (100 Hz physics, 10 Hz 36-beam scans), over '
          f'{seconds:.1f} wall s: CPU s per wall s')
    print(f'   bridge {base["cpu"][0]:6.1%}   {NODE} node {base["cpu"][1]:6.1%}   listener '
          f'{base["cpu"][2]:6.1%}')

    print('\n2. Pace: sim s per wall s on /clock at the listener, against the requested factor')
    print(f'   {"requested":>9s} {"measured":>9s} {"ratio":>7s} {"on /scan":>9s} '
          f'{"CPU: bridge":>12s} {"node":>6s} {"listener":>9s}  sustained')
    best = None
    for factor in FACTORS:
        result = base if factor == 1 else live_window(factor, warmup_s=1.0,
                                                      window_s=5.0 * scale)
        measured = pace(result)
        ratio = measured / factor
        sustained = ratio >= SUSTAINED
        if sustained:
            best = factor
        cpu = result['cpu']
        print(f'   {factor:9g} {measured:9.2f} {ratio:7.1%} {pace(result, "scan"):9.2f} '
              f'{cpu[0]:12.1%} {cpu[1]:6.1%} {cpu[2]:9.1%}  {"yes" if sustained else "no"}')
    print(f'   highest factor sustained (>= {SUSTAINED:.0%}): {best}')

    scans = in_window(base['scan'], base['window'])
    clock = np.array(base['clock'], dtype=float)
    gaps = np.diff(scans[:, 0])
    print(f'\n3. /scan at real_time_factor 1 in the listener process: {len(scans)} scans in '
          f'{seconds:.1f} s, {(len(scans) - 1) / (scans[-1, 0] - scans[0, 0]):.2f} Hz')
    print(f'   inter-arrival        {stats_ms(gaps)}')
    increments = np.round(np.diff(scans[:, 1]) * 1e3).astype(int)
    values, counts = np.unique(increments, return_counts=True)
    print('   stamp increments     ' + ', '.join(f'{value} ms x {count}'
                                                 for value, count in zip(values, counts)))
    if base['t0'] is not None:
        latency = scans[:, 0] - (base['t0'] + scans[:, 1])
        clock_latency = clock[:, 0] - (base['t0'] + clock[:, 1])
        print(f'   latency              {stats_ms(latency)}   (publish due -> receipt; t0 '
              "from the bridge's start notice)")
        print(f'   /clock latency       {stats_ms(clock_latency)}')
    aligned = scans[:, 0] - scans[:, 1] - (clock[:, 0] - clock[:, 1]).min()
    print(f'   above fastest /clock {stats_ms(aligned)}   (/clock-vs-wall alignment)')


if __name__ == '__main__':
    main()
