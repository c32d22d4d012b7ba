"""
Poses and frames of SDF models: composing poses and SDF 1.7's ``relative_to`` frames.

A pose is x, y, z (m), roll, pitch, yaw (rad), fixed axes X-Y-Z (:data:`.sdf_values.Pose6`).
"""

import xml.etree.ElementTree as ElementTree

import numpy as np
from sim_bridge.simulation.geometry import (
    euler_from_matrix, pose_matrix, rotation_matrix, Shape)
from sim_bridge.simulation.sdf_values import label, Pose6, SdfValues, ZERO_POSE


def compose(parent: Pose6, child: Pose6) -> Pose6:
    """Return the pose of ``child``, given in ``parent``'s frame, in parent's parent (m, rad)."""
    matrix = pose_matrix(*parent) @ pose_matrix(*child)
    return (float(matrix[0, 3]), float(matrix[1, 3]), float(matrix[2, 3]),
            *euler_from_matrix(matrix))


def relative_pose(parent: Pose6, child: Pose6) -> Pose6:
    """Return ``child`` (a pose in some frame) in the frame of ``parent`` (same frame)."""
    rotation = rotation_matrix(*parent[3:]).T
    position = rotation @ (np.asarray(child[:3]) - parent[:3])
    return (*map(float, position), *euler_from_matrix(rotation @ rotation_matrix(*child[3:])))


def place(shape: Shape, pose: Pose6) -> Shape:
    """Return ``shape``, given in a frame at ``pose`` (m, rad), in that frame's parent."""
    x, y, z, roll, pitch, yaw = pose
    return shape.placed(x, y, z, yaw, roll, pitch)


class Frames:
    """
    The named frames of one model (links, ``<frame>``s, joints, nested models) for poses.

    SDF 1.7's ``relative_to``: a link's pose is relative to the model unless it names another
    frame; a collision's or sensor's is relative to its link; a joint's to its child link; a
    ``<frame>``'s to what it is ``attached_to``. ``__model__`` is the model frame.
    """

    def __init__(self, reader: SdfValues, model: ElementTree.Element, where: str) -> None:
        self.reader = reader
        self.where = where
        self.elements: dict[str, tuple[ElementTree.Element, str | None]] = {}
        for child in model:
            name = child.get('name')
            if name and child.tag in ('link', 'model', 'include', 'frame'):
                self.elements[name] = (child, child.get('attached_to') or None)
            elif name and child.tag == 'joint':
                self.elements[name] = (child, (child.findtext('child') or '').strip() or None)
        self.poses: dict[str, Pose6] = {'__model__': ZERO_POSE}
        self.resolving: set[str] = set()

    def pose_of(self, name: str | None) -> Pose6:
        """Return the pose (m, rad) of the frame ``name`` in the model frame."""
        if name in self.poses:
            return self.poses[name]
        if name not in self.elements or name in self.resolving:
            problem = 'is a loop of relative_to' if name in self.resolving else 'names no frame'
            raise self.reader.error(self.where, f'relative_to="{name}" {problem} of this model '
                                    '(links, frames, joints, nested models or __model__)')
        self.resolving.add(name)
        element, default_parent = self.elements[name]
        at = f'{self.where}/{label(element)}'
        self.poses[name] = self.resolve(element, at, parent=default_parent)
        self.resolving.discard(name)
        return self.poses[name]

    def resolve(self, element: ElementTree.Element, where: str, parent: str | None = None,
                link: ElementTree.Element | None = None) -> Pose6:
        """Return an element's pose in the model frame, relative to its parent by default."""
        own = self.reader.pose(element, where)
        pose = element.find('pose')
        relative_to = (pose.get('relative_to') or '').strip() if pose is not None else ''
        if relative_to:
            base = self.pose_of(relative_to)
        elif link is not None:
            base = self.resolve(link, self.where)
        elif parent:
            base = self.pose_of(parent)
        else:
            return own
        return compose(base, own)
