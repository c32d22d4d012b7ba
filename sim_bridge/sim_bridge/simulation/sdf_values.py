"""
SDF values as the model reader reads them: numbers, vectors, booleans and ``<pose>`` elements.

:class:`SdfValues` is the base of the SDF reader's parts (:mod:`.sdf`, :mod:`.sdf_lookup`,
:mod:`.sdf_geometry`, :mod:`.sdf_lidar`): it keeps the file read for its error messages
(:class:`SdfError`, naming the file and the element path) and parses the text of elements.
A ``<pose>`` is ``x y z roll pitch yaw`` (m, rad; degrees with ``degrees="true"``).
"""

import math
from pathlib import Path
import xml.etree.ElementTree as ElementTree

from sim_bridge.simulation.xml_text import parse_xml, XmlError

#: A pose: x, y, z (m), roll, pitch, yaw (rad), fixed axes X-Y-Z.

Pose6 = tuple[float, float, float, float, float, float]
ZERO_POSE: Pose6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class SdfError(ValueError):
    """A model file the simulator cannot use; the message names the file and the element."""


def parse_sdf_xml(text: str, path: Path) -> ElementTree.Element:
    """Return the root element of the XML ``text`` read from ``path``; SdfError when unreadable."""
    try:
        return parse_xml(text, path)
    except XmlError as error:
        raise SdfError(str(error)) from None


def label(element: ElementTree.Element) -> str:
    """Return an element as an error message names it, e.g. ``<link name="base">``."""
    name = element.get('name')
    return f'<{element.tag} name="{name}">' if name is not None else f'<{element.tag}>'


class SdfValues:
    """Parses the values of one SDF file, keeping the file name for error messages."""

    def __init__(self, path: Path, world_folder: Path | None) -> None:
        self.path = path
        self.world_folder = world_folder

    def error(self, where: str, problem: str) -> SdfError:
        return SdfError(f'{self.path}: {where}: {problem}')

    def children(self, element: ElementTree.Element, where: str,
                 fields: dict[str, str]) -> dict[str, float]:
        """Return {field: number} for each child element ``fields`` maps to a field name."""
        return {name: self.number(element, tag, where) for tag, name in fields.items()
                if element.find(tag) is not None}

    def pose(self, element: ElementTree.Element, where: str) -> Pose6:
        """Return an element's own ``<pose>`` numbers (m, rad), ZERO_POSE when it has none."""
        pose = element.find('pose')
        if pose is None:
            return ZERO_POSE
        pose_where = f'{where}/<pose>'
        if pose.get('rotation_format', 'euler_rpy') != 'euler_rpy':
            raise self.error(pose_where, 'only rotation_format="euler_rpy" is supported')
        values = self.numbers(pose.text, pose_where, 6)
        if pose.get('degrees', 'false').strip().lower() in ('true', '1'):
            values = values[:3] + tuple(math.radians(angle) for angle in values[3:])
        return values

    def numbers(self, text: str | None, where: str, count: int) -> tuple[float, ...]:
        parts = (text or '').split()
        try:
            values = tuple(float(part) for part in parts)
        except ValueError:
            values = ()
        if len(values) != count or not all(math.isfinite(value) for value in values):
            raise self.error(where, f'must be {count} finite numbers, got {(text or "")!r}')
        return values

    def number(self, parent: ElementTree.Element, tag: str, where: str) -> float:
        return self.numbers(parent.findtext(tag), f'{where}/<{tag}>', 1)[0]

    def integer(self, parent: ElementTree.Element, tag: str, where: str) -> int:
        text = (parent.findtext(tag) or '').strip()
        if not text.isdigit() or int(text) < 1:
            raise self.error(f'{where}/<{tag}>', f'must be a positive integer, got {text!r}')
        return int(text)

    def positive(self, parent: ElementTree.Element, tag: str, where: str,
                 default: float | None = None) -> float:
        """Return a positive number; ``default`` (SDF's) when the element is missing."""
        if parent.find(tag) is None:
            if default is not None:
                return default
            raise self.error(f'{where}/<{tag}>', 'is missing')
        value = self.number(parent, tag, where)
        if value <= 0.0:
            raise self.error(f'{where}/<{tag}>', f'must be positive, got {value}')
        return value

    def vector(self, parent: ElementTree.Element, tag: str, where: str,
               count: int) -> tuple[float, ...]:
        if parent.find(tag) is None:
            raise self.error(f'{where}/<{tag}>', 'is missing')
        return self.numbers(parent.findtext(tag), f'{where}/<{tag}>', count)

    def boolean(self, element: ElementTree.Element | None, where: str, default: bool) -> bool:
        if element is None:
            return default
        text = (element.text or '').strip().lower()
        if text in ('true', '1'):
            return True
        if text in ('false', '0'):
            return False
        raise self.error(where, f'must be true or false, got {text!r}')
