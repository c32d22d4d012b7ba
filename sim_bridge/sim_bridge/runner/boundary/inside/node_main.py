"""
Start a TARGET in the node's process as ``ros2 run`` or ``python3`` would (for the agent).

Its module code runs, then its ``__main__`` block or ``main()``; a console script its entry
point; a file of Node classes alone (or ``FILE:Class``) the class, spun by a canonical main.
Imported only in a node's process (sim_bridge.runner.boundary.inside.agent), never on the trusted
side.
"""

import ast
from importlib.metadata import entry_points
from pathlib import Path
import sys
from types import ModuleType
from typing import Any, Callable

#: Longest traceback text (characters) sent with a node's error.
MAX_TRACEBACK_CHARS = 32_000


def _file_main(path: str) -> Callable[[], Any]:
    """
    Run the node file's module code now, as ``python3 FILE`` does; return what starts it.

    Its ``if __name__ == '__main__'`` block (run with what follows it), else its ``main()``;
    None when it has neither.
    """
    from sim_bridge.runner.node_styles import has_main_guard
    source = Path(path).read_bytes()
    tree = ast.parse(source, path)
    guards = [index for index, statement in enumerate(tree.body)
              if has_main_guard(ast.unparse(statement))]
    if not guards and not any(isinstance(statement, ast.FunctionDef) and statement.name == 'main'
                              for statement in tree.body):
        return None  # a module of Node classes: the class is loaded and spun
    module = ModuleType('__main__' if guards else 'node_file')
    module.__file__ = path
    sys.modules[module.__name__] = module
    split = guards[0] if guards else len(tree.body)
    exec(compile(ast.Module(tree.body[:split], []), path, 'exec'), vars(module))
    if guards:
        rest = compile(ast.Module(tree.body[split:], []), path, 'exec')
        return lambda: exec(rest, vars(module))
    return getattr(module, 'main', None)


def prepare(target: str) -> tuple[Callable[[], Any], str | None]:
    """
    Import TARGET as ``ros2 run`` / ``python3`` would; return what starts it, and its file.

    A file: its module code runs now, then its ``__main__`` block or ``main()``; a console
    script: its entry point; a module: its ``main()``. ``FILE:Class``, or a file of Node
    classes alone: the class, spun by a canonical main (``rclpy.init``, ``rclpy.spin``).
    """
    from sim_bridge.runner.targets import (
        load_module, load_node_class, module_file, split_target, TargetError)
    where, class_name = split_target(target)
    path = module_file(where)
    start = None
    if class_name is None and (where.endswith('.py') or '/' in where or Path(where).is_file()):
        if path is None or not Path(path).is_file():
            raise TargetError(f'node file not found: {where}')
        sys.path.insert(0, str(Path(path).resolve().parent))
        start = _file_main(path)
    elif class_name is None:
        scripts = entry_points(group='console_scripts', name=where)
        start = next(iter(scripts)).load() if scripts else getattr(
            load_module(where), 'main', None)
    if start is None:
        from rclpy.node import Node
        node_class = load_node_class(target, Node)

        def start() -> None:
            import rclpy
            rclpy.init()
            rclpy.spin(node_class())
    return start, path


def start_failure(target: str, error: BaseException, code) -> dict:
    """Return the ended frame's fields of TARGET failing to start: RunError on the trusted side."""
    from sim_bridge.runner.targets import describe, split_target, TargetError
    cause = error.__cause__ if isinstance(error, TargetError) else error
    if isinstance(error, TargetError):  # load_node_class's own words
        message = str(error)
    else:
        message = f"'{split_target(target)[0]}' fails to import: {describe(error, code)}"
    if cause is None:
        return {'status': 'start', 'error': message}
    return {'status': 'start', 'error': message,
            'traceback': code.traceback(cause)[-MAX_TRACEBACK_CHARS:]}
