"""
Finding model files: a model folder's SDF file and the files ``model://``, Fuel and file URIs name.

A folder's ``model.config`` names its SDF file (Gazebo's rule); ``model://NAME/...`` is looked
up on :func:`~sim_bridge.common.paths.model_search_path`; a Fuel URL in Gazebo's download
cache; a mesh's relative path or ``file://`` URI relative to the SDF file that names it (gz-sim's
``asFullPath``); an ``<include>``'s where sdformat's ``sdf::findFile`` finds it
(:func:`include_folders`). Gazebo's ``ground_plane`` and ``sun`` have builtin stand-ins, so
worlds that include them work offline.
"""

import os
from pathlib import Path
from urllib.parse import unquote, urlparse

from sim_bridge.common import paths
from sim_bridge.simulation.sdf_values import parse_sdf_xml, SdfError, SdfValues

#: A model named by a bare file name with one of these suffixes is that file, not a folder.
MODEL_FILE_SUFFIXES = ('.sdf', '.urdf', '.xacro')
#: The Fuel models with builtin stand-ins (see :meth:`ModelLookup.builtin`), by name.
FUEL_BUILTINS = {'ground plane': 'ground_plane', 'sun': 'sun'}
#: sdformat's own list of folders searched for an ``<include>``'s file (gz-sim appends its
#: resource path to it).
SDF_PATH_VARIABLE = 'SDF_PATH'


def include_folders(including_file: Path, world_folder: Path | None) -> list[Path]:
    """
    Return the folders an ``<include>``'s relative ``file://`` URI or path is looked up in.

    sdformat's ``sdf::findFile(uri, searchLocalPath=true)`` (``<include>`` in its parser.cc)
    strips the scheme, then tries the current working directory (where Gazebo was started),
    the path as given, and each ``SDF_PATH`` folder, to which gz-sim's ``addResourcePaths``
    appends ``GZ_SIM_RESOURCE_PATH``. The kit tries the rest of its model path after those
    (``IGN_GAZEBO_RESOURCE_PATH``, ``GAZEBO_MODEL_PATH``), then the including file's folder and
    the world's, as kit worlds may, then the users' and the kit's model folders.
    """
    variables = (SDF_PATH_VARIABLE, *paths.MODEL_PATH_VARIABLES)
    folders = [Path.cwd()]
    folders += [Path(entry) for variable in variables
                for entry in os.environ.get(variable, '').split(os.pathsep) if entry]
    folders.append(including_file.parent)
    folders += paths.model_search_path(world_folder)
    return list(dict.fromkeys(folders))


def model_file(path: Path) -> Path:
    """Return the SDF file of a model folder or file; FileNotFoundError when there is none."""
    if path.is_dir():
        path = path / sdf_file_name(path)
    if not path.is_file():
        raise FileNotFoundError(f'model file not found: {path}')
    return path


def sdf_file_name(folder: Path) -> str:
    """
    Return the SDF file a model folder's ``model.config`` names (newest version first).

    Gazebo's rule; ``model.sdf`` when there is no ``model.config``.
    """
    config = folder / 'model.config'
    if not config.is_file():
        return 'model.sdf'
    root = parse_sdf_xml(config.read_text(encoding='utf-8'), config)
    candidates = []
    for element in root.iter('sdf'):
        version = element.get('version', '0')
        try:
            key = tuple(int(part) for part in version.split('.'))
        except ValueError:
            raise SdfError(f'{config}: <sdf version="{version}">: version must be like "1.6"')
        if not (element.text or '').strip():
            raise SdfError(f'{config}: <sdf version="{version}">: names no file')
        candidates.append((key, element.text.strip()))
    if not candidates:
        raise SdfError(f'{config}: <model>: has no <sdf> element naming the model file')
    return max(candidates)[1]


def fuel_cache(uri) -> Path | None:
    """
    Return the newest downloaded copy of a Fuel model URI in Gazebo's cache, or None.

    ``https://fuel.gazebosim.org/1.0/OWNER/models/NAME[/VERSION]`` is kept by ``gz fuel
    download`` in ``~/.gz/fuel/fuel.gazebosim.org/owner/models/name/VERSION`` (owner and name
    in lower case; ``~/.ignition/fuel`` before Gazebo Garden, or ``GZ_FUEL_CACHE_PATH``).
    """
    parts = [unquote(part) for part in uri.path.strip('/').split('/')]
    if 'models' not in parts[1:-1]:
        return None
    index = parts.index('models')
    owner, name = parts[index - 1].lower(), parts[index + 1].lower()
    version = parts[index + 2] if len(parts) > index + 2 else ''
    roots = [Path(os.environ['GZ_FUEL_CACHE_PATH'])] if os.environ.get('GZ_FUEL_CACHE_PATH') \
        else []
    roots += [Path.home() / '.gz' / 'fuel', Path.home() / '.ignition' / 'fuel']
    for root in roots:
        folder = root / uri.netloc / owner / 'models' / name
        if version.isdigit() and (folder / version).is_dir():
            return folder / version
        versions = sorted((place for place in folder.glob('*') if place.name.isdigit()),
                          key=lambda place: int(place.name))
        if versions:
            return versions[-1]
    return None


class ModelLookup(SdfValues):
    """The SDF reader's part finding the model folders and files that URIs name."""

    def builtin(self, uri: str) -> str | None:
        """Return 'ground_plane' or 'sun' for those URIs when no model folder provides them."""
        parsed = urlparse(uri)
        if parsed.scheme == 'model':
            name = parsed.netloc
            if name in ('ground_plane', 'sun') and not self.findable(name):
                return name
            return None
        if parsed.scheme in ('http', 'https'):
            name = unquote(parsed.path.rstrip('/').split('/models/')[-1].split('/')[0])
            return FUEL_BUILTINS.get(name.lower())
        return None

    def findable(self, name: str) -> bool:
        try:
            paths.find_model(name, self.world_folder)
        except FileNotFoundError:
            return False
        return True

    def model_folder(self, uri: str, where: str, include: bool = False) -> Path:
        """
        Return the model folder (or SDF file) a ``model://``, Fuel, file or path URI names.

        ``include``: the URI is an ``<include>``'s, whose file or path is found as sdformat
        finds it (:func:`include_folders`), not relative to this file as a mesh's is.
        """
        parsed = urlparse(uri)
        if parsed.scheme == 'model':
            # model:///NAME/... (three slashes) names the same file as model://NAME/...
            name, _, rest = (parsed.netloc + parsed.path).lstrip('/').partition('/') \
                if not parsed.netloc else (parsed.netloc, '', parsed.path)
            try:
                folder = paths.find_model(name, self.world_folder)
            except FileNotFoundError as error:
                raise self.error(where, str(error)) from None
            return folder / unquote(rest.lstrip('/'))
        if parsed.scheme in ('http', 'https'):
            cached = fuel_cache(parsed)
            if cached is not None:
                return cached
            raise self.error(where, f'{uri} is a Gazebo Fuel model, not available offline: '
                             f"download it (gz fuel download -u '{uri}') and put its model "
                             'folder on GZ_SIM_RESOURCE_PATH')
        return self.included_file(uri, where) if include else self.local_file(uri, where)

    def included_file(self, uri: str, where: str) -> Path:
        """Return the model folder or file an ``<include>``'s file URI or path names."""
        path = self.uri_path(uri, where)
        if path.is_absolute():
            return path
        folders = include_folders(self.path, self.world_folder)
        found = next((folder / path for folder in folders if (folder / path).exists()), None)
        if found is None:
            others = ', '.join(str(folder) for folder in folders[1:])
            raise self.error(where, f'{uri} not found in the working directory ({Path.cwd()}), '
                             f'as Gazebo looks first, nor in {others}: start from the folder '
                             'it is relative to, or put that folder on GZ_SIM_RESOURCE_PATH')
        return found

    def uri_path(self, uri: str, where: str) -> Path:
        """Return the path a ``file://`` URI or a plain path names, as written."""
        parsed = urlparse(uri)
        if parsed.scheme not in ('', 'file'):
            raise self.error(where, f'unsupported URI {uri!r}; use model://NAME/..., a '
                             'file:// URI or a path relative to the SDF file')
        return Path(unquote(parsed.netloc + parsed.path) if parsed.scheme else uri)

    def local_file(self, uri: str, where: str) -> Path:
        """Return the file a ``file://`` URI or a path names, relative to this file's folder."""
        path = self.uri_path(uri, where)
        if path.is_absolute():
            return path
        candidates = [self.path.parent / path]
        candidates += [folder / path for folder in paths.model_search_path(self.world_folder)]
        return next((place for place in candidates if place.exists()), candidates[0])
