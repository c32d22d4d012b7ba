"""rclpy.constants for the lockstep runtime."""

__lockstep__ = True

S_TO_NS = 1000 * 1000 * 1000
