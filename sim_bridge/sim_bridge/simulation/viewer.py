"""
The pybullet window of a simulator run with ``gui``: drawing only, no physics.

A visual-only robot body (rays pass through it), the robot's collision shapes as one triangle
mesh (any shape: rolled wheels, meshes), follows the simulated pose, a top-down camera
follows the robot, and the lidar's rays can be drawn as lines: green to a hit, grey for no
return.
"""

from collections.abc import Sequence
import math

import numpy as np
from sim_bridge.simulation.bullet import pybullet
from sim_bridge.simulation.geometry import Shape, triangulate

ROBOT_COLOUR = (0.1, 0.3, 0.8, 1.0)
HIT_COLOUR = (0.1, 0.7, 0.1)
MISS_COLOUR = (0.6, 0.6, 0.6)
#: At most this many rays are drawn per scan (every n-th beam of a dense lidar).
MAX_DRAWN_RAYS = 72
#: Camera height above the floor (m) and pitch (deg; −90 is straight down, which pybullet's
#: camera cannot take exactly).
CAMERA_DISTANCE = 6.0
CAMERA_PITCH_DEG = -89.0


def drawn_beams(beams: int) -> np.ndarray:
    """Return the indices of the beams to draw: all of them, or every n-th of a dense lidar."""
    return np.arange(0, beams, max(1, math.ceil(beams / MAX_DRAWN_RAYS)))


def robot_mesh(shapes: Sequence[Shape]) -> tuple[np.ndarray, np.ndarray]:
    """Return one triangle mesh, (V, 3) vertices (m) and (F, 3) indices, of all ``shapes``."""
    vertices, faces, count = [], [], 0
    for shape in shapes:
        shape_vertices, shape_faces = triangulate(shape)
        vertices.append(shape_vertices @ shape.rotation().T + (shape.x, shape.y, shape.z))
        faces.append(shape_faces + count)
        count += len(shape_vertices)
    return np.vstack(vertices), np.vstack(faces)


class Viewer:
    """
    Show a robot of collision ``shapes`` (its base frame, m) in the pybullet window of ``client``.

    ``draw_rays`` draws each scan handed to :meth:`show_scan`.
    """

    def __init__(self, client: int, shapes: Sequence[Shape], draw_rays: bool = False):
        self.client = client
        self.draw_rays = draw_rays
        # The side panels (pybullet's synthetic camera previews) only hide the world.
        pybullet.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0, physicsClientId=client)
        self.ray_items: list[int] = []
        vertices, faces = robot_mesh(shapes)
        visual = pybullet.createVisualShape(pybullet.GEOM_MESH, vertices=vertices.tolist(),
                                            indices=faces.ravel().tolist(),
                                            rgbaColor=ROBOT_COLOUR, physicsClientId=client)
        self.robot_body = pybullet.createMultiBody(0.0, -1, visual, physicsClientId=client)

    def show_robot(self, pose: tuple[float, float, float]) -> None:
        """Move the robot to ``pose`` (x m, y m, yaw rad) and the camera above it."""
        x, y, yaw = pose
        pybullet.resetBasePositionAndOrientation(
            self.robot_body, (x, y, 0.0), pybullet.getQuaternionFromEuler((0.0, 0.0, yaw)),
            physicsClientId=self.client)
        pybullet.resetDebugVisualizerCamera(CAMERA_DISTANCE, 0.0, CAMERA_PITCH_DEG, (x, y, 0.0),
                                            physicsClientId=self.client)

    def show_scan(self, starts: np.ndarray, ends: np.ndarray, hits: np.ndarray) -> None:
        """
        Draw rays from ``starts`` to ``ends`` ((N, 3) arrays, m, world frame).

        ``hits`` (N booleans) tells which rays found a surface; each drawn line replaces the
        previous scan's, so the window shows the latest scan only.
        """
        if not self.draw_rays:
            return
        for number, index in enumerate(drawn_beams(len(starts))):
            if number == len(self.ray_items):
                self.ray_items.append(-1)
            self.ray_items[number] = pybullet.addUserDebugLine(
                starts[index], ends[index], HIT_COLOUR if hits[index] else MISS_COLOUR,
                lineWidth=1.0, replaceItemUniqueId=self.ray_items[number],
                physicsClientId=self.client)
