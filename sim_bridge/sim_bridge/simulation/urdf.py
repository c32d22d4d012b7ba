"""
URDF and xacro robots, read as ``ros_gz_sim create -topic robot_description`` spawns them.

The usual ROS 2 route into Gazebo: a ``robot_description`` (a URDF, often written as xacro)
that Gazebo converts to SDF. :func:`urdf_to_sdf` does the same, and
:func:`~.sdf.load_model` reads the result, in three steps:

1. xacro (PyPI's ``xacro``) expands the file, whatever its suffix: TurtleBot3's own
   ``turtlebot3_burger.urdf`` uses ``xacro:arg``; a plain URDF comes out as it went in;
2. urdfdom-py (``urdf_parser_py``) reads links, joints and collisions; each link's pose in the
   robot's frame is the chain of joint origins from the root link, at joint positions 0;
3. the result is written as an SDF ``<model>`` (links at those poses, collisions at their
   origins, ``<gazebo reference="LINK">`` contents inside that link, ``<gazebo>`` contents in
   the model) and read by :func:`~.sdf.parse_model`, so the lidar (Classic
   ``libgazebo_ros_ray_sensor.so`` or Sim ``gpu_lidar``) and the diff drive (Classic
   ``libgazebo_ros_diff_drive.so`` or Sim ``gz-sim-diff-drive-system``) are read as in SDF.

xacro's ``$(find PKG)`` and mesh ``filename`` s ``package://PKG/path`` name the package folder
:func:`~.ros_packages.find_package` finds as ROS tools do (``AMENT_PREFIX_PATH``,
``ROS_PACKAGE_PATH``, the file's own package tree, the model path), so a ROS 1 description
(``$(find turtlebot3_description)``) expands where no ROS 2 workspace is sourced; xacro's own
``$(find)`` is kept and only its package lookup answered. ``model://`` is found on the model
path; ``file://`` and paths relative to the URDF's folder as they are. Units: m, rad.
"""

from contextlib import contextmanager
from pathlib import Path
from urllib.parse import unquote, urlparse
import xml.etree.ElementTree as ElementTree

from sim_bridge.common import paths
from sim_bridge.simulation.ros_packages import find_package, PackageNotFoundError
from sim_bridge.simulation.sdf_frames import compose
from sim_bridge.simulation.sdf_values import SdfError

#: File suffixes read as URDF (xacro first).
URDF_SUFFIXES = ('.urdf', '.xacro')
Pose6 = tuple[float, float, float, float, float, float]


def is_urdf_file(path: Path) -> bool:
    """Return True for a file named like a URDF or xacro robot (``.urdf``, ``.urdf.xacro``)."""
    return path.suffix.lower() in URDF_SUFFIXES


def expanded_urdf(path: Path) -> str:
    """Return the URDF text of a URDF or xacro robot file, expanded as for spawning it."""
    return _read(Path(path))[1]


def urdf_to_sdf(path: Path) -> str:
    """
    Return the SDF text of the robot of a URDF or xacro file, as Gazebo converts it to spawn it.

    Raises :class:`~.sdf_values.SdfError` naming the file for one that xacro or the URDF reader
    refuses, or a mesh that cannot be found.
    """
    path = Path(path)
    robot, text = _read(path)
    sdf = ElementTree.Element('sdf', version='1.9')
    model = ElementTree.SubElement(sdf, 'model', name=robot.name)
    extensions = _gazebo_extensions(ElementTree.fromstring(text))
    poses = _link_poses(robot, path)
    for link in robot.links:
        element = ElementTree.SubElement(model, 'link', name=link.name)
        _pose(element, poses[link.name])
        for index, collision in enumerate(link.collisions):
            element.append(_collision(collision, f'{link.name}_collision_{index}', path))
        for extension in extensions.get(link.name, []):
            element.extend(extension)
    for joint in robot.joints:
        element = ElementTree.SubElement(model, 'joint', name=joint.name, type=joint.type)
        ElementTree.SubElement(element, 'parent').text = joint.parent
        ElementTree.SubElement(element, 'child').text = joint.child
    for extension in extensions.get(None, []):
        model.extend(extension)
    return ElementTree.tostring(sdf, encoding='unicode')


def _read(path: Path):
    """Return (urdf_parser_py's robot, the expanded URDF text) of ``path``."""
    import xacro
    from urdf_parser_py import urdf
    from urdf_parser_py.xml_reflection import core
    try:
        with _packages_found_from(path):
            text = xacro.process_file(str(path)).toxml()
    except Exception as error:  # xacro raises its own errors, OSError and XML errors
        # xacro wraps what $(find) raised in "<class ...>: message message": the message once
        cause = getattr(error, 'exc', None)
        why = cause if isinstance(cause, PackageNotFoundError) else error
        raise SdfError(f'{path}: xacro cannot expand it: {why}') from None
    complaints = []
    core.on_error = complaints.append  # urdf_parser_py's hook; its default prints to stderr
    try:
        robot = urdf.URDF.from_xml_string(text)
    except Exception as error:  # urdf_parser_py raises many kinds on a broken file
        raise SdfError(f'{path}: not a URDF robot: {error}') from None
    finally:
        core.on_error = core.on_error_stderr
    if not robot.links:
        raise SdfError(f'{path}: <robot name="{robot.name}">: has no <link>')
    return robot, text


@contextmanager
def _packages_found_from(path: Path):
    """
    Let xacro's ``$(find PKG)`` answer with :func:`~.ros_packages.find_package` for ``path``.

    xacro resolves ``$(find)`` itself and asks ``substitution_args._eval_find`` for the folder
    (ament's share directory, which needs a sourced ROS 2 workspace): that hook is answered
    while the file is expanded, and restored after.
    """
    from xacro import substitution_args
    ament_find = substitution_args._eval_find
    substitution_args._eval_find = lambda package: str(find_package(package, path))
    try:
        yield
    finally:
        substitution_args._eval_find = ament_find


def _gazebo_extensions(root: ElementTree.Element) -> dict[str | None, list]:
    """Return the ``<gazebo>`` elements by the link they reference (None: the model's)."""
    extensions: dict[str | None, list] = {}
    for element in root.findall('gazebo'):
        extensions.setdefault(element.get('reference'), []).append(element)
    return extensions


def _link_poses(robot, path: Path) -> dict[str, Pose6]:
    """Return each link's pose in the root link's frame, joints at position 0."""
    parents = {joint.child: joint for joint in robot.joints}
    roots = [link.name for link in robot.links if link.name not in parents]
    if len(roots) != 1:
        raise SdfError(f'{path}: <robot name="{robot.name}">: needs exactly one root link '
                       f'(one that is no joint\'s child), found {roots or "none"}')
    poses: dict[str, Pose6] = {roots[0]: (0.0,) * 6}

    def pose_of(name: str, chain: tuple[str, ...] = ()) -> Pose6:
        if name not in poses:
            if name in chain:
                raise SdfError(f'{path}: the joints loop through link {name}')
            joint = parents[name]
            poses[name] = compose(pose_of(joint.parent, chain + (name,)),
                                  _origin(joint.origin))
        return poses[name]
    for link in robot.links:
        pose_of(link.name)
    return poses


def _origin(origin) -> Pose6:
    """Return a URDF ``<origin>`` (None: the identity) as (x, y, z, roll, pitch, yaw)."""
    if origin is None:
        return (0.0,) * 6
    xyz = origin.xyz if origin.xyz is not None else (0.0, 0.0, 0.0)
    rpy = origin.rpy if origin.rpy is not None else (0.0, 0.0, 0.0)
    return tuple(float(value) for value in (*xyz, *rpy))


def _pose(element: ElementTree.Element, pose: Pose6) -> None:
    ElementTree.SubElement(element, 'pose').text = ' '.join(repr(value) for value in pose)


def _collision(collision, name: str, path: Path) -> ElementTree.Element:
    """Return a URDF ``<collision>`` as SDF (a mesh's file found and given by its path)."""
    element = ElementTree.Element('collision', name=getattr(collision, 'name', None) or name)
    _pose(element, _origin(collision.origin))
    geometry = ElementTree.SubElement(element, 'geometry')
    shape = collision.geometry
    kind = type(shape).__name__
    if kind == 'Box':
        box = ElementTree.SubElement(geometry, 'box')
        ElementTree.SubElement(box, 'size').text = ' '.join(map(repr, shape.size))
    elif kind in ('Cylinder', 'Sphere'):
        primitive = ElementTree.SubElement(geometry, kind.lower())
        ElementTree.SubElement(primitive, 'radius').text = repr(shape.radius)
        if kind == 'Cylinder':
            ElementTree.SubElement(primitive, 'length').text = repr(shape.length)
    elif kind == 'Mesh':
        mesh = ElementTree.SubElement(geometry, 'mesh')
        ElementTree.SubElement(mesh, 'uri').text = str(mesh_file(shape.filename, path))
        if shape.scale is not None:
            scale = shape.scale if len(shape.scale) == 3 else [shape.scale[0]] * 3
            ElementTree.SubElement(mesh, 'scale').text = ' '.join(map(repr, scale))
    else:
        raise SdfError(f'{path}: <collision name="{name}">: no geometry (box, cylinder, '
                       'sphere or mesh)')
    return element


def mesh_file(uri: str, urdf_path: Path) -> Path:
    """
    Return the file a URDF mesh ``filename`` names; SdfError naming where it was looked for.

    ``package://PKG/...`` and ``model://PKG/...`` are looked up as the module text says.
    """
    parsed = urlparse(uri)
    if parsed.scheme in ('package', 'model'):
        relative = unquote(parsed.path.lstrip('/'))
        roots = _package_roots(parsed.netloc, urdf_path)
        for root in roots:
            if (root / relative).is_file():
                return root / relative
        looked = ', '.join(str(root) for root in roots) or 'no folder of that package found'
        raise SdfError(f'{urdf_path}: mesh {uri}: not found (looked in {looked}); put the '
                       f'package {parsed.netloc!r} on AMENT_PREFIX_PATH (its share/'
                       f'{parsed.netloc}), ROS_PACKAGE_PATH or GZ_SIM_RESOURCE_PATH')
    if parsed.scheme == 'file':
        return Path(unquote(parsed.path))
    if parsed.scheme:
        raise SdfError(f'{urdf_path}: mesh {uri}: unsupported URI; use package://, model://, '
                       'file:// or a path')
    return urdf_path.parent / uri


def _package_roots(package: str, urdf_path: Path) -> list[Path]:
    """Return the folders a ROS package or model named ``package`` may be, first first."""
    try:
        roots = [find_package(package, urdf_path)]
    except FileNotFoundError:
        roots = []
    roots += [folder / package for folder in paths.model_search_path()]
    return list(dict.fromkeys(roots))
