"""
Pure controllers of the lab's driving nodes: no rclpy, plain numbers in and out.

:mod:`~scan_pkg.behaviors.wander` drives the wanderbot, :mod:`~scan_pkg.behaviors.wall_follow`
the wall follower; each takes :class:`scan_pkg.laser.Scan` objects and returns
``(linear m/s, angular rad/s)`` commands as Python floats.
"""
