"""The trajectory plot: a real PNG whose axes show the whole run and mark what happened."""

from dataclasses import replace
import math

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon
import numpy as np
import pytest
import shapely

from sim_bridge.media.plot import _patch, plot_trajectory, scan_hits, SCANS_DRAWN, spread_evenly
from sim_bridge.scoring.run_trace import CollisionEvent, ScanSnapshot, Trace
from sim_bridge.simulation.geometry import Footprint, Shape
from sim_bridge.simulation.world import Obstacle, World

PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


@pytest.fixture
def world():
    return World.from_dict({
        'obstacles': [
            {'name': 'box', 'type': 'cube', 'size': [1.2, 0.8, 1.0], 'pose': [0.0, 0.0, 0.3]},
            {'name': 'pillar', 'type': 'cylinder', 'radius': 0.3, 'length': 1.0,
             'pose': [2.0, 2.0]}],
        'target': 'box', 'bounds': [-3.0, -3.0, 3.0, 3.0], 'robot': {'pose': [1.3, 0.0, 0.0]}})


@pytest.fixture
def trace():
    """One and a half clockwise loops of radius 1.3 m, a scan every 0.5 s, one collision."""
    trace = Trace(robot_radius=0.15)
    for index, angle in enumerate(np.linspace(0.0, -3.0 * math.pi, 1500)):
        x, y, yaw = 1.3 * math.cos(angle), 1.3 * math.sin(angle), angle - math.pi / 2
        trace.append(time=0.01 * (index + 1), x=x, y=y, yaw=yaw, linear=0.3, angular=-0.23,
                     clearance=0.5)
        if index % 50 == 0:
            trace.scans.append(ScanSnapshot(0.01 * (index + 1), (x, y, yaw), np.full(36, 0.7),
                                            -1.57, 3.14 / 35))
    trace.collisions.append(CollisionEvent(3.0, -1.3, 0.0, 'box'))
    return trace


def test_plot_writes_a_png_of_substance(tmp_path, trace, world):
    path = tmp_path / 'trajectory.png'
    plot_trajectory(trace, world, path)
    data = path.read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    assert len(data) > 30_000


def test_plot_view_holds_the_path_the_obstacles_and_the_bounds(tmp_path, trace, world):
    axes = plot_trajectory(trace, world, tmp_path / 'trajectory.png').axes[0]
    (xmin, xmax), (ymin, ymax) = axes.get_xlim(), axes.get_ylim()
    assert xmin <= -3.0 and xmax >= 3.0 and ymin <= -3.0 and ymax >= 3.0
    assert xmin <= trace.array('x').min() and xmax >= trace.array('x').max()


def test_plot_marks_start_end_collisions_target_and_a_few_scans(tmp_path, trace, world):
    figure = plot_trajectory(trace, world, tmp_path / 'trajectory.png', title='box, seed 1')
    axes = figure.axes[0]
    labels = [text.get_text() for text in figure.legends[0].get_texts()]
    assert {'start', 'end', 'collision (1)', 'target: box'} <= set(labels)
    assert axes.get_title() == 'box, seed 1'
    scan_dots = [line for line in axes.lines if line.get_marker() == '.']
    assert len(scan_dots) == SCANS_DRAWN
    crosses = [line for line in axes.lines if line.get_marker() == 'x']
    assert [tuple(line.get_xydata()[0]) for line in crosses] == [(-1.3, 0.0)]
    path = max(axes.collections, key=lambda collection: len(collection.get_segments()))
    assert len(path.get_segments()) == len(trace) - 1
    assert figure.axes[1].get_ylabel() == 'time (s)'


def test_plot_of_an_empty_run_still_draws_the_world(tmp_path, world):
    plot_trajectory(Trace(robot_radius=0.2), world, tmp_path / 'empty.png')
    assert (tmp_path / 'empty.png').read_bytes().startswith(PNG_SIGNATURE)


def test_scan_hits_are_placed_in_the_world_frame_and_skip_no_returns():
    scan = ScanSnapshot(0.0, (1.0, 2.0, math.pi / 2), np.array([1.0, math.inf, 2.0]),
                        -math.pi / 2, math.pi / 2)
    assert scan_hits(scan) == pytest.approx(np.array([[2.0, 2.0], [-1.0, 2.0]]))


def test_spread_evenly_keeps_first_and_last():
    assert spread_evenly(list(range(10)), 4) == [0, 3, 6, 9]
    assert spread_evenly([1, 2], 4) == [1, 2]


def test_plot_draws_what_the_robot_could_hit_and_the_robots_outline(tmp_path, trace, world):
    # A table at (2, -2) whose top (0.7 m) is above the lab robot: the plot shows its four
    # legs, not the top. The robot is a 0.4 x 0.2 m box: its outline, turned by the yaw.
    legs = tuple(Shape('box', 2.0 + sx * 0.4, -2.0 + sy * 0.3, 0.35, size=(0.05, 0.05, 0.7))
                 for sx in (-1, 1) for sy in (-1, 1))
    top = Shape('box', 2.0, -2.0, 0.72, size=(1.0, 0.8, 0.04))
    robot = replace(world.robot, shapes=(Shape('box', 0.0, 0.0, 0.1, size=(0.4, 0.2, 0.2)),))
    world = replace(world, robot=robot, obstacles=world.obstacles + (
        Obstacle('table', 'model', legs + (top,), (2.0, -2.0, 0.0)),))
    axes = plot_trajectory(trace, world, tmp_path / 'trajectory.png').axes[0]
    outlines = [patch.get_xy() for patch in axes.patches if isinstance(patch, Polygon)]
    table_legs = [xy for xy in outlines if np.all(np.abs(xy - (2.0, -2.0)).max(axis=0) < 0.5)]
    assert len(table_legs) == 4
    assert all(np.ptp(xy, axis=0) == pytest.approx((0.05, 0.05)) for xy in table_legs)
    # At the start (1.3, 0) heading -y the robot's 0.4 m length lies along y.
    start = [line.get_xydata() for line in axes.lines if line.get_color() == '#2e7d32'
             and line.get_marker() in ('None', '')]
    assert np.ptp(start[0], axis=0) == pytest.approx((0.2, 0.4))
    assert 0.5 * (start[0].min(axis=0) + start[0].max(axis=0)) == pytest.approx((1.3, 0.0))


def test_a_walled_enclosure_is_drawn_with_its_floor_open():
    # A hexagonal wall (as the TurtleBot3 world's) slices to a polygon with a hole where the
    # robot drives: the patch must paint the wall, not the floor inside it.
    outer = shapely.Polygon([(3 * math.cos(a), 3 * math.sin(a))
                             for a in np.arange(6) * math.pi / 3])
    wall = Footprint('polygon', 0.0, 0.0, polygon=outer.difference(outer.buffer(-0.2)))
    figure = Figure(figsize=(2, 2), dpi=100)
    FigureCanvasAgg(figure)
    axes = figure.add_axes((0, 0, 1, 1))
    axes.set_xlim(-3.2, 3.2)
    axes.set_ylim(-3.2, 3.2)
    axes.add_patch(_patch(wall, facecolor='black', edgecolor='none'))
    figure.canvas.draw()
    pixels = np.asarray(figure.canvas.buffer_rgba())

    def grey_at(x, y):
        column, row = axes.transData.transform((x, y))
        return int(pixels[pixels.shape[0] - 1 - round(row), round(column), 0])

    assert grey_at(0.0, 0.0) == 255  # the floor inside: white
    assert grey_at(2.9, 0.0) == 0    # the wall: painted
