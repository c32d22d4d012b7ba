"""
The robot in its world in 3-D, as a simulator window shows it, rendered off-screen on the CPU.

A video's 3-D pane: the world's shapes and the robot (its collision shapes as one mesh, as the
pybullet window shows them) in a pybullet client of its own in DIRECT mode, seen by a camera
that follows the robot from behind and above, rendered by pybullet's TinyRenderer
(``getCameraImage`` with ``ER_TINY_RENDERER``: software rendering, no display, no GPU).
"""

import math

import numpy as np
from PIL import Image
from sim_bridge.simulation.bullet import pybullet

from sim_bridge.simulation.lidar import build_scene
from sim_bridge.simulation.viewer import ROBOT_COLOUR, robot_mesh

#: The camera: this far (m) behind the robot, this high (m) above the floor, looking at a point
#: this far (m) ahead of it, with this vertical field of view (deg).
CAMERA_BEHIND = 2.2
CAMERA_HEIGHT = 1.6
CAMERA_AHEAD = 0.8
FIELD_OF_VIEW_DEG = 60.0
#: Where the light comes from (a direction, world frame) and the sky's colour (RGB).
LIGHT_DIRECTION = (0.4, 0.6, 1.0)
SKY = (200, 215, 230)


class View3D:
    """
    Render ``world`` (a :class:`~sim_bridge.simulation.world.World`) with its robot at a pose.

    ``size`` (px) of each image. :meth:`close` (or the end of a ``with``) frees the client.
    """

    def __init__(self, world, size: tuple[int, int]) -> None:
        self.size = size
        self.client = pybullet.connect(pybullet.DIRECT)
        if self.client < 0:
            raise RuntimeError('cannot start pybullet for the 3-D view')
        build_scene(self.client, world.shapes(), floor_size=world.floor_size, visuals=True)
        vertices, faces = robot_mesh(world.robot.shapes)
        visual = pybullet.createVisualShape(pybullet.GEOM_MESH, vertices=vertices.tolist(),
                                            indices=faces.ravel().tolist(),
                                            rgbaColor=ROBOT_COLOUR, physicsClientId=self.client)
        self.robot = pybullet.createMultiBody(0.0, -1, visual, physicsClientId=self.client)
        self.projection = pybullet.computeProjectionMatrixFOV(
            FIELD_OF_VIEW_DEG, size[0] / size[1], 0.05, 50.0, physicsClientId=self.client)

    def image(self, pose: tuple[float, float, float]) -> Image.Image:
        """Return the view with the robot at ``pose`` (x m, y m, yaw rad), as an RGB image."""
        x, y, yaw = pose
        pybullet.resetBasePositionAndOrientation(
            self.robot, (x, y, 0.0), pybullet.getQuaternionFromEuler((0.0, 0.0, yaw)),
            physicsClientId=self.client)
        heading = np.array([math.cos(yaw), math.sin(yaw)])
        eye = (*(np.array([x, y]) - CAMERA_BEHIND * heading), CAMERA_HEIGHT)
        target = (*(np.array([x, y]) + CAMERA_AHEAD * heading), 0.0)
        view = pybullet.computeViewMatrix(eye, target, (0.0, 0.0, 1.0),
                                          physicsClientId=self.client)
        width, height = self.size
        _, _, rgba, _, segmentation = pybullet.getCameraImage(
            width, height, view, self.projection, renderer=pybullet.ER_TINY_RENDERER,
            lightDirection=LIGHT_DIRECTION, shadow=0, physicsClientId=self.client)
        pixels = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[..., :3].copy()
        pixels[np.asarray(segmentation).reshape(height, width) < 0] = SKY
        return Image.fromarray(pixels)

    def close(self) -> None:
        """Disconnect the pybullet client (once)."""
        if self.client >= 0:
            pybullet.disconnect(physicsClientId=self.client)
            self.client = -1

    def __enter__(self) -> 'View3D':
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
