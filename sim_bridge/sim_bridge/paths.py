"""
Find the workspace's worlds and models in a source checkout or a colcon install.

A source checkout (including a pip editable install) keeps ``worlds/`` and ``models/`` at the
repository's top level, two folders above this package. A colcon install has them in the
package's share directory. Models are also looked up the way Gazebo does, on
``GZ_SIM_RESOURCE_PATH`` and ``GAZEBO_MODEL_PATH``.
"""

import os
from pathlib import Path
import sys

PACKAGE_NAME = 'sim_bridge'
WORLD_SUFFIX = '.yaml'


def repo_root() -> Path | None:
    """Return the source checkout this module runs from, or None when installed elsewhere."""
    root = Path(__file__).resolve().parents[2]
    if (root / 'worlds').is_dir() and (root / 'models').is_dir():
        return root
    return None


def share_dir() -> Path | None:
    """
    Return the package's installed share directory, or None when it is not installed.

    ament's index finds a colcon install (a sourced workspace sets ``AMENT_PREFIX_PATH``); a
    plain pip install puts the same data files under ``<prefix>/share/sim_bridge``.
    """
    if os.environ.get('AMENT_PREFIX_PATH'):
        from ament_index_python.packages import get_package_share_directory
        from ament_index_python.packages import PackageNotFoundError
        try:
            return Path(get_package_share_directory(PACKAGE_NAME))
        except PackageNotFoundError:
            pass
    installed = Path(sys.prefix) / 'share' / PACKAGE_NAME
    return installed if installed.is_dir() else None


def _data_dir(name: str) -> Path:
    # The checkout first, and the install only when there is none (finding an install can fail
    # where no workspace is sourced).
    for find_base in (repo_root, share_dir):
        base = find_base()
        if base is not None and (base / name).is_dir():
            return base / name
    raise FileNotFoundError(
        f"cannot find the '{name}' folder: neither a source checkout nor an installed "
        f"'{PACKAGE_NAME}' share directory holds it")


def worlds_dir() -> Path:
    """Return the folder of the shipped world files."""
    return _data_dir('worlds')


def models_dir() -> Path:
    """Return the folder of the shipped Gazebo model folders."""
    return _data_dir('models')


def world_names() -> list[str]:
    """Return the names of the shipped worlds, sorted."""
    return sorted(path.stem for path in worlds_dir().glob('*' + WORLD_SUFFIX))


def find_world(name_or_path: str | os.PathLike) -> Path:
    """Return the world file for a shipped world's name or for a path to any world file."""
    path = Path(name_or_path)
    if path.suffix == WORLD_SUFFIX or path.parent != Path('.'):
        if path.is_file():
            return path
        raise FileNotFoundError(f'world file not found: {path}')
    shipped = worlds_dir() / (str(name_or_path) + WORLD_SUFFIX)
    if shipped.is_file():
        return shipped
    raise FileNotFoundError(
        f"unknown world '{name_or_path}': shipped worlds are {', '.join(world_names())}")


def model_search_path() -> list[Path]:
    """Return the folders searched for models: ours first, then Gazebo's resource paths."""
    folders = [models_dir()]
    for variable in ('GZ_SIM_RESOURCE_PATH', 'GAZEBO_MODEL_PATH'):
        folders += [Path(entry) for entry in os.environ.get(variable, '').split(os.pathsep)
                    if entry]
    return folders


def find_model(name: str) -> Path:
    """Return the model folder (holding ``model.sdf``) of the model called ``name``."""
    folders = model_search_path()
    for folder in folders:
        if (folder / name / 'model.sdf').is_file():
            return folder / name
    raise FileNotFoundError(
        f"model '{name}' not found (looked for {name}/model.sdf in "
        f"{', '.join(str(folder) for folder in folders)})")


def output_folder(text: str) -> Path:
    """
    Return the ``--out`` folder of a command line: a folder, or a path one can be made at.

    Raises argparse.ArgumentTypeError (argparse's one-line error) when the path, or the nearest
    part of it that exists, is a file.
    """
    from argparse import ArgumentTypeError
    path = Path(text)
    existing = next((place for place in (path, *path.parents) if place.exists()), None)
    if existing is not None and not existing.is_dir():
        raise ArgumentTypeError(f'{existing} is a file, not a folder: name a folder for the '
                                'outputs')
    return path
