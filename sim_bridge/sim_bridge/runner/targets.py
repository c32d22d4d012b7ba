"""
Find the rclpy Node class a runner TARGET names: a console script, a module or a file.

TARGET forms: ``wall_follow`` (a console script, as ``ros2 run`` knows it),
``scan_pkg.wall_follow`` (a module), ``path/to/node.py`` (any file, run as written); each
optionally followed by
``:ClassName`` when the module defines several Node subclasses. A path that exists is a path,
whatever it holds (``col:on/node.py``). Modules are imported as they are, with the rclpy of
this Python (a sourced ROS 2 Jazzy, or the PyPI wheels).

:class:`StudentCode` tells a node's own code from everything else in a traceback, so that an
error is reported at the student's line, not at rclpy's, the runner's or Python's library's.
"""

from dataclasses import dataclass
from importlib import import_module
from importlib.metadata import entry_points
import importlib.util
import inspect
import os
from pathlib import Path
import re
import site
import sys
import sysconfig
import traceback
from types import FrameType, ModuleType
from typing import Iterable
import unicodedata

from sim_bridge.runner.node_styles import node_class

#: Frames under these folders are never a node's own code: this package (the runner), and
#: Python's library and installed packages (a node calling random.choice([]) raised the
#: IndexError, not random.py).
LIBRARY_DIRS = tuple({os.path.dirname(os.path.abspath(__file__)) + os.sep} | {
    os.path.join(path, '') for path in (
        *(sysconfig.get_paths()[key] for key in ('stdlib', 'platstdlib', 'purelib', 'platlib')),
        *site.getsitepackages())})


class TargetError(LookupError):
    """
    A TARGET that names no loadable module or no rclpy Node subclass in it.

    ``file`` is the node file that failed to import, when known.
    """

    def __init__(self, message: str, file: str | None = None):
        super().__init__(message)
        self.file = file


#: What Python says of a character it refuses that a reader cannot see (its code point).
INVISIBLE_CHARACTER = re.compile(r'invalid non-printable character U\+(?P<code>[0-9A-Fa-f]{4,6})')


def split_target(target: str, base: Path | None = None) -> tuple[str, str | None]:
    """
    Split ``TARGET`` into what it names and the ``:ClassName`` that follows, if any.

    A TARGET naming an existing file (relative to ``base`` if given) is a path even when it
    holds ':'; otherwise the text after its last ':' is a class name when it is an identifier.
    """
    where, colon, class_name = target.rpartition(':')
    if not colon or not class_name.isidentifier() or ((base or Path()) / target).is_file():
        return target, None
    return where, class_name


def missing_node_file(target: str) -> str | None:
    """Return the file TARGET names when it names a node file that is not there, else None."""
    where, _ = split_target(target)
    if (where.endswith('.py') or '/' in where) and not Path(where).is_file():
        return where
    return None


def is_library_frame(filename: str) -> bool:
    """Return True when code in ``filename`` is not a node's own: see LIBRARY_DIRS."""
    return (filename.startswith('<') or '/msg/_' in filename or '/rclpy/' in filename
            or os.path.abspath(filename).startswith(LIBRARY_DIRS))


@dataclass(frozen=True)
class StudentCode:
    """
    Where a run's node code is, to find the node's own frames in a traceback.

    ``folders``: the folders of the run's node files (a node's own code is its file and the
    modules beside it). Without folders (or when no frame is in them), a node's own frames are
    those outside generated message code, rclpy, this package and Python's library
    (:func:`is_library_frame`).
    """

    folders: frozenset[str] = frozenset()

    @classmethod
    def of(cls, files: Iterable[str | os.PathLike]) -> 'StudentCode':
        """Return the student code of a run of the node files ``files``."""
        return cls(frozenset(os.path.dirname(os.path.abspath(file)) for file in files))

    def frames(self, frames: Iterable[traceback.FrameSummary]) -> list[traceback.FrameSummary]:
        """Return the frames of ``frames`` that are a node's own code, outermost first."""
        frames = list(frames)
        own = [frame for frame in frames
               if os.path.dirname(os.path.abspath(frame.filename)) in self.folders]
        return own or [frame for frame in frames if not is_library_frame(frame.filename)]

    def live_frames(self, error: BaseException) -> list[FrameType]:
        """Return the frames of ``error``'s traceback that are the node's own, outermost first."""
        steps = list(traceback.walk_tb(error.__traceback__))
        summaries = traceback.StackSummary.extract(steps, lookup_lines=False)
        own = {id(summary) for summary in self.frames(summaries)}
        return [frame for (frame, _), summary in zip(steps, summaries) if id(summary) in own]

    def origin(self, error: BaseException) -> str:
        """
        Return ' at file:line: code' of the node's line where ``error`` arose, or ''.

        The innermost frame of the node's own code, so an int assigned to a float field points
        at the assignment, not at rosidl's setter; a SyntaxError at its own file and line.
        """
        if isinstance(error, SyntaxError) and error.filename and error.lineno:
            text = (error.text or '').strip()
            return f' at {error.filename}:{error.lineno}' + (f': {text}' if text else '')
        return self.stack_origin(traceback.extract_tb(error.__traceback__))

    def stack_origin(self, frames: Iterable[traceback.FrameSummary]) -> str:
        """Return ' at file:line: code' of the innermost of ``frames`` that is the node's."""
        own = self.frames(frames)
        if not own:
            return ''
        frame = own[-1]
        return f' at {frame.filename}:{frame.lineno}' + (f': {frame.line}' if frame.line else '')

    def stack_traceback(self, frames: Iterable[traceback.FrameSummary],
                        error_lines: Iterable[str]) -> str:
        """Return the node's own of ``frames`` as Python prints them, then ``error_lines``."""
        own = self.frames(frames)
        head = ['Traceback (most recent call last):\n', *traceback.format_list(own)] if own else []
        return ''.join(head + list(error_lines))

    def traceback(self, error: BaseException) -> str:
        """
        Return the node's part of ``error``'s traceback: its own frames and the error lines.

        A SyntaxError ends with its file, line, the offending code and a caret, as Python
        prints it.
        """
        return self.stack_traceback(traceback.extract_tb(error.__traceback__),
                                    traceback.format_exception_only(error))


def _console_script_module(name: str) -> str | None:
    for entry in entry_points(group='console_scripts', name=name):
        return entry.value.partition(':')[0]
    return None


def _load_file(path: Path) -> ModuleType:
    if not path.is_file():
        raise TargetError(f'node file not found: {path}')
    module_name = f'lab_target_{path.stem}_{abs(hash(path.resolve())):x}'
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    # As `python3 path/to/node.py` does, the file's folder is searched first for its imports.
    sys.path.insert(0, str(path.parent))
    try:
        spec.loader.exec_module(module)
    except BaseException:  # noqa: B902 the half-run module must not stay importable
        del sys.modules[module_name]
        raise
    finally:
        sys.path.remove(str(path.parent))
    return module


def load_module(where: str) -> ModuleType:
    """Import the module a TARGET (without ``:ClassName``) names."""
    if where.endswith('.py') or '/' in where or Path(where).is_file():
        return _load_file(Path(where))
    module_name = _console_script_module(where) or where
    try:
        return import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name != module_name and not module_name.startswith(f'{error.name}.'):
            raise
        raise TargetError(f"'{where}' is neither a console script, a module nor a .py file")


def error_message(error: BaseException) -> str:
    """Return ``str(error)``, or what Python's traceback says when a student's __str__ raises."""
    try:
        return str(error)
    except Exception:  # noqa: B902 whatever the student's __str__ raised
        return '<exception str() failed>'


def describe(error: BaseException, code: StudentCode = StudentCode()) -> str:
    """Say what ``error`` was and the node's own line that raised it (StudentCode.origin)."""
    message = error_message(error)
    text = f'{type(error).__name__}: {message}' if message else type(error).__name__
    if isinstance(error, SystemExit):
        text = f'SystemExit (sys.exit({error.code!r}))'
    elif isinstance(error, SyntaxError):
        text = f'{type(error).__name__}: {error.msg}'  # str() has the file's name and line
        hint = invisible_character_hint(error)
        if hint:
            return f'{text}{code.origin(error)} ({hint})'
    return text + code.origin(error)


def invisible_character_hint(error: SyntaxError) -> str:
    """
    Return how to fix a line that holds a character Python refuses and nobody sees, or ''.

    Code copied from a document (the handout's is indented with no-break spaces, U+00A0) or a
    web page (zero-width spaces, U+200B) looks right and does not compile; the hint names the
    line, the character and what to replace it with.
    """
    found = INVISIBLE_CHARACTER.search(error.msg or '')
    if found is None:
        return ''
    character = chr(int(found['code'], 16))
    name = unicodedata.name(character, 'an invisible character').lower()
    blank = unicodedata.category(character) == 'Zs'
    instead = 'a space' if blank else 'nothing (delete it)'
    where = f'line {error.lineno}' if error.lineno else 'the file'
    return (f"{where} holds a {name} (U+{found['code'].upper()}), as text copied from a "
            f'document does: replace every one in the file with {instead}')


def module_file(where: str) -> str | None:
    """Return the file of the module a TARGET (without ``:ClassName``) names, when found."""
    if where.endswith('.py') or '/' in where or Path(where).is_file():
        return where
    try:
        spec = importlib.util.find_spec(_console_script_module(where) or where)
    except (ImportError, ValueError):
        return None
    return spec.origin if spec is not None and spec.has_location else None


def node_command(target: str, arguments: Iterable[str] = ()) -> str:
    """
    Return the command a person types to start TARGET's node, with ``arguments`` after it.

    ``ros2 run PACKAGE NAME`` for a console script, ``python3 FILE`` for a file (its name
    only: a report never carries the grader's paths), ``python3 -m MODULE`` for a module.
    """
    where, _ = split_target(target)
    if where.endswith('.py') or '/' in where or Path(where).is_file():
        start = f'python3 {Path(where).name}'
    else:
        entry = next(iter(entry_points(group='console_scripts', name=where)), None)
        package = entry.dist.name if entry is not None and entry.dist is not None else None
        if package:  # a ROS package's name has no '-' (REP 144); setuptools may write scan-pkg
            package = package.replace('-', '_')
        start = f'ros2 run {package} {where}' if package else f'python3 -m {where}'
    return ' '.join([start, *arguments])


def module_source(module: ModuleType) -> str:
    """Return the source text of ``module``'s file, or '' when it cannot be read."""
    try:
        return Path(module.__file__).read_text(encoding='utf-8')
    except (OSError, TypeError, UnicodeDecodeError):  # TypeError: no __file__ (a namespace)
        return ''


def node_classes(module: ModuleType, node_base: type) -> dict[str, type]:
    """Return the Node subclasses defined in ``module`` (not merely imported by it), by name."""
    return {name: value for name, value in vars(module).items()
            if inspect.isclass(value) and issubclass(value, node_base)
            and value is not node_base and value.__module__ == module.__name__}


def load_node_class(target: str, node_base: type) -> type:
    """
    Return the Node subclass TARGET names; ``node_base`` is the runtime's rclpy Node.

    Without ``:ClassName``, the module's one Node subclass; of several, the one its ``main()``
    constructs, else the one most derived (sim_bridge.runner.node_styles.node_class).
    """
    where, class_name = split_target(target)
    try:
        module = load_module(where)
    except TargetError:
        raise
    except (Exception, SystemExit) as error:  # a file that exits as it is imported
        raise TargetError(f"'{where}' fails to import: {describe(error)}",
                          module_file(where)) from error
    classes = node_classes(module, node_base)
    if class_name is not None:
        if class_name not in classes:
            raise TargetError(f"'{where}' has no Node subclass '{class_name}' "
                              f"(it has: {', '.join(classes) or 'none'})")
        return classes[class_name]
    if len(classes) > 1:  # a helper base class, or main() constructs one of several
        chosen = node_class(module_source(module))
        if chosen in classes:
            return classes[chosen]
    if len(classes) != 1:
        found = f"several: {', '.join(classes)}" if classes else 'none'
        raise TargetError(f"'{where}' must define exactly one rclpy Node subclass ({found}); "
                          f'name one with {where}:ClassName')
    return next(iter(classes.values()))


def target_name(target: str) -> str:
    """Return the name a TARGET goes by: its console script, last module part or file stem."""
    where = split_target(target)[0]
    if where.endswith('.py') or '/' in where:
        return Path(where).stem
    return where.rpartition('.')[2]
