"""
Benchmark the lockstep runtime's per-event overhead.

Prints the time (us) per event of:
* publish -> deliver of a LaserScan with 36 and 1081 beams (validation, delivery copy, queueing,
  the callback call), with and without a tap (what the runner's recorder adds);
* building that LaserScan from a numpy array, as the simulator bridge does each scan;
* publish -> deliver of a Twist, an Odometry and a one-transform TFMessage;
* one timer event with an empty callback;
* one simulated second of a bridge-like node (100 Hz timer, /clock every tick, a 36-beam scan
  every 10th tick, received by one subscriber), and the real-time factor that overhead alone
  would allow.

Run: python test/bench/bench_lockstep.py [--quick]
"""

import sys
import time

import numpy as np

from sim_bridge import lockstep

TARGET_S = 0.05 if '--quick' in sys.argv else 0.25
REPEATS = 3


def best_time_per_call(function, calls: int) -> float:
    """Best-of-REPEATS wall time per call (s) of ``function(calls)``."""
    best = float('inf')
    for _ in range(REPEATS):
        start = time.perf_counter()
        function(calls)
        best = min(best, (time.perf_counter() - start) / calls)
    return best


def calibrated(function) -> float:
    """Time per call (s), with a call count chosen to run about TARGET_S."""
    calls = 16
    while True:
        start = time.perf_counter()
        function(calls)
        if time.perf_counter() - start > TARGET_S / 4:
            break
        calls *= 2
    return best_time_per_call(function, calls)


def main() -> None:
    runtime = lockstep.install()
    try:
        import rclpy
        from geometry_msgs.msg import TransformStamped, Twist
        from nav_msgs.msg import Odometry
        from rclpy.node import Node
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import LaserScan
        from tf2_msgs.msg import TFMessage

        rclpy.init(args=[])
        source = Node('source')
        sink = Node('sink')
        rows = []

        def scan(beams: int) -> LaserScan:
            return LaserScan(angle_min=-1.57, angle_max=1.57, angle_increment=3.14 / (beams - 1),
                             range_min=0.12, range_max=10.0,
                             ranges=np.linspace(0.5, 9.5, beams))

        def publish_deliver(publisher, msg):
            def run(calls):
                for _ in range(calls):
                    publisher.publish(msg)
                    runtime.run_until(runtime.now_ns)
            return run

        for beams in (36, 1081):
            topic = f'scan_{beams}'
            publisher = source.create_publisher(LaserScan, topic, 10)
            sink.create_subscription(LaserScan, topic, lambda msg: None, 10)
            msg = scan(beams)
            rows.append((f'LaserScan {beams} beams: publish -> deliver',
                         calibrated(publish_deliver(publisher, msg))))

            def ignore(topic, msg, t_ns):
                pass
            runtime.add_tap(ignore)
            rows.append((f'LaserScan {beams} beams: publish -> deliver, with a tap',
                         calibrated(publish_deliver(publisher, msg))))
            runtime.remove_tap(ignore)
            ranges = np.linspace(0.5, 9.5, beams)
            rows.append((f'LaserScan {beams} beams: build from a numpy array',
                         calibrated(lambda calls: [LaserScan(ranges=ranges)
                                                   for _ in range(calls)])))

        twist_publisher = source.create_publisher(Twist, 'cmd_vel', 10)
        sink.create_subscription(Twist, 'cmd_vel', lambda msg: None, 10)
        twist = Twist()
        twist.linear.x = 0.2
        rows.append(('Twist: publish -> deliver',
                     calibrated(publish_deliver(twist_publisher, twist))))
        odom_publisher = source.create_publisher(Odometry, 'odom', 10)
        sink.create_subscription(Odometry, 'odom', lambda msg: None, 10)
        rows.append(('Odometry: publish -> deliver',
                     calibrated(publish_deliver(odom_publisher, Odometry()))))
        tf_publisher = source.create_publisher(TFMessage, 'tf', 100)
        sink.create_subscription(TFMessage, 'tf', lambda msg: None, 100)
        rows.append(('TFMessage with 1 transform: publish -> deliver',
                     calibrated(publish_deliver(tf_publisher, TFMessage(
                         transforms=[TransformStamped(child_frame_id='base_link')])))))

        timer_node = Node('ticker')
        fired = [0]

        def tick():
            fired[0] += 1
        timer = timer_node.create_timer(0.001, tick)

        def timer_events(calls):
            runtime.run_until(runtime.now_ns + calls * 1_000_000)
        start_ns, fired[0] = runtime.now_ns, 0
        per_period = calibrated(timer_events)
        events_per_period = fired[0] / ((runtime.now_ns - start_ns) / 1_000_000)
        rows.append(('timer event (callback counting calls)', per_period / events_per_period))
        timer_node.destroy_timer(timer)

        bridge = Node('bridge')
        clock_publisher = bridge.create_publisher(Clock, 'clock', 10)
        scan_publisher = bridge.create_publisher(LaserScan, 'scan', 10)
        sink.create_subscription(LaserScan, 'scan', lambda msg: None, 10)
        ticks = [0]
        ranges = np.linspace(0.5, 9.5, 36)

        def step():
            ticks[0] += 1
            clock_publisher.publish(Clock(clock=bridge.get_clock().now().to_msg()))
            if ticks[0] % 10 == 0:
                scan_publisher.publish(LaserScan(angle_min=-1.57, angle_max=1.57,
                                                 range_min=0.12, range_max=10.0, ranges=ranges))
        bridge.create_timer(0.01, step)

        def sim_seconds(calls):
            runtime.run_until(runtime.now_ns + calls * 1_000_000_000)
        per_sim_second = calibrated(sim_seconds)
        rows.append(('bridge-like node, per simulated second', per_sim_second))
    finally:
        lockstep.uninstall()

    width = max(len(label) for label, _ in rows)
    print(f'{"lockstep event":<{width}}  {"us":>9}')
    for label, seconds in rows:
        print(f'{label:<{width}}  {seconds * 1e6:9.2f}')
    print(f'real-time factor allowed by the runtime overhead alone: {1 / per_sim_second:,.0f}x')


if __name__ == '__main__':
    main()
