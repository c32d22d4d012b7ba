"""
Find a ROS package's folder as ROS tools do: xacro's ``$(find PKG)`` and ``package://PKG/``.

A package named ``PKG`` is looked for, first match wins:

1. ROS 2's install prefixes: ``share/PKG`` under each ``AMENT_PREFIX_PATH`` entry (what
   ament_index_python's ``get_package_share_directory``, and so ROS 2's xacro, answers);
2. ROS 1's ``ROS_PACKAGE_PATH``: each folder crawled as rospack crawls it: a folder holding a
   ``package.xml`` is a package, named by its ``<name>``, and is not searched further; folders
   holding ``CATKIN_IGNORE``, ``COLCON_IGNORE`` or ``AMENT_IGNORE``, and hidden ones, are
   skipped;
3. the file's own package tree: the folders above the file that hold a ``package.xml`` naming
   ``PKG`` (a description package's xacro names its own package), then the workspace folder
   holding the file's package, crawled as above (its sibling packages);
4. Gazebo's model path (:func:`~sim_bridge.common.paths.model_search_path`): a ``PKG`` folder
   on it, where ros_gz puts packages' share folders for ``model://``.

A source package's folder holds what its install's ``share/PKG`` does (``urdf/``, ``meshes/``),
so ROS 1's answer (the source folder) and ROS 2's (the share folder) name the same files.
"""

from collections.abc import Iterator
import os
from pathlib import Path
import xml.etree.ElementTree as ElementTree

from sim_bridge.common import paths

#: Files that make rospack and colcon skip the folder holding them.
IGNORE_MARKERS = ('CATKIN_IGNORE', 'COLCON_IGNORE', 'AMENT_IGNORE')
#: How many folders deep below a search root a package is looked for.
MAX_CRAWL_DEPTH = 6
#: How many folders one crawl reads at most (a ROS_PACKAGE_PATH naming / stays quick).
MAX_CRAWL_FOLDERS = 20000


class PackageNotFoundError(FileNotFoundError):
    """A ROS package found nowhere; says where it was looked for and what to set."""


def package_name(folder: Path) -> str | None:
    """Return the ``<name>`` of the ``package.xml`` in ``folder``, None when it has none."""
    try:
        root = ElementTree.parse(folder / 'package.xml').getroot()
    except (OSError, ElementTree.ParseError):
        return None
    return (root.findtext('name') or '').strip() or None


def crawl(root: Path, name: str) -> Path | None:
    """Return the folder of package ``name`` below ``root`` as rospack finds it, or None."""
    root_depth = len(root.parts)
    read = 0
    for folder, subfolders, files in os.walk(root):
        read += 1
        here = Path(folder)
        if read > MAX_CRAWL_FOLDERS or any(marker in files for marker in IGNORE_MARKERS):
            subfolders[:] = []
            continue
        if 'package.xml' in files:
            if package_name(here) == name:
                return here
            subfolders[:] = []  # a package holds no other package
            continue
        deep = len(here.parts) - root_depth >= MAX_CRAWL_DEPTH
        subfolders[:] = [] if deep else sorted(sub for sub in subfolders
                                               if not sub.startswith('.'))
    return None


def _own_tree(name: str, near: Path) -> Iterator[Path | None]:
    """Yield the folders of the file ``near``'s package tree that may be package ``name``."""
    own = None
    for folder in near.resolve().parents:
        if (folder / 'package.xml').is_file():
            if package_name(folder) == name:
                yield folder
                return
            own = own or folder
    if own is not None:
        yield crawl(own.parent, name)


def _env_folders(variable: str) -> list[Path]:
    return [Path(entry) for entry in os.environ.get(variable, '').split(os.pathsep) if entry]


def find_package(name: str, near: Path | None = None) -> Path:
    """
    Return the folder of ROS package ``name`` (see the module text), for a file at ``near``.

    Raises :class:`PackageNotFoundError`, one line saying where it looked and what to set.
    """
    for prefix in _env_folders('AMENT_PREFIX_PATH'):
        if (prefix / 'share' / name).is_dir():
            return prefix / 'share' / name
    for root in _env_folders('ROS_PACKAGE_PATH'):
        found = crawl(root, name)
        if found is not None:
            return found
    for found in _own_tree(name, near) if near is not None else ():
        if found is not None:
            return found
    for folder in paths.model_search_path():
        if (folder / name).is_dir():
            return folder / name
    where = f', nor in the package tree of {near}' if near is not None else ''
    raise PackageNotFoundError(
        f"ROS package '{name}' not found on AMENT_PREFIX_PATH, ROS_PACKAGE_PATH or the model "
        f'path{where}: put the folder holding it on ROS_PACKAGE_PATH (or source its '
        'workspace)')
