"""
Find the rclpy Node class a runner TARGET names: a console script, a module or a file.

TARGET forms: ``wall_follow`` (a console script, as ``ros2 run`` knows it),
``scan_pkg.wall_follow`` (a module), ``path/to/node.py`` (any file, run as written); each
optionally followed by
``:ClassName`` when the module defines several Node subclasses. A path that exists is a path,
whatever it holds (``col:on/node.py``). Modules are imported as they are, with the rclpy of
this Python (a sourced ROS 2 Jazzy, or the PyPI wheels).
"""

from importlib import import_module
from importlib.metadata import entry_points
import importlib.util
import inspect
from pathlib import Path
import sys
import traceback
from types import ModuleType


class TargetError(LookupError):
    """A TARGET that names no loadable module or no rclpy Node subclass in it."""


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
    except Exception:
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


def import_failure(error: Exception) -> str:
    """Describe an exception raised while importing a TARGET, with where it was raised."""
    if isinstance(error, SyntaxError):
        return f'{type(error).__name__}: {error}'
    frame = traceback.extract_tb(error.__traceback__)[-1]
    return f'{type(error).__name__}: {error} ({frame.filename}:{frame.lineno})'


def node_classes(module: ModuleType, node_base: type) -> dict[str, type]:
    """Return the Node subclasses defined in ``module`` (not merely imported by it), by name."""
    return {name: value for name, value in vars(module).items()
            if inspect.isclass(value) and issubclass(value, node_base)
            and value is not node_base and value.__module__ == module.__name__}


def load_node_class(target: str, node_base: type) -> type:
    """Return the Node subclass TARGET names; ``node_base`` is the runtime's rclpy Node."""
    where, class_name = split_target(target)
    try:
        module = load_module(where)
    except TargetError:
        raise
    except Exception as error:
        raise TargetError(f"'{where}' fails to import: {import_failure(error)}") from error
    classes = node_classes(module, node_base)
    if class_name is not None:
        if class_name not in classes:
            raise TargetError(f"'{where}' has no Node subclass '{class_name}' "
                              f"(it has: {', '.join(classes) or 'none'})")
        return classes[class_name]
    if len(classes) != 1:
        found = f"several: {', '.join(classes)}" if classes else 'none'
        raise TargetError(f"'{where}' must define exactly one rclpy Node subclass ({found}); "
                          f'name one with {where}:ClassName')
    return next(iter(classes.values()))
