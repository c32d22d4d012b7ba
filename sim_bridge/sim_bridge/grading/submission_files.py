"""
A student's node files, found the way students hand them in.

Students hand in the files at the top of the submission, in a folder, in the handout's
package layout (``scan_pkg/scan_pkg/wanderbot.py`` beside ``setup.py``), or in a zip of any of
those. :func:`find_node_files` finds each wanted file: the shallowest of that name, a zip
unpacked first (bounded: no path outside its folder, no link, at most MAX_MEMBERS files and
MAX_UNPACKED_BYTES in all, each at most MAX_FILE_BYTES), colcon's ``build/``, ``install/`` and
``log/``, hidden folders and a copy of the kit's ``sim_bridge`` package left out. A node with
no file of its name gets the one file the student meant for it
(:mod:`sim_bridge.grading.node_names`: ``wall_follower.py``, a file whose node is named so, a
``setup.py`` entry point), and a note says so; several such files are listed, none graded.
:func:`missing_text` says what was found when a file is missing. Plain files and folders: no
rclpy.
"""

from dataclasses import dataclass, field
import os
from pathlib import Path, PurePosixPath
import re
import shutil
import stat
from typing import BinaryIO
import zipfile

from sim_bridge.common.text import printable
from sim_bridge.grading.node_names import candidates, syntax_trees

#: Folders no handed-in node is in: colcon's outputs, caches, virtual environments.
SKIPPED = frozenset({'build', 'install', 'log', '__pycache__', '__MACOSX', 'venv', '.venv',
                     'node_modules'})
#: How deep below the submission's top a node file is looked for.
MAX_DEPTH = 6
#: A package.xml naming the kit's simulator package, and how much of one is read (bytes).
KIT_PACKAGE_NAME = re.compile(r'<name>\s*sim_bridge\s*</name>')
PACKAGE_XML_BYTES = 64 * 1024
#: Bounds of what a zip may unpack to: files, bytes in all and in one file.
MAX_MEMBERS = 2000
MAX_UNPACKED_BYTES = 64 * 2 ** 20
MAX_FILE_BYTES = 8 * 2 ** 20
#: Zips unpacked: those at most this deep, at most this many.
MAX_ZIPS = 4
#: The files listed when a wanted one is missing.
LISTED = 10


@dataclass
class Found:
    """The node files found in a submission, the Python files seen, and notes on the way."""

    files: dict[str, Path] = field(default_factory=dict)
    #: Every .py file seen, relative to the submission (a zip's: under the zip's name).
    seen: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: The files that could each be a wanted file of none found, when there are several.
    choices: dict[str, list[str]] = field(default_factory=dict)


def unpack_zip(archive: Path, into: Path) -> str | None:
    """
    Unpack ``archive`` into the new folder ``into`` safely; return why it was refused, or None.

    Refused whole: a member whose path leaves the folder (absolute, ``..``), more than
    MAX_MEMBERS members, more than MAX_UNPACKED_BYTES in all or MAX_FILE_BYTES in one (as the
    zip declares them, and as they unpack); links and special files are skipped.
    """
    try:
        with zipfile.ZipFile(archive) as opened:
            members = opened.infolist()
            if len(members) > MAX_MEMBERS:
                return f'{len(members)} files (at most {MAX_MEMBERS})'
            declared = sum(member.file_size for member in members)
            if declared > MAX_UNPACKED_BYTES:
                return f'{declared / 2 ** 20:.0f} MiB unpacked (at most ' \
                       f'{MAX_UNPACKED_BYTES / 2 ** 20:.0f} MiB)'
            for member in members:
                path = PurePosixPath(member.filename.replace('\\', '/'))
                if path.is_absolute() or '..' in path.parts or ':' in member.filename:
                    return f'its file {printable(member.filename)!r} would unpack outside it'
            into.mkdir(parents=True)
            budget = MAX_UNPACKED_BYTES
            for member in members:
                kind = stat.S_IFMT(member.external_attr >> 16)  # 0: not said (not from Unix)
                if member.is_dir() or (kind and kind != stat.S_IFREG):
                    continue
                if member.file_size > MAX_FILE_BYTES:
                    return f'its file {printable(member.filename)!r} is too large'
                target = into / PurePosixPath(member.filename.replace('\\', '/'))
                target.parent.mkdir(parents=True, exist_ok=True)
                with opened.open(member) as source, open(target, 'wb') as sink:
                    bounded = _Bounded(source, min(MAX_FILE_BYTES, budget))
                    shutil.copyfileobj(bounded, sink)
                    budget -= bounded.read_bytes
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as error:
        return f'not a zip that can be read ({printable(str(error))})'
    return None


class _Bounded:
    """A file object that stops reading, with ValueError, beyond ``limit`` bytes."""

    def __init__(self, source: BinaryIO, limit: int) -> None:
        self.source, self.limit, self.read_bytes = source, limit, 0

    def read(self, size: int = -1) -> bytes:
        """Read as the source does, at most one byte beyond the limit, then refuse."""
        left = self.limit - self.read_bytes
        data = self.source.read(left + 1 if size < 0 else min(size, left + 1))
        self.read_bytes += len(data)
        if self.read_bytes > self.limit:
            raise ValueError('a file unpacks larger than the zip says')
        return data


def is_kit_package(folder: Path) -> bool:
    """
    Tell whether ``folder`` is a copy of the kit's sim_bridge package (its package.xml says so).

    The handout's workspace holds one beside the student's scan_pkg (``src/sim_bridge``): its
    worked examples are the kit's, never the student's nodes.
    """
    try:
        with open(folder / 'package.xml', 'rb') as manifest:
            head = manifest.read(PACKAGE_XML_BYTES).decode('utf-8', 'replace')
    except OSError:
        return False
    return KIT_PACKAGE_NAME.search(head) is not None


def _walk(top: Path, label: str) -> list[tuple[int, str, Path]]:
    """
    Return (depth, shown path, path) of the files below ``top``, skipped folders left out.

    Skipped: SKIPPED, hidden folders, a copy of the kit's sim_bridge package, and what lies
    deeper than MAX_DEPTH.
    """
    files = []
    for folder, subfolders, names in os.walk(top):
        depth = len(Path(folder).relative_to(top).parts)
        subfolders[:] = sorted(name for name in subfolders if name not in SKIPPED
                               and not name.startswith('.') and depth < MAX_DEPTH
                               and not is_kit_package(Path(folder) / name))
        for name in sorted(names):
            path = Path(folder) / name
            shown = (Path(label) / path.relative_to(top)).as_posix()
            files.append((depth, shown, path))
    return files


def find_node_files(submission: Path, wanted: list[str], scratch: Path) -> Found:
    """
    Find each of the ``wanted`` file names (``wanderbot.py``) in ``submission``.

    Zips in it are unpacked below ``scratch`` (a folder of the grader's) first; of several
    files of one name, the shallowest is taken (then the first by path) and a note says which.
    """
    found = Found()
    files = _walk(submission, '')
    zips = [(depth, shown, path) for depth, shown, path in files
            if path.suffix.lower() == '.zip' and path.is_file()][:MAX_ZIPS]
    for index, (_, shown, path) in enumerate(zips):
        into = scratch / f'zip_{index}'
        if into.exists():
            shutil.rmtree(into)
        refused = unpack_zip(path, into)
        if refused:
            found.notes.append(f'{printable(shown)}: not unpacked: {refused}')
            continue
        files += [(depth + 1, f'{shown}/{inner}', inner_path)
                  for depth, inner, inner_path in _walk(into, '')]
    python = []
    for depth, shown, path in sorted(files, key=lambda item: (item[0], item[1])):
        if path.suffix != '.py' or path.is_symlink() or not path.is_file():
            continue
        found.seen.append(printable(shown))
        python.append((printable(shown), path))
        if path.name in wanted and path.name not in found.files:
            found.files[path.name] = path
            if depth:
                found.notes.append(f'{path.name}: graded {printable(shown)}')
    meant_files(found, python, [name for name in wanted if name not in found.files])
    return found


def meant_files(found: Found, python: list[tuple[str, Path]], absent: list[str]) -> None:
    """
    Add to ``found`` the file the student meant for each ``absent`` name, when there is one.

    ``python``: (shown path, path) of the submission's Python files, shallowest first; a file
    already taken for a wanted name is no other's. One candidate is graded, with a note
    ('graded wall_follower.py as wall_follow (its name)'); several go to ``found.choices``.
    """
    taken = set(found.files.values())
    trees = syntax_trees(python) if absent else {}
    for name in absent:
        could_be = [candidate for candidate in candidates(python, PurePosixPath(name).stem,
                                                          trees)
                    if candidate.path not in taken]
        if len(could_be) == 1:
            [chosen] = could_be
            found.files[name] = chosen.path
            taken.add(chosen.path)
            found.notes.append(f'graded {chosen.shown} as {PurePosixPath(name).stem} '
                               f'({chosen.why})')
        elif could_be:
            found.choices[name] = [f'{candidate.shown} ({candidate.why})'
                                   for candidate in could_be]


def missing_text(absent: list[str], found: Found, wanted: list[str], name: str) -> str:
    """
    Say in one line which files ``name/`` misses.

    Then the files that could each be one, or all that was found instead (at most LISTED,
    and how many more), and what is expected.
    """
    several = [f"{', '.join(found.choices[file])} could each be {file}" for file in absent
               if file in found.choices]
    if several:
        return f"no {', '.join(absent)} in {name}/: {'; '.join(several)} (rename the one to grade)"
    more = len(found.seen) - LISTED
    seen = ', '.join(found.seen[:LISTED]) + (f' and {more} more' if more > 0 else '')
    return (f"no {', '.join(absent)} in {name}/ (found: {seen or 'no Python file'}; "
            f"expected {', '.join(wanted)} or files named after them, at the top, in a "
            'folder, in scan_pkg/scan_pkg/ or in a zip)')
