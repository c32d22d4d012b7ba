"""
Tests of simulation.mesh_slice: whatever the lidar sees at the robot's height blocks the robot.

Meshes as modellers ship them, made here with trimesh: a wall that is one sheet of triangles
(open, every face on edge), a box without lid or bottom, a box whose triangles share no
corner (unmerged) and whose faces are doubled, a pipe, at any pose and scale.
"""

import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from sim_bridge.common import paths
from sim_bridge.simulation.geometry import Mesh, Shape, slice_polygon
from sim_bridge.simulation.simulator import Simulator
from sim_bridge.simulation.world import World, WorldError
import trimesh

BAND = (0.005, 0.2)


def sheet(length: float = 2.0, height: float = 1.0) -> trimesh.Trimesh:
    """Return a vertical sheet of two triangles along y at x = 0, from z = 0 up (m)."""
    half = 0.5 * length
    return trimesh.Trimesh([[0.0, -half, 0.0], [0.0, half, 0.0], [0.0, half, height],
                            [0.0, -half, height]], [[0, 1, 2], [0, 2, 3]], process=False)


def open_box() -> trimesh.Trimesh:
    """Return a 1 m cube standing on the floor with its lid and bottom taken off."""
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    box.apply_translation((0.0, 0.0, 0.5))
    sides = np.abs(box.face_normals[:, 2]) < 0.5
    return trimesh.Trimesh(box.vertices, box.faces[sides], process=False)


def unmerged_doubled_box() -> trimesh.Trimesh:
    """Return a 1 m cube on the floor whose faces share no vertex and come twice each."""
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    box.apply_translation((0.0, 0.0, 0.5))
    triangles = np.concatenate((box.triangles, box.triangles[:, ::-1]))
    return trimesh.Trimesh(triangles.reshape(-1, 3), np.arange(3 * len(triangles)).reshape(-1, 3),
                           process=False)


def shape_of(mesh: trimesh.Trimesh, x: float = 0.0, y: float = 0.0, yaw: float = 0.0,
             scale: float = 1.0) -> Shape:
    return Shape('mesh', x, y, 0.0, yaw=yaw,
                 mesh=Mesh(np.asarray(mesh.vertices) * scale, np.asarray(mesh.faces)))


@pytest.mark.parametrize('mesh', [sheet(), open_box(), unmerged_doubled_box()],
                         ids=['sheet', 'open box', 'unmerged doubled box'])
@pytest.mark.parametrize('yaw, scale', [(0.0, 1.0), (0.7, 0.5), (-2.0, 3.0)])
def test_every_face_on_edge_is_in_the_slice(mesh, yaw, scale):
    outline = slice_polygon(shape_of(mesh, 1.0, -2.0, yaw, scale), *BAND)
    # Every corner of the mesh's faces at the band's height lies on or in the outline.
    turn = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    corners = np.asarray(mesh.vertices)[:, :2] * scale @ turn.T + (1.0, -2.0)
    assert shapely.distance(outline, shapely.MultiPoint(corners)) == pytest.approx(0.0, abs=1e-5)
    assert not outline.is_empty and outline.is_valid


def test_a_closed_outline_is_solid_even_with_cracks_and_doubled_faces():
    # The doubled box crosses the section twice at each wall: they count once, so its inside
    # is inside; the open box's walls close the same square.
    for mesh in (unmerged_doubled_box(), open_box()):
        outline = slice_polygon(shape_of(mesh), *BAND)
        assert outline.area == pytest.approx(1.0, rel=1e-2)
        assert shapely.contains_xy(outline, 0.0, 0.0)
    # A crack of 0.3 mm in a wall still closes it.
    cracked = open_box()
    vertices = np.array(cracked.vertices)
    vertices[vertices[:, 0] > 0.0, 0] += 3e-4
    cracked = trimesh.Trimesh(vertices[cracked.faces].reshape(-1, 3),
                              np.arange(3 * len(cracked.faces)).reshape(-1, 3), process=False)
    assert shapely.contains_xy(slice_polygon(shape_of(cracked), *BAND), 0.0, 0.0)


def test_a_pipes_bore_stays_open():
    pipe = trimesh.creation.annulus(0.3, 0.5, 1.0, sections=64)
    pipe.apply_translation((0.0, 0.0, 0.5))
    outline = slice_polygon(shape_of(pipe), *BAND)
    assert not shapely.contains_xy(outline, 0.0, 0.0)
    assert shapely.contains_xy(outline, 0.4, 0.0)


MESH_WALL_WORLD = """<sdf version="1.10"><world name="meshes">
<include><uri>model://mesh_wall</uri><pose>1 0 0 0 0 0</pose></include>
<include><uri>model://turtlebot3_burger</uri><name>burger</name><pose>{x} 0 0 0 0 0</pose>
</include></world></sdf>"""


def write_mesh_wall(folder: Path) -> None:
    """Write a model folder whose only collision is a one-sheet wall (OBJ), 2 m across."""
    (folder / 'mesh_wall' / 'meshes').mkdir(parents=True)
    sheet().export(folder / 'mesh_wall' / 'meshes' / 'wall.obj')
    (folder / 'mesh_wall' / 'model.sdf').write_text(
        '<sdf version="1.6"><model name="mesh_wall"><static>true</static><link name="l">'
        '<collision name="c"><geometry><mesh><uri>model://mesh_wall/meshes/wall.obj</uri>'
        '</mesh></geometry></collision></link></model></sdf>')


def test_a_burger_is_stopped_by_a_wall_made_of_one_mesh_sheet(tmp_path, monkeypatch):
    write_mesh_wall(tmp_path)
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', f'{tmp_path}:{paths.models_dir()}')
    world_file = tmp_path / 'meshes.sdf'
    world_file.write_text(MESH_WALL_WORLD.format(x=0.0))
    simulator = Simulator(World.load(world_file), seed=0)
    assert simulator.scan().ranges[0] == pytest.approx(1.032, abs=0.01)  # lidar 32 mm back
    simulator.set_command(0.2, 0.0)
    for _ in range(1000):
        simulator.step(0.01)
    assert [event.obstacle for event in simulator.collisions] == ['mesh_wall']
    assert simulator.pose[0] < 1.0


def test_a_spawn_on_a_mesh_wall_is_refused_naming_robot_and_wall(tmp_path, monkeypatch):
    write_mesh_wall(tmp_path)
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', f'{tmp_path}:{paths.models_dir()}')
    world_file = tmp_path / 'meshes.sdf'
    world_file.write_text(MESH_WALL_WORLD.format(x=1.0))
    with pytest.raises(WorldError, match="robot 'burger' .* overlaps obstacle "
                                         "'mesh_wall'"):
        World.load(world_file)


def test_a_texture_trimesh_cannot_read_is_one_ignored_item_not_a_traceback(
        tmp_path, monkeypatch, capsys):
    # trimesh logs a texture it cannot load (a missing bump map) as a warning with its
    # traceback, and goes on with the triangles.
    import logging
    import trimesh.exchange.load
    load = trimesh.exchange.load.load

    def load_warning_of_a_texture(*args, **kwargs):
        logging.getLogger('trimesh.exchange.dae').warning('unable to load bumpmap',
                                                          exc_info=FileNotFoundError('x.jpg'))
        return load(*args, **kwargs)
    monkeypatch.setattr(trimesh, 'load', load_warning_of_a_texture)
    write_mesh_wall(tmp_path)
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', f'{tmp_path}:{paths.models_dir()}')
    world_file = tmp_path / 'meshes.sdf'
    world_file.write_text(MESH_WALL_WORLD.format(x=0.0))
    world = World.load(world_file)
    assert 'mesh texture wall.obj' in world.ignored
    assert 'Traceback' not in capsys.readouterr().err
