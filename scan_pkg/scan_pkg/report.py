"""
Turn LaserScan messages into Scans, and Scans into the lab's log lines.

Pure functions shared by the scan-reading nodes: no rclpy here. A message that cannot be a scan
is reported by a text, never by an exception escaping into a node's callback.
"""

import math
from typing import Any, Mapping

import numpy as np

from scan_pkg.laser import Scan

NO_OBSTACLE = 'No valid obstacle readings.'
WARNING_PERIOD_S = 5.0


def positive_parameter(name: str, value: float) -> float:
    """Return ``value`` if it is a positive finite number, else ValueError naming ``name``."""
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"parameter '{name}' must be a positive finite number, got {value!r}")
    return value


def read_scan(msg: Any, logger: Any) -> Scan | None:
    """
    Return the Scan in a LaserScan-like message, or None when there is nothing to report.

    Nothing to report: the message cannot be a scan, has no beams, or only NaN (no beam holds
    any information, so no range may be reported, not even the cap). What is wrong with the
    message (that, or it holds no valid reading) is logged as a warning on ``logger`` (an rclpy
    logger) so a node carries on instead of dying in its callback. rclpy throttles a log call
    site, so each kind of fault has its own call: one kind never hides another.
    """
    try:
        scan = Scan.from_msg(msg)
    except ValueError as error:
        logger.warning(f'ignoring malformed scan: {error}', throttle_duration_sec=WARNING_PERIOD_S)
        return None
    if len(scan) == 0:
        logger.warning(scan_warning(scan), throttle_duration_sec=WARNING_PERIOD_S)
        return None
    warning = scan_warning(scan)
    if warning is not None:
        logger.warning(warning, throttle_duration_sec=WARNING_PERIOD_S)
    return None if scan.is_blind() else scan


def scan_warning(scan: Scan) -> str | None:
    """
    Return a text naming why ``scan`` holds no measurement, or None when nothing is wrong.

    A scan where every beam saw nothing within range (+inf or beyond range_max) is open space,
    not a fault.
    """
    if len(scan) == 0:
        return 'ignoring scan with no ranges'
    ranges = scan.ranges
    # Nothing is wrong with a valid reading (closest finds one) or with open space all round.
    if scan.closest() is not None or (ranges > scan.range_max).all():
        return None
    # With no valid reading, every finite one lies outside the sensor's range.
    finite = np.isfinite(ranges)
    counts = {
        'NaN': np.isnan(ranges).sum(),
        '+inf (no return)': np.isposinf(ranges).sum(),
        '-inf (too close)': np.isneginf(ranges).sum(),
        f'outside [{scan.range_min:g}, {scan.range_max:g}] m': finite.sum(),
    }
    found = ', '.join(f'{count} {kind}' for kind, count in counts.items() if count)
    return f'no valid reading among {len(scan)} beams ({found})'


def format_range(range_m: float | None) -> str:
    """Format a range (m) with centimetre resolution; None (no beam there) as 'n/a'."""
    return 'n/a' if range_m is None else f'{range_m:.2f} m'


def range_ahead_line(scan: Scan, max_range: float) -> str:
    """Return the log line of the range straight ahead, capped at ``max_range`` (m)."""
    return f'Range ahead: {format_range(scan.range_at(0.0, max_range=max_range))}'


def regions_line(regions: Mapping[str, float | None]) -> str:
    """Return the one-line log of the five region minima (m), right to left."""
    return ' | '.join(f"{name.replace('_', '-')}: {format_range(value)}"
                      for name, value in regions.items())


def closest_line(scan: Scan) -> str:
    """Return the log line of the nearest valid return: distance (m) and bearing (deg)."""
    closest = scan.closest()
    if closest is None:
        return NO_OBSTACLE
    range_m, angle_rad, _ = closest
    return (f'Closest obstacle: {format_range(range_m)} '
            f'at {math.degrees(angle_rad):+.1f} deg')
