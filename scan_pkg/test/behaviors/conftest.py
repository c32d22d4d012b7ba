"""Synthetic scans for the controller tests: a lab lidar ray-cast analytically against shapes."""

import dataclasses
import math
from pathlib import Path
import sys

import numpy as np
import pytest
from scan_pkg.laser import Scan
import yaml

LAB_BEAMS = 36
LAB_ANGLE_MIN = -1.57
LAB_ANGLE_MAX = 1.57
LAB_RANGE_MIN = 0.12
LAB_RANGE_MAX = 10.0


def segment_ranges(origin, directions, start, end):
    """Return the distance (m) along each unit direction to segment start-end (inf if missed)."""
    p = np.asarray(start, float)
    edge = np.asarray(end, float) - p
    offset = p - np.asarray(origin, float)
    # Solve origin + t * direction = p + s * edge for t >= 0 and 0 <= s <= 1.
    denominator = directions[:, 0] * edge[1] - directions[:, 1] * edge[0]
    with np.errstate(divide='ignore', invalid='ignore'):
        t = (offset[0] * edge[1] - offset[1] * edge[0]) / denominator
        s = (offset[0] * directions[:, 1] - offset[1] * directions[:, 0]) / denominator
    hit = (denominator != 0.0) & (t >= 0.0) & (s >= 0.0) & (s <= 1.0)
    return np.where(hit, t, np.inf)


def circle_ranges(origin, directions, centre, radius):
    """
    Return the distance (m) along each unit direction to a circle (inf if missed).

    From outside, the near side of the circle; from inside, the circle around the origin.
    """
    offset = np.asarray(centre, float) - np.asarray(origin, float)
    along = directions @ offset
    squared_miss = offset @ offset - along ** 2
    half_chord = np.sqrt(np.maximum(radius ** 2 - squared_miss, 0.0))
    t = np.where(along - half_chord >= 0.0, along - half_chord, along + half_chord)
    return np.where((squared_miss <= radius ** 2) & (t >= 0.0), t, np.inf)


def box_segments(centre_x, centre_y, half_x, half_y):
    """Return the four edges of an axis-aligned box (m) as (start, end) pairs."""
    corners = [(centre_x - half_x, centre_y - half_y), (centre_x + half_x, centre_y - half_y),
               (centre_x + half_x, centre_y + half_y), (centre_x - half_x, centre_y + half_y)]
    return [(corners[i], corners[(i + 1) % 4]) for i in range(4)]


def cast_scan(segments=(), circles=(), pose=(0.0, 0.0, 0.0), beams=LAB_BEAMS,
              angle_min=LAB_ANGLE_MIN, angle_max=LAB_ANGLE_MAX, noise=0.0, seed=0):
    """
    Return the Scan a lidar at ``pose`` (x m, y m, yaw rad) sees of segments and circles.

    ``segments``: ((x1, y1), (x2, y2)) pairs; ``circles``: ((x, y), radius) pairs, all in m in
    the frame of ``pose``. No return is +inf, as the simulator reports it; ``noise`` is the
    standard deviation (m) of Gaussian noise added to the returns.
    """
    increment = (angle_max - angle_min) / (beams - 1)
    bearings = pose[2] + angle_min + increment * np.arange(beams)
    directions = np.column_stack((np.cos(bearings), np.sin(bearings)))
    origin = pose[:2]
    ranges = np.full(beams, np.inf)
    for start, end in segments:
        ranges = np.minimum(ranges, segment_ranges(origin, directions, start, end))
    for centre, radius in circles:
        ranges = np.minimum(ranges, circle_ranges(origin, directions, centre, radius))
    if noise:
        finite = np.isfinite(ranges)
        ranges[finite] += np.random.default_rng(seed).normal(0.0, noise, finite.sum())
    ranges[ranges > LAB_RANGE_MAX] = np.inf
    return Scan(ranges, angle_min, increment, LAB_RANGE_MIN, LAB_RANGE_MAX)


def mirrored(scan):
    """Return ``scan`` seen in a mirror through the robot's heading (y -> -y)."""
    assert math.isclose(scan.angle_min, -scan.angle_max)
    return Scan(scan.ranges[::-1], scan.angle_min, scan.angle_increment, scan.range_min,
                scan.range_max)


PARAMS_DIR = Path(__file__).resolve().parents[2] / 'params'


def check_params_file(node_name, config_class, node_parameters):
    """
    Assert params/<node>.yaml lists every parameter with the code's default and type.

    ``node_parameters``: the node's own parameters beyond ``config_class``'s fields, by name.
    """
    text = (PARAMS_DIR / f'{node_name}.yaml').read_text(encoding='utf-8')
    listed = yaml.safe_load(text)[node_name]['ros__parameters']
    defaults = {field.name: field.default for field in dataclasses.fields(config_class)}
    defaults.update(node_parameters)
    assert listed == defaults
    # rclpy types a parameter by its value: 1 would make a float parameter an integer one.
    assert {name: type(value) for name, value in listed.items()} == {
        name: type(value) for name, value in defaults.items()}


# Captured at import: when the fixture runs, the name 'conftest' may be another folder's.
_SCAN_BUILDERS = sys.modules[__name__]


@pytest.fixture(scope='session')
def shapes():
    """Give tests this module's scan builders: ``shapes.cast_scan(...)`` and the rest."""
    return _SCAN_BUILDERS
