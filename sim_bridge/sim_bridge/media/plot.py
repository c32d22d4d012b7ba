"""
Draw a run from above: obstacles, the robot's path coloured by time, collisions, lidar scans.

Rendering only; it reads a finished :class:`~sim_bridge.scoring.run_trace.Trace` and the run's
world and writes a PNG through matplotlib's Agg canvas (no pyplot, no GUI, safe in any process).
"""

import math
import os
from typing import Any

from matplotlib import colormaps
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import PathPatch, Polygon, Rectangle
from matplotlib.path import Path
import numpy as np
from shapely.geometry.polygon import orient
from sim_bridge.scoring.run_trace import ScanSnapshot, Trace

#: How many lidar scans, evenly spread in time, the plot draws.
SCANS_DRAWN = 4
#: Scans with at most this many beams also get their rays drawn, not only the hits.
MAX_RAYS_DRAWN = 90
#: The path is thinned to at most this many segments: plenty for a figure, quick to render.
MAX_SEGMENTS = 3000
FIGURE_WIDTH = 8.0  # inches
OBSTACLE_COLOUR = '#9e9e9e'
TARGET_COLOUR = '#f4a259'
PATH_COLOURMAP = 'viridis'


def scan_hits(scan: ScanSnapshot) -> np.ndarray:
    """Return the (K, 2) world points (m) where the scan's beams hit something."""
    ranges = np.asarray(scan.ranges, dtype=float)
    angles = scan.pose[2] + scan.angle_min + scan.angle_increment * np.arange(len(ranges))
    hit = np.isfinite(ranges)
    return np.column_stack((scan.pose[0] + ranges[hit] * np.cos(angles[hit]),
                            scan.pose[1] + ranges[hit] * np.sin(angles[hit])))


def spread_evenly(items: list, count: int) -> list:
    """Return up to ``count`` items taken at evenly spaced positions, first and last included."""
    if len(items) <= count:
        return list(items)
    return [items[round(index)] for index in np.linspace(0, len(items) - 1, count)]


def plot_trajectory(trace: Trace, world: Any, path: str | os.PathLike, *,
                    title: str | None = None) -> Figure:
    """
    Write a top-down PNG of the run to ``path`` and return the figure.

    ``world`` is the run's ``World``: its obstacles are drawn as what the robot could hit,
    their slice through its height band (a table whose top is above the robot is its legs),
    the target highlighted, its bounds dashed. The path is coloured by sim time (s); start
    and end are marked with the robot's outline there, each collision with a cross; a few
    lidar scans show what the robot saw.
    """
    figure = Figure(figsize=(FIGURE_WIDTH, FIGURE_WIDTH), dpi=120, layout='constrained')
    axes = figure.add_subplot()
    legend = _draw_world(axes, world)
    time, x, y = trace.array('time'), trace.array('x'), trace.array('y')
    colour_scale = (float(time[0]), float(max(time[-1], time[0] + 1e-9))) if len(time) else None
    if len(time):
        legend += _draw_scans(axes, trace.scans, colour_scale)
        _draw_path(figure, axes, time, x, y, colour_scale)
        legend += _draw_robot_ends(axes, world, x, y, trace.array('yaw'))
    if trace.collisions:
        axes.plot([event.x for event in trace.collisions], [event.y for event in trace.collisions],
                  'x', color='red', markersize=11, markeredgewidth=2.5, zorder=6)
        legend.append(Line2D([], [], linestyle='none', marker='x', color='red',
                             markeredgewidth=2.5, label=f'collision ({len(trace.collisions)})'))
    axes.set_title(title if title is not None else str(getattr(world, 'name', '')))
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.set_aspect('equal', adjustable='box')
    axes.grid(True, linewidth=0.4, alpha=0.5)
    axes.autoscale_view()
    (xmin, xmax), (ymin, ymax) = axes.get_xlim(), axes.get_ylim()
    # Height for the map's aspect (the colour bar takes a fifth of the width), plus room for
    # the title, the axis label and the legend.
    height = FIGURE_WIDTH * 0.8 * (ymax - ymin) / max(xmax - xmin, 1e-9) + 1.6
    figure.set_size_inches(FIGURE_WIDTH, min(max(height, 4.5), 2.0 * FIGURE_WIDTH))
    figure.legend(handles=legend, loc='outside lower center', ncols=3, fontsize='small',
                  frameon=False)
    figure.savefig(os.fspath(path), format='png')
    return figure


def _draw_world(axes, world) -> list:
    xmin, ymin, xmax, ymax = world.bounds
    axes.add_patch(Rectangle((xmin, ymin), xmax - xmin, ymax - ymin, fill=False,
                             linestyle='--', linewidth=0.8, edgecolor='#bdbdbd'))
    for footprint, owner in zip(world.footprints(), world.footprint_owners()):
        is_target = owner == world.target
        axes.add_patch(_patch(footprint, zorder=2,
                              facecolor=TARGET_COLOUR if is_target else OBSTACLE_COLOUR,
                              edgecolor='#c0631a' if is_target else '#616161',
                              linewidth=1.5 if is_target else 0.6))
    legend = []
    if any(obstacle.name != world.target for obstacle in world.obstacles):
        legend.append(Rectangle((0, 0), 1, 1, facecolor=OBSTACLE_COLOUR, label='obstacle'))
    if world.target is not None:
        legend.append(Rectangle((0, 0), 1, 1, facecolor=TARGET_COLOUR, edgecolor='#c0631a',
                                label=f'target: {world.target}'))
    return legend


def _patch(footprint, **style):
    """
    Return a patch of a footprint; a polygon's holes stay open.

    A wall enclosing an area (the TurtleBot3 world's hexagon) is a polygon with a hole where
    the robot drives; its exterior alone would paint over that floor.
    """
    if footprint.kind != 'polygon':
        return Polygon(footprint.outline(), closed=True, **style)
    parts = getattr(footprint.polygon, 'geoms', [footprint.polygon])
    # Oriented exteriors counter-clockwise and holes clockwise: the fill leaves holes out.
    rings = [ring for part in parts for oriented in [orient(part)]
             for ring in (oriented.exterior, *oriented.interiors)]
    return PathPatch(Path.make_compound_path(
        *(Path(np.asarray(ring.coords), closed=True) for ring in rings)), **style)


def _draw_path(figure, axes, time, x, y, colour_scale) -> None:
    stride = max(1, math.ceil(len(time) / MAX_SEGMENTS))
    points = np.column_stack((x, y))[::stride]
    if stride > 1:
        points = np.vstack((points, [(x[-1], y[-1])]))
    times = np.append(time[::stride], time[-1])[:len(points)]
    segments = np.stack((points[:-1], points[1:]), axis=1)
    path = LineCollection(segments, cmap=PATH_COLOURMAP, linewidths=2.0, capstyle='round',
                          zorder=4)
    path.set_array(0.5 * (times[:-1] + times[1:]))
    path.set_clim(*colour_scale)
    axes.add_collection(path)
    figure.colorbar(path, ax=axes, label='time (s)', shrink=0.8)


def _draw_robot_ends(axes, world, x, y, yaw) -> list:
    marks = []
    ends = (((x[0], y[0], yaw[0]), '#2e7d32', 'o', 'start'),
            ((x[-1], y[-1], yaw[-1]), '#c62828', 's', 'end'))
    for pose, colour, marker, label in ends:
        for ring in world.floor_slice.robot_outlines(pose):
            axes.plot(ring[:, 0], ring[:, 1], color=colour, linewidth=1.0, zorder=5)
        axes.plot(pose[0], pose[1], marker, color=colour, markersize=7, zorder=5)
        marks.append(Line2D([], [], linestyle='none', marker=marker, color=colour, label=label))
    return marks


def _draw_scans(axes, scans, colour_scale) -> list:
    drawn = spread_evenly(scans, SCANS_DRAWN)
    colourmap = colormaps[PATH_COLOURMAP]
    legend = []
    for scan in drawn:
        share = (scan.time - colour_scale[0]) / (colour_scale[1] - colour_scale[0])
        colour = colourmap(min(max(share, 0.0), 1.0))
        hits = scan_hits(scan)
        if len(scan.ranges) <= MAX_RAYS_DRAWN and len(hits):
            rays = np.stack((np.broadcast_to(scan.pose[:2], hits.shape), hits), axis=1)
            axes.add_collection(LineCollection(rays, colors=[colour], linewidths=0.5,
                                               alpha=0.25, zorder=3))
        axes.plot(hits[:, 0], hits[:, 1], '.', color=colour, markersize=4, zorder=3)
    if drawn:
        legend.append(Line2D([], [], linestyle='none', marker='.', color='#555555',
                             label=f'lidar hits ({len(drawn)} scans, coloured by time)'))
    return legend
