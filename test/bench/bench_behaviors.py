"""
Benchmark the driving controllers: time (us) per call of each step of a scan callback.

The scan is the simulator's: the lab's scanner (-1.57..+1.57 rad, 0.12-10 m) with 36 beams and
with 1081, a straight wall 0.5 m to the right of the robot and parallel to it, nothing
elsewhere (+inf), Gaussian noise of 0.01 m on the returns, the ranges as array.array('f') (what
rclpy delivers). Each timed call gets a Scan it has not seen, as a node does: nothing a Scan
caches carries over from one call to the next.

Rows: ``read_scan`` (message to Scan); ``obstacle_points``, ``estimate_wall`` and
``corridor_distance`` (the wall follower's pieces); the WallFollower's ``update_scan`` +
``command`` and the Wanderer's (the controllers, without ROS); and the wall_follow node's
``on_scan`` callback on real rclpy (the above plus the clock and the Twist).

Run: python test/bench/bench_behaviors.py [--quick]
"""

import array
import math

import numpy as np
import rclpy
from scan_pkg.behaviors.wall_follow import estimate_wall, WallFollowConfig, WallFollower
from scan_pkg.behaviors.wander import corridor_distance, obstacle_points, Wanderer
from scan_pkg.laser import Scan
from scan_pkg.report import read_scan
from sim_bridge.common.run_environment import keep_dds_in_process
from timing import microseconds_per_call

BEAMS = (36, 1081)
ANGLE_MIN, ANGLE_MAX = -1.57, 1.57
RANGE_MIN, RANGE_MAX = 0.12, 10.0
WALL_Y = -0.5
NOISE_M = 0.01
SEED = 1
POOL = 16


class Message:
    """The fields of sensor_msgs/msg/LaserScan that read_scan reads."""

    def __init__(self, ranges: np.ndarray):
        self.ranges = array.array('f', ranges)
        self.angle_min = ANGLE_MIN
        self.angle_max = ANGLE_MAX
        self.angle_increment = (ANGLE_MAX - ANGLE_MIN) / (len(ranges) - 1)
        self.range_min = RANGE_MIN
        self.range_max = RANGE_MAX


def wall_ranges(rng: np.random.Generator, beams: int) -> np.ndarray:
    """Return the ranges (m) of a wall WALL_Y m beside the robot, with noise, +inf elsewhere."""
    angles = np.linspace(ANGLE_MIN, ANGLE_MAX, beams)
    with np.errstate(divide='ignore'):
        ranges = WALL_Y / np.sin(angles)
    seen = (ranges > 0.0) & (ranges <= RANGE_MAX)
    ranges[seen] += rng.normal(0.0, NOISE_M, seen.sum())
    ranges[~seen] = math.inf
    return ranges


def follower_step(follower: WallFollower):
    """Return a call feeding a scan to ``follower`` and asking its command, 0.1 s apart."""
    clock = [0.0]

    def step(scan):
        clock[0] += 0.1
        follower.update_scan(scan, clock[0])
        follower.command(clock[0])
    return step


def node_callback():
    """Return the on_scan of a wall_follow node on real rclpy (initialised by the caller)."""
    from scan_pkg.wall_follow import WallFollow
    return WallFollow().on_scan


def main() -> None:
    rng = np.random.default_rng(SEED)
    config = WallFollowConfig()
    length = config.distance + config.robot_radius
    rows = {}
    keep_dds_in_process()
    rclpy.init(args=[])
    try:
        on_scan = node_callback()
        for beams in BEAMS:
            messages = [Message(wall_ranges(rng, beams)) for _ in range(POOL)]

            def scans():
                return [Scan.from_msg(msg) for msg in messages]

            def points():
                return [obstacle_points(scan) for scan in scans()]

            rows[beams] = {
                # These scans are sound: read_scan logs nothing, so it needs no logger.
                'read_scan': microseconds_per_call(lambda msg: read_scan(msg, None),
                                                   lambda: messages),
                'obstacle_points': microseconds_per_call(obstacle_points, scans),
                'estimate_wall': microseconds_per_call(
                    lambda p: estimate_wall(p, config.fit_radius, config.extrapolation), points),
                'corridor_distance': microseconds_per_call(
                    lambda p: corridor_distance(p, length, config.robot_radius,
                                                config.stop_margin), points),
                'WallFollower update+command': microseconds_per_call(
                    follower_step(WallFollower(config)), scans),
                'Wanderer update+command': microseconds_per_call(
                    follower_step(Wanderer()), scans),
                'WallFollow.on_scan': microseconds_per_call(on_scan, lambda: messages),
            }
    finally:
        rclpy.try_shutdown()
    print(f"{'us per call':<30}" + ''.join(f'{beams:>10} beams' for beams in BEAMS))
    for name in rows[BEAMS[0]]:
        print(f'{name:<30}' + ''.join(f'{rows[beams][name]:>16.1f}' for beams in BEAMS))


if __name__ == '__main__':
    main()
