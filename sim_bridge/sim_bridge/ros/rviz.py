"""
What RViz shows of a simulated world: the robot's ``robot_description`` and the obstacles.

The bridge publishes both once, latched (transient local), as Gazebo's usual companions do:
``/robot_description`` (std_msgs/String, as robot_state_publisher publishes it; RViz's
RobotModel display reads it) and ``/world_markers`` (visualization_msgs/MarkerArray in the
odometry frame, where RViz's fixed frame is in ``params/lab.rviz``). A URDF or xacro robot is
described by its own file, xacro-expanded, as given. An SDF robot (the lab robot, a Gazebo
model folder) gets the URDF robot_state_publisher would need: its base link holding every
collision shape as a visual (a mesh as its bounding box: a URDF names mesh files, the
simulator holds triangles), a link per joint below it and the lidar's link, fixed joints at
the poses the bridge's static TF gives. An obstacle's mesh is a triangle list marker.
"""

from xml.etree import ElementTree

import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from sim_bridge.simulation.geometry import quaternion_from_euler, Shape
from sim_bridge.simulation.sdf_frames import place, relative_pose
from sim_bridge.simulation.sdf_model import Model
from sim_bridge.simulation.sdf_values import Pose6, ZERO_POSE
from sim_bridge.simulation.urdf import expanded_urdf, is_urdf_file
from sim_bridge.simulation.world import World
from std_msgs.msg import String
from visualization_msgs.msg import Marker, MarkerArray

#: Latched: a display started later still gets the one message.
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: RGBA (0..1) of the obstacles' markers and the robot's visuals.
OBSTACLE_RGBA = (0.55, 0.55, 0.6, 1.0)
MARKER_TYPES = {'box': Marker.CUBE, 'cylinder': Marker.CYLINDER, 'capsule': Marker.CYLINDER,
                'sphere': Marker.SPHERE, 'ellipsoid': Marker.SPHERE, 'mesh': Marker.TRIANGLE_LIST}


def shape_extent(shape: Shape) -> tuple[float, float, float]:
    """Return a shape's full size along its own x, y, z (m): its bounding box's edges."""
    if shape.kind in ('box', 'ellipsoid'):
        return tuple(float(value) for value in shape.size)
    if shape.kind == 'sphere':
        return (2.0 * shape.radius,) * 3
    if shape.kind == 'cylinder':
        return (2.0 * shape.radius, 2.0 * shape.radius, shape.length)
    if shape.kind == 'capsule':
        return (2.0 * shape.radius, 2.0 * shape.radius, shape.length + 2.0 * shape.radius)
    vertices = shape.mesh.vertices
    return tuple(float(value) for value in np.ptp(vertices, axis=0)) if len(vertices) else (
        0.0, 0.0, 0.0)


def shape_pose(shape: Shape) -> Pose6:
    """Return a shape's pose (m, rad) in the frame it is given in."""
    return (shape.x, shape.y, shape.z, shape.roll, shape.pitch, shape.yaw)


def _origin(parent: ElementTree.Element, pose: Pose6) -> None:
    ElementTree.SubElement(parent, 'origin', xyz=' '.join(f'{value:.6g}' for value in pose[:3]),
                           rpy=' '.join(f'{value:.6g}' for value in pose[3:]))


def _visual(link: ElementTree.Element, shape: Shape, pose: Pose6) -> None:
    """Add ``shape`` at ``pose`` in the link's frame as a visual of ``link``."""
    visual = ElementTree.SubElement(link, 'visual')
    if shape.kind == 'mesh':  # its bounding box, centred on the triangles
        vertices = np.asarray(shape.mesh.vertices)
        centre = vertices.min(axis=0) + np.ptp(vertices, axis=0) / 2.0
        pose = shape_pose(place(Shape('box', *map(float, centre)), pose))
    _origin(visual, pose)
    geometry = ElementTree.SubElement(visual, 'geometry')
    if shape.kind in ('cylinder', 'capsule'):
        ElementTree.SubElement(geometry, 'cylinder', radius=f'{shape.radius:.6g}',
                               length=f'{shape_extent(shape)[2]:.6g}')
    elif shape.kind == 'sphere':
        ElementTree.SubElement(geometry, 'sphere', radius=f'{shape.radius:.6g}')
    else:
        ElementTree.SubElement(geometry, 'box', size=' '.join(
            f'{value:.6g}' for value in shape_extent(shape)))


def sdf_robot_urdf(model: Model, base: str, laser: str, lidar_pose: Pose6) -> str:
    """
    Return the URDF of an SDF robot for robot_state_publisher (see the module).

    ``base`` and ``laser`` are the bridge's frames, ``lidar_pose`` the lidar's pose in the
    model frame (m, rad).
    """
    joints = [joint for joint in model.joints if joint[1] != base]
    base_pose = next((parent_pose for parent, _, parent_pose, _ in joints if parent == base),
                     ZERO_POSE)
    robot = ElementTree.Element('robot', name=model.name)
    base_link = ElementTree.SubElement(robot, 'link', name=base)
    for shape in model.shapes:
        _visual(base_link, shape, relative_pose(base_pose, shape_pose(shape)))
    links = {base}
    children = [(parent, child, parent_pose, lidar_pose if child == laser else child_pose)
                for parent, child, parent_pose, child_pose in joints]
    if laser not in {child for _, child, _, _ in children}:
        children.append((base, laser, base_pose, lidar_pose))
    for parent, child, parent_pose, child_pose in children:
        if child in links:
            continue
        links.add(child)
        ElementTree.SubElement(robot, 'link', name=child)
        joint = ElementTree.SubElement(robot, 'joint', name=f'{parent}_to_{child}', type='fixed')
        ElementTree.SubElement(joint, 'parent', link=parent)
        ElementTree.SubElement(joint, 'child', link=child)
        _origin(joint, relative_pose(parent_pose, child_pose))
    return ElementTree.tostring(robot, encoding='unicode')


def robot_description(model: Model, base: str, laser: str, lidar_pose: Pose6) -> str:
    """Return the robot's URDF: a URDF or xacro robot's own, else :func:`sdf_robot_urdf`'s."""
    if is_urdf_file(model.path):
        return expanded_urdf(model.path)
    return sdf_robot_urdf(model, base, laser, lidar_pose)


def obstacle_marker(shape: Shape, index: int, origin: Pose6, frame: str) -> Marker:
    """Return obstacle ``shape`` (world frame) as marker ``index`` in ``frame`` at ``origin``."""
    marker = Marker(ns='obstacles', id=index, type=MARKER_TYPES[shape.kind],
                    action=Marker.ADD)
    marker.header.frame_id = frame
    x, y, z, roll, pitch, yaw = relative_pose(origin, shape_pose(shape))
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = x, y, z
    rotation = marker.pose.orientation
    rotation.x, rotation.y, rotation.z, rotation.w = quaternion_from_euler(roll, pitch, yaw)
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = OBSTACLE_RGBA
    if shape.kind == 'mesh':
        marker.scale.x = marker.scale.y = marker.scale.z = 1.0
        for vertex in np.asarray(shape.mesh.vertices)[np.asarray(shape.mesh.faces).ravel()]:
            point = type(marker.pose.position)()
            point.x, point.y, point.z = (float(value) for value in vertex)
            marker.points.append(point)
    else:
        marker.scale.x, marker.scale.y, marker.scale.z = shape_extent(shape)
    return marker


def world_markers(world: World, origin: Pose6, frame: str) -> MarkerArray:
    """Return every obstacle of ``world`` as markers in ``frame``, whose pose is ``origin``."""
    return MarkerArray(markers=[obstacle_marker(shape, index, origin, frame)
                                for index, shape in enumerate(world.shapes())])


def publish_scene(node: Node, world: World, frames: dict[str, str], origin: Pose6,
                  lidar_pose: Pose6) -> None:
    """Publish ``/robot_description`` and ``/world_markers`` once, latched, from ``node``."""
    description = robot_description(world.robot, frames['base_link'], frames['laser'],
                                    lidar_pose)
    descriptions = node.create_publisher(String, 'robot_description', LATCHED)
    descriptions.publish(String(data=description))
    markers = node.create_publisher(MarkerArray, 'world_markers', LATCHED)
    markers.publish(world_markers(world, origin, frames['odom']))
