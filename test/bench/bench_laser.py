"""
Benchmark scan_pkg.laser against the lab's list-slicing code, on the same scans.

Prints the time (us) per scan a node spends on its questions: build the Scan from the message,
then regions(), closest() and range_at(0). The lab's code answers the same three questions the
way the classic ROS tutorials do: min() over five list slices, a Python loop for the nearest
reading, and the middle element for the range ahead. Each row uses one seeded pool of scans for
both, with the message's ranges held as array.array('f') (what rclpy delivers) or as a list.

Run: python test/bench/bench_laser.py [--quick]
"""

import array
import math

import numpy as np
from scan_pkg.laser import Scan
from timing import microseconds_per_call

SEED = 20240611
POOL = 32

# Scanners with the beam counts of the benchmark: the lab's 36 beams over +-1.57 rad,
# a TurtleBot3 LDS (360 beams over 0..2 pi) and a Hokuyo UTM-30LX (1081 beams over +-135 deg).
SCANNERS = {
    36: {'angle_min': -1.57, 'angle_max': 1.57, 'range_min': 0.12, 'range_max': 3.5},
    360: {'angle_min': 0.0, 'angle_max': 2 * math.pi * 359 / 360, 'range_min': 0.12,
          'range_max': 3.5},
    1081: {'angle_min': -math.radians(135), 'angle_max': math.radians(135), 'range_min': 0.1,
           'range_max': 30.0},
}


class Message:
    """The fields of sensor_msgs/msg/LaserScan that both implementations read."""

    def __init__(self, ranges, angle_min, angle_max, range_min, range_max):
        self.ranges = ranges
        self.angle_min = angle_min
        self.angle_max = angle_max
        self.angle_increment = (angle_max - angle_min) / (len(ranges) - 1)
        self.range_min = range_min
        self.range_max = range_max


def readings(rng, beams, range_min, range_max, messy):
    """
    Return one scan's ranges (m) as a simulator or a driver reports them.

    Beyond range_max there is no return (+inf). A messy scan also holds NaN, -inf and readings
    below range_min, a few percent each.
    """
    ranges = rng.uniform(range_min, 1.2 * range_max, beams)
    ranges[ranges > range_max] = math.inf
    if messy:
        kind = rng.random(beams)
        ranges[kind < 0.03] = math.nan
        ranges[(kind >= 0.03) & (kind < 0.05)] = -math.inf
        ranges[(kind >= 0.05) & (kind < 0.08)] = range_min / 2
    return ranges.astype(np.float32)


def ours(msg):
    scan = Scan.from_msg(msg)
    return scan.regions(), scan.closest(), scan.range_at(0.0)


def lab(msg):
    """Answer the three questions as the lab's nodes do, on the message's own sequence."""
    k = len(msg.ranges) // 5
    regions = {
        'right': min(min(msg.ranges[0:k]), 10),
        'fright': min(min(msg.ranges[k:2 * k]), 10),
        'front': min(min(msg.ranges[2 * k:3 * k]), 10),
        'fleft': min(min(msg.ranges[3 * k:4 * k]), 10),
        'left': min(min(msg.ranges[4 * k:5 * k]), 10),
    }
    closest_range, closest_index = math.inf, -1
    for index, reading in enumerate(msg.ranges):
        if math.isinf(reading) or math.isnan(reading):
            continue
        if reading < closest_range:
            closest_range, closest_index = reading, index
    closest = (closest_range, msg.angle_min + closest_index * msg.angle_increment)
    ahead = msg.ranges[len(msg.ranges) // 2]
    return regions, closest, ahead


def main():
    rng = np.random.default_rng(SEED)
    print('us per scan for from_msg + regions() + closest() + range_at(0); '
          'lab = list slicing + Python loop')
    print(f"{'beams':>6} {'ranges':>12} {'scans':>6} {'ours us':>9} {'lab us':>9} {'lab/ours':>9}")
    for beams, scanner in SCANNERS.items():
        for messy in (False, True):
            pool = [readings(rng, beams, scanner['range_min'], scanner['range_max'], messy)
                    for _ in range(POOL)]
            for container in ('array.array', 'list'):
                messages = [Message(array.array('f', ranges) if container == 'array.array'
                                    else ranges.tolist(), **scanner) for ranges in pool]
                ours_us = microseconds_per_call(ours, lambda: messages)
                lab_us = microseconds_per_call(lab, lambda: messages)
                print(f"{beams:>6} {container:>12} {'messy' if messy else 'clean':>6} "
                      f'{ours_us:>9.1f} {lab_us:>9.1f} {lab_us / ours_us:>8.1f}x')


if __name__ == '__main__':
    main()
