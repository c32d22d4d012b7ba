"""
Pure controllers of the lab's driving nodes: no rclpy, plain numbers in and out.

:mod:`~scan_pkg.behaviors.wander` drives the wanderbot, :mod:`~scan_pkg.behaviors.wall_follow`
the wall follower; each takes :class:`scan_pkg.laser.Scan` objects and returns
``(linear m/s, angular rad/s)`` commands as Python floats.
"""

from typing import Any, Iterable


def require(config: Any, *, positive: Iterable[str] = (), non_negative: Iterable[str] = ()
            ) -> None:
    """Raise ValueError naming the first field of ``config`` that is out of its range."""
    for name in positive:
        if not getattr(config, name) > 0.0:
            raise ValueError(f'{name} must be > 0, got {getattr(config, name)!r}')
    for name in non_negative:
        if not getattr(config, name) >= 0.0:
            raise ValueError(f'{name} must be >= 0, got {getattr(config, name)!r}')
