"""
What a run sees of the machine's files in its sandbox (sim_bridge.runner.boundary.outside.sandbox).

With namespaces (bubblewrap), a run's root is empty but for what is mounted: the system
folders (SYSTEM_PATHS) and the few files of /etc a Python needs (ETC_PATHS), read-only; the
Python installation, its site folders and the kit's sim_bridge package (:func:`python_roots`),
read-only; and what the kit keeps from runs hidden inside those (:func:`hidden_mounts`: an
answer file is empty, a folder of answers an empty read-only folder, a package the run must
not import an empty folder).
"""

import importlib.util
import os
from pathlib import Path
import sys
from typing import Sequence

#: What of /etc a Python and a DDS participant read (the rest is the instructor's).
ETC_PATHS = ('/etc/ld.so.cache', '/etc/ld.so.conf', '/etc/ld.so.conf.d', '/etc/localtime',
             '/etc/nsswitch.conf', '/etc/hosts', '/etc/host.conf', '/etc/alternatives')
#: Top folders of the system installation, read-only (symlinks mirrored on merged-/usr).
SYSTEM_PATHS = ('/usr', '/bin', '/sbin', '/lib', '/lib32', '/lib64')
#: The kit's sim_bridge package, which runs see read-only (the stepping agent lives there).
KIT_PACKAGE = Path(__file__).resolve().parents[3]
#: Packages of the kit a run must not import (the reference nodes).
HIDDEN_PACKAGES = ('scan_pkg',)


def is_within(path: str, roots: Sequence[str]) -> bool:
    """Tell whether ``path`` is one of ``roots`` or inside one (paths as strings)."""
    return any(path == root or path.startswith(root.rstrip('/') + '/') for root in roots)


def python_roots() -> list[str]:
    """
    Return the folders outside the system ones a run needs read-only, outermost only.

    The Python installation and venv (``sys.prefix``, ``sys.base_prefix``, the site
    folders: the installation's and any on Python's path, such as one a ``.pth`` file added),
    the kit's ``sim_bridge`` package, and a sourced ROS 2 (``/opt/ros/$ROS_DISTRO``).
    """
    import site
    site_folders = [path for path in sys.path
                    if os.path.basename(path) in ('site-packages', 'dist-packages')]
    candidates = [sys.prefix, sys.base_prefix, sys.exec_prefix, sys.base_exec_prefix,
                  os.path.dirname(os.path.dirname(os.path.realpath(sys.executable))),
                  *site.getsitepackages(), *site_folders, str(KIT_PACKAGE)]
    if os.environ.get('ROS_DISTRO'):
        candidates.append(f'/opt/ros/{os.environ["ROS_DISTRO"]}')
    roots: list[str] = []
    for path in sorted({os.path.realpath(path) for path in candidates}, key=len):
        if os.path.isdir(path) and not is_within(path, [*SYSTEM_PATHS, *roots]):
            roots.append(path)
    return roots


def hidden_package_folders(roots: Sequence[str]) -> list[str]:
    """
    Return the folders of HIDDEN_PACKAGES that a run would see under ``roots`` or /usr.

    A kit installed as a package (not editable: in site-packages, or /usr/local) has its
    reference nodes there; a run gets an empty read-only folder in their place.
    """
    folders = []
    for name in HIDDEN_PACKAGES:
        spec = importlib.util.find_spec(name)
        for folder in (spec.submodule_search_locations or []) if spec else []:
            folder = os.path.realpath(folder)
            if is_within(folder, [*SYSTEM_PATHS, *roots]):
                folders.append(folder)
    return folders


def system_mounts() -> list[str]:
    """Return bwrap's arguments for the system folders and /etc's few files, read-only."""
    arguments = []
    for path in SYSTEM_PATHS:
        if os.path.islink(path):
            arguments += ['--symlink', os.readlink(path), path]
        elif os.path.isdir(path):
            arguments += ['--ro-bind', path, path]
    for path in ETC_PATHS:
        arguments += ['--ro-bind-try', path, path]
    return arguments


def parent_folders(paths: Sequence[str]) -> list[str]:
    """
    Return the folders above ``paths`` that bwrap must make, outermost first.

    bwrap makes a mount point's missing parents 0700 (root's, in a root sandbox): made
    first as 0755, the run's uid can pass through them to what is mounted below.
    """
    parents = {str(parent) for path in paths for parent in Path(path).parents}
    mounted = [*paths, *SYSTEM_PATHS, '/dev', '/proc']
    return sorted((folder for folder in parents
                   if folder not in ('/', '/tmp') and not is_within(folder, mounted)), key=len)


def hidden_mounts(hidden: Sequence[str], mounted: Sequence[str]) -> list[str]:
    """
    Return bwrap's arguments that hide ``hidden`` (files and folders) inside ``mounted``.

    A file is empty (/dev/null), a folder an empty read-only one; what lies outside
    ``mounted`` is absent from the sandbox already, and a file in a hidden folder goes with it.
    Follow the arguments that mount ``mounted``.
    """
    folders = [path for path in hidden if os.path.isdir(path) and is_within(path, mounted)]
    arguments = []
    for folder in folders:
        arguments += ['--tmpfs', folder, '--remount-ro', folder]
    for path in hidden:
        if path not in folders and is_within(path, mounted) and not is_within(path, folders):
            arguments += ['--ro-bind', '/dev/null', path]
    return arguments
