"""
Where a run's robot drove and turned: path length, runs of a condition, stop-and-turns.

Plain functions of numpy arrays (units in each docstring), shared by the metrics and the
evidence of the motion tasks (:mod:`.motion_evidence`). Pure: numpy only.
"""

import math

import numpy as np

#: A stop-and-turn manoeuvre: turning faster than this (rad/s) ...
TURN_MIN_ANGULAR = 0.1
#: ... and, at some moment of it, driving slower than this (m/s).
TURN_MAX_LINEAR = 0.02
#: Turning pauses shorter than this (s) belong to the same manoeuvre (a controller re-planning).
TURN_MAX_GAP = 0.25


def path_length(x: np.ndarray, y: np.ndarray) -> float:
    """Return the length (m) of the polyline through the points (``x``, ``y``) (m)."""
    if len(x) < 2:
        return 0.0
    return float(np.hypot(np.diff(x), np.diff(y)).sum())


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Return the (first, last) indices, inclusive, of each maximal run of True in ``mask``."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1).tolist(),
                    (np.flatnonzero(edges == -1) - 1).tolist()))


def stop_and_turn_periods(time: np.ndarray, linear: np.ndarray,
                          angular: np.ndarray) -> list[tuple[int, int]]:
    """
    Return the (first, last) sample indices, inclusive, of each stop-and-turn manoeuvre.

    A manoeuvre is a maximal period of turning faster than ``TURN_MIN_ANGULAR`` (rad/s), with
    pauses shorter than ``TURN_MAX_GAP`` (s) bridged, during which the robot at some moment
    drives slower than ``TURN_MAX_LINEAR`` (m/s). Counting the whole turning period, not only
    its stopped part, keeps the rotation made while the robot was still braking (velocity and
    acceleration limits) in the manoeuvre. A manoeuvre still open when the run ends (turning
    at the last sample, or paused for no longer than ``TURN_MAX_GAP`` before it) is left out:
    its final angle is unknown, and scoring the part done so far would report a short turn
    that the robot never made. ``time`` in s, ``linear`` m/s, ``angular`` rad/s.
    """
    merged: list[list[int]] = []
    for first, last in true_runs(np.abs(angular) > TURN_MIN_ANGULAR):
        if merged and time[first] - time[merged[-1][1]] <= TURN_MAX_GAP:
            merged[-1][1] = last
        else:
            merged.append([first, last])
    if merged and time[-1] - time[merged[-1][1]] <= TURN_MAX_GAP:
        merged.pop()
    slow = np.abs(linear) < TURN_MAX_LINEAR
    return [(first, last) for first, last in merged if slow[first:last + 1].any()]


def turn_angle(yaw: np.ndarray, first: int, last: int) -> float:
    """Return the heading change (deg, absolute) from before sample ``first`` to ``last``."""
    heading = np.unwrap(yaw[max(first - 1, 0):last + 1])
    return math.degrees(abs(heading[-1] - heading[0]))


def stop_and_turn_angles(time: np.ndarray, linear: np.ndarray, angular: np.ndarray,
                         yaw: np.ndarray) -> list[float]:
    """
    Return the heading change (deg, absolute) of each stop-and-turn manoeuvre.

    The manoeuvres are :func:`stop_and_turn_periods`'; ``time`` in s, ``linear`` m/s,
    ``angular`` rad/s, ``yaw`` rad.
    """
    return [turn_angle(yaw, first, last)
            for first, last in stop_and_turn_periods(time, linear, angular)]
