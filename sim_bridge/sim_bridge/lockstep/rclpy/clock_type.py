"""rclpy.clock_type for the lockstep runtime: the ClockType enum."""

from enum import IntEnum

__lockstep__ = True


class ClockType(IntEnum):
    """Kinds of clock; in the lockstep runtime every kind reads the simulated clock."""

    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3
