"""
Find the workspace's worlds, models, scenarios and examples in a checkout or a colcon install.

A source checkout (including a pip editable install) keeps ``worlds/``, ``models/``,
``scenarios/`` and ``examples/`` at the repository's top level, three folders above this
module. A colcon install has them in the package's share directory. Models are looked up the
way Gazebo does (see :func:`model_search_path`): a world's own folder, Gazebo's resource
paths, the users' model folders, and the kit's ``models/`` last.
"""

import os
from pathlib import Path
import sys

PACKAGE_NAME = 'sim_bridge'
WORLD_SUFFIX = '.yaml'
#: Suffixes of world files given by path: the kit's YAML and Gazebo's SDF.
WORLD_FILE_SUFFIXES = ('.yaml', '.yml', '.world', '.sdf')
#: Environment variables listing model folders, in the order they are searched.
MODEL_PATH_VARIABLES = ('GZ_SIM_RESOURCE_PATH', 'IGN_GAZEBO_RESOURCE_PATH', 'GAZEBO_MODEL_PATH')
#: Folders below the home directory where Gazebo keeps downloaded models.
HOME_MODEL_FOLDERS = ('.gazebo/models', '.gz/models')


def repo_root() -> Path | None:
    """Return the source checkout this module runs from, or None when installed elsewhere."""
    root = Path(__file__).resolve().parents[3]
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


def scenarios_dir() -> Path:
    """Return the folder of the shipped scenarios (each lab task's grading)."""
    return _data_dir('scenarios')


def examples_dir() -> Path:
    """Return the folder of the example nodes (naive solutions) the demo and the videos run."""
    return _data_dir('examples')


def world_names() -> list[str]:
    """Return the names of the shipped worlds, sorted."""
    return sorted(path.stem for path in worlds_dir().glob('*' + WORLD_SUFFIX))


def find_world(name_or_path: str | os.PathLike) -> Path:
    """Return the world file for a shipped world's name or for a path to any world file."""
    path = Path(name_or_path)
    if path.suffix in WORLD_FILE_SUFFIXES or path.parent != Path('.'):
        if path.is_file():
            return path
        raise FileNotFoundError(f'world file not found: {path}')
    shipped = worlds_dir() / (str(name_or_path) + WORLD_SUFFIX)
    if shipped.is_file():
        return shipped
    raise FileNotFoundError(
        f"unknown world '{name_or_path}': shipped worlds are {', '.join(world_names())}")


def model_search_path(world_folder: str | os.PathLike | None = None) -> list[Path]:
    """
    Return the folders searched for models, first match wins.

    The world file's own folder (when a world is being read), then Gazebo Sim's
    ``GZ_SIM_RESOURCE_PATH`` and its older name ``IGN_GAZEBO_RESOURCE_PATH``, Gazebo Classic's
    ``GAZEBO_MODEL_PATH``, the users' ``~/.gazebo/models`` and ``~/.gz/models``, and the kit's
    ``models/`` last: a model on the user's paths (the real TurtleBot3 folders, say) wins over
    the kit's folder of the same name.
    """
    folders = [Path(world_folder)] if world_folder is not None else []
    for variable in MODEL_PATH_VARIABLES:
        folders += [Path(entry) for entry in os.environ.get(variable, '').split(os.pathsep)
                    if entry]
    home = Path.home()
    folders += [home / folder for folder in HOME_MODEL_FOLDERS]
    folders.append(models_dir())
    return list(dict.fromkeys(folders))


def is_model_folder(folder: Path) -> bool:
    """Return True when ``folder`` holds a Gazebo model (``model.config`` or ``model.sdf``)."""
    return (folder / 'model.config').is_file() or (folder / 'model.sdf').is_file()


def find_model(name: str, world_folder: str | os.PathLike | None = None) -> Path:
    """Return the folder of the model called ``name`` on :func:`model_search_path`."""
    folders = model_search_path(world_folder)
    for folder in folders:
        if is_model_folder(folder / name):
            return folder / name
    raise FileNotFoundError(
        f"model '{name}' not found (looked for {name}/model.config or model.sdf in "
        f"{', '.join(str(folder) for folder in folders)}); put its folder on "
        'GZ_SIM_RESOURCE_PATH')


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
