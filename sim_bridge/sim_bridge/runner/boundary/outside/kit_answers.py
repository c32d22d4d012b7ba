"""
What of the kit holds answers, in every copy a run could read: what a student's run never reads.

The answers are the kit's reference nodes (the modules of scan_pkg's console scripts), the
controllers they run (``scan_pkg.behaviors``) and the worked examples (``examples/``); and the
grader's own answer key in sim_bridge (GRADER_KEYS, :func:`grader_key_files`), which every run
in bubblewrap sees empty, the kit's own nodes' too (none of them reads it). Without namespaces
(PARTLY sandboxed) the key stays readable: the grader imports it as whatever user runs it, and
mode bits that closed it to a run's uid would close it to that user too; it holds what the
handout's own sample code prints (the range ahead, five region minima), no behaviour. A
copy of them lies wherever the kit was built or installed: a venv's site folder (an
autograder's), setuptools' ``build/lib`` and ``*.egg-info`` beside a package that ``pip
install FOLDER`` built, colcon's ``build/`` and ``install/``, git's history, Python's bytecode
caches. :func:`reference_node_files` lists the answer files (sources and bytecode) of every copy
of scan_pkg; :func:`answer_folders` the folders of the kit that hold nothing a run needs, to be
closed whole. A run's sandbox (sim_bridge.runner.boundary.outside.sandbox) hides both: empty in its
namespaces, unreadable to its uid without them.
"""

import functools
import importlib.machinery
import importlib.util
import os
from pathlib import Path
import sys
from typing import Sequence

from sim_bridge.runner.boundary.outside.sandbox_view import is_within, KIT_PACKAGE

#: Folders at the kit's top closed whole: the worked examples, colcon's build folder (copies
#: of the packages) and git's history.
TOP_ANSWER_FOLDERS = ('examples', 'build', '.git')
#: Folders beside each of the kit's packages closed whole: what setuptools leaves there when
#: pip installs the package from its folder (a copy of it, its file list).
PACKAGE_ANSWER_FOLDERS = ('build', '*.egg-info')
#: Folders never searched for copies of scan_pkg (closed whole, or no Python package).
UNSEARCHED_FOLDERS = ('.git', 'node_modules', '__pycache__')
#: The grader's answer key, in the sim_bridge package: the scan geometry (the lab's regions)
#: printed values are judged by. sim_bridge is readable in a run (its agent lives there).
GRADER_KEYS = ('scoring/scan_geometry.py',)


def bytecode_of(source: Path) -> list[str]:
    """Return the bytecode files Python cached of ``source`` (``__pycache__/NAME.*.pyc``)."""
    return [str(path) for path in (source.parent / '__pycache__').glob(f'{source.stem}.*.pyc')]


def grader_key_files() -> list[str]:
    """
    Return the files of the grader's answer key (GRADER_KEYS), to be hidden from every run.

    In the sim_bridge package this process runs and in any other copy on Python's path or in
    its site folders (an installed copy beside a source checkout), with their bytecode (real
    paths).
    """
    import site
    entries = dict.fromkeys([*sys.path, *site.getsitepackages()])
    packages = [KIT_PACKAGE, *(Path(entry or '.') / 'sim_bridge' for entry in entries)]
    files = []
    for package in dict.fromkeys(Path(os.path.realpath(folder)) for folder in packages):
        for name in GRADER_KEYS:
            source = package / name
            if source.is_file():
                files += [str(source), *bytecode_of(source)]
    return files


def reference_node_files() -> list[str]:
    """
    Return the files of the kit's reference answers, to be hidden from a student's node.

    The modules of scan_pkg's console scripts (the lab's nodes), the pure controllers they run
    (``scan_pkg.behaviors``), and the bytecode Python cached of each (a student could load a
    ``.pyc`` by hand as well as a ``.py``), in every copy of scan_pkg a run could read
    (:func:`library_copies`: an autograder's venv holds one beside the kit's own; and
    :func:`kit_copies`: any other in the kit's folder, such as a stale install).
    """
    sources = [Path(source) for source in reference_node_sources()]
    copies = list(dict.fromkeys([*library_copies(), *kit_copies()]))
    files = []
    for imported in library_folders():
        names = [source.relative_to(imported) for source in sources
                 if source.is_relative_to(imported)]
        for copy in copies:
            for name in names:
                source = copy / name
                if os.path.exists(source):
                    files.append(str(source))
                files += bytecode_of(source)
    return list(dict.fromkeys(files))


def reference_node_sources() -> list[str]:
    """Return the source files of the kit's reference answers (see reference_node_files)."""
    files = [os.path.realpath(spec.origin) for spec in console_script_specs()]
    behaviors = importlib.util.find_spec('scan_pkg.behaviors')
    for folder in (behaviors.submodule_search_locations or []) if behaviors else []:
        files.extend(os.path.realpath(path) for path in sorted(Path(folder).glob('*.py')))
    return files


def console_script_specs() -> list[importlib.machinery.ModuleSpec]:
    """Return the specs of scan_pkg's console scripts' modules, as this process finds them."""
    from importlib.metadata import distribution, PackageNotFoundError
    try:
        scripts = [entry for entry in distribution('scan_pkg').entry_points
                   if entry.group == 'console_scripts']
    except PackageNotFoundError:
        return []
    specs = [importlib.util.find_spec(entry.module) for entry in scripts]
    return [spec for spec in specs if spec is not None and spec.origin]


def library_folders() -> list[Path]:
    """
    Return the folders of the kit's scan_pkg package as this process imports it, real paths.

    The folder of each console script's module's package (``scan_pkg`` imported from the
    workspace's top is a namespace of the ament package's folder; its modules are not).
    """
    folders = [Path(os.path.realpath(spec.origin)).parents[spec.name.count('.') - 1]
               for spec in console_script_specs()]
    spec = importlib.util.find_spec('scan_pkg')
    folders += [Path(os.path.realpath(folder)) for folder in
                ((spec.submodule_search_locations or []) if spec else [])
                if os.path.isfile(Path(folder) / '__init__.py')]
    return list(dict.fromkeys(folders))


def library_copies() -> list[Path]:
    """
    Return every scan_pkg package folder a run could import (real paths).

    This process's (:func:`library_folders`), and any other on Python's path or in its site
    folders: a venv with the kit installed (Gradescope's setup.sh) holds a copy that a
    ``PYTHONPATH`` to the kit's source only shadows.
    """
    import site
    folders = library_folders()
    for entry in dict.fromkeys([*sys.path, *site.getsitepackages()]):
        candidate = Path(entry or '.') / 'scan_pkg'
        if os.path.isfile(candidate / '__init__.py'):
            folders.append(Path(os.path.realpath(candidate)))
    return list(dict.fromkeys(folders))


def kit_tops() -> list[Path]:
    """Return the kit's top folders: those holding its ament packages (with package.xml)."""
    packages = [KIT_PACKAGE.parent, *(folder.parent for folder in library_folders())]
    return list(dict.fromkeys(package.parent for package in packages
                              if os.path.isfile(package / 'package.xml')))


def answer_folders(needed: Sequence[str]) -> list[str]:
    """
    Return the kit's folders that hold answers or copies of the kit, to be closed whole.

    TOP_ANSWER_FOLDERS at each of :func:`kit_tops`, PACKAGE_ANSWER_FOLDERS beside each of its
    packages (real paths). A folder that holds one of ``needed`` (what a run must read: its
    Python, the kit's packages) stays open: :func:`reference_node_files` hides the answers in
    it file by file. A folder this process cannot enter (an ordinary user's grader, a folder
    already closed) is taken as it is named.
    """
    folders = []
    for top in kit_tops():
        candidates = [top / name for name in TOP_ANSWER_FOLDERS]
        for package in sorted(top.iterdir()):
            if os.path.isfile(package / 'package.xml'):
                candidates += [match for pattern in PACKAGE_ANSWER_FOLDERS
                               for match in sorted(package.glob(pattern))]
        folders += [os.path.realpath(folder) for folder in candidates
                    if os.path.isdir(folder) and not folder.is_symlink()
                    and not any(is_within(path, [os.path.realpath(folder)]) for path in needed)]
    return list(dict.fromkeys(folders))


@functools.lru_cache(maxsize=None)
def kit_copies() -> list[Path]:
    """
    Return every scan_pkg package folder in the kit's folders (real paths), once per process.

    Whether or not a run would import it: a venv the grader does not use, a stale install.
    Symlinks are not followed; UNSEARCHED_FOLDERS are not entered.
    """
    copies = []
    for top in kit_tops():
        for folder, names, files in os.walk(top):
            if os.path.basename(folder) == 'scan_pkg' and '__init__.py' in files:
                copies.append(Path(os.path.realpath(folder)))
            names[:] = [name for name in names if name not in UNSEARCHED_FOLDERS]
    return copies
