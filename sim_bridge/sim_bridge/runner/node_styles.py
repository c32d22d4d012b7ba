"""
Decide, from a node file's source alone, whether the runner may step it or must run it as written.

A stepped run (sim_bridge.runner.stepping) constructs the file's one Node subclass in the runner's
own executor: faithful only when the file's ``main()`` (or its ``if __name__ == '__main__'`` block)
does nothing but ``rclpy.init``, construct that class, spin it, destroy it and shut down, and no
callback sleeps (a sleep in a stepped run freezes simulated time). Anything else (a loop of
``spin_once``, a MultiThreadedExecutor, a node built by ``rclpy.create_node`` or ``Node('...')``,
several nodes, a sleep in a callback) only runs as its author meant when its own ``main()`` runs.
No rclpy here: plain source text in, a decision out.
"""

import ast
from typing import NamedTuple

#: A sleep in a callback at least this long (s) is a hang, not pacing: the stepped run's
#: watchdog names the line it hangs at, which is what a grader wants to see.
HANG_SLEEP_S = 10.0
#: The calls that register a callback on a node, with the index of the callback argument.
CALLBACK_ARGUMENT = {'create_timer': 1, 'create_wall_timer': 1, 'create_subscription': 2,
                     'create_service': 2}


class Decision(NamedTuple):
    """Whether a file allows stepping, and why not in one line (the first reason found)."""

    steppable: bool
    reason: str


def _call_name(node: ast.Call) -> str:
    """Return the called name: ``spin_once`` for ``rclpy.spin_once(...)``, ``Node`` for Node()."""
    function = node.func
    if isinstance(function, ast.Attribute):
        return function.attr
    return function.id if isinstance(function, ast.Name) else ''


def _is_node_base(base: ast.expr) -> bool:
    return (isinstance(base, ast.Name) and base.id == 'Node'
            or isinstance(base, ast.Attribute) and base.attr == 'Node')


def _is_main_guard(statement: ast.stmt) -> bool:
    test = getattr(statement, 'test', None)
    return (isinstance(statement, ast.If) and isinstance(test, ast.Compare)
            and isinstance(test.left, ast.Name) and test.left.id == '__name__'
            and any(isinstance(c, ast.Constant) and c.value == '__main__'
                    for c in test.comparators))


def _sleep_seconds(call: ast.Call) -> float | None:
    """Return a ``time.sleep(S)`` call's constant S (s), inf when not a constant."""
    if _call_name(call) != 'sleep' or not call.args:
        return None
    if isinstance(call.func, ast.Attribute) and not (
            isinstance(call.func.value, ast.Name) and call.func.value.id == 'time'):
        return None  # rate.sleep(), asyncio.sleep(): not the time module's
    argument = call.args[0]
    if isinstance(argument, ast.Constant) and isinstance(argument.value, (int, float)):
        return float(argument.value)
    return float('inf')


def _entry_reason(entry: list[ast.stmt], node_classes: set[str]) -> str | None:
    """Return why the entry code (main() and the __main__ block) cannot be stepped, or None."""
    for statement in entry:
        where = 'main()' if isinstance(statement, ast.FunctionDef) else 'the __main__ block'
        for item in ast.walk(statement):
            if isinstance(item, (ast.While, ast.For)):
                body_calls = {_call_name(c) for c in ast.walk(item) if isinstance(c, ast.Call)}
                if 'spin_once' in body_calls:
                    return f'{where} loops on rclpy.spin_once (line {item.lineno})'
                return f'{where} runs a loop of its own (line {item.lineno})'
            if not isinstance(item, ast.Call):
                continue
            name = _call_name(item)
            if name == 'MultiThreadedExecutor':
                return f'{where} spins a MultiThreadedExecutor (line {item.lineno})'
            if name in ('create_node', 'Node'):
                return (f'{where} builds its node with {ast.unparse(item.func)}(...) '
                        f'(line {item.lineno}), not a Node subclass')
            if name in ('spin_once', 'spin_until_future_complete'):
                return f'{where} calls {name} (line {item.lineno})'
            if _sleep_seconds(item) is not None:
                return f'{where} sleeps (line {item.lineno})'
    constructed = _constructed(entry, node_classes)
    if len(constructed) > 1:
        lines = ', '.join(str(call.lineno) for call in constructed)
        return f'main() starts several nodes (lines {lines})'
    return None


def _constructed(entry: list[ast.stmt], node_classes: set[str]) -> list[ast.Call]:
    """Return the calls in the entry code that construct one of ``node_classes``."""
    return [item for statement in entry for item in ast.walk(statement)
            if isinstance(item, ast.Call) and _call_name(item) in node_classes]


def _node_classes(tree: ast.Module) -> list[ast.ClassDef]:
    """
    Return the file's Node subclasses, in the file's order.

    A class derived from Node, or from another of them (a helper base class of the course's:
    ``class Avoider(LaserNode)``).
    """
    classes = [s for s in tree.body if isinstance(s, ast.ClassDef)]
    names: set[str] = set()
    while True:
        found = {c.name for c in classes if any(
            _is_node_base(base) or isinstance(base, ast.Name) and base.id in names
            for base in c.bases)}
        if found == names:
            return [c for c in classes if c.name in names]
        names = found


def _most_derived(classes: list[ast.ClassDef]) -> list[ast.ClassDef]:
    """Return the classes of ``classes`` that no other of them derives from."""
    bases = {base.id for c in classes for base in c.bases if isinstance(base, ast.Name)}
    return [c for c in classes if c.name not in bases]


def _entry(tree: ast.Module) -> list[ast.stmt]:
    """Return the file's entry code: its ``__main__`` block and its ``main()``."""
    entry = [s for s in tree.body if _is_main_guard(s)]
    return entry + [s for s in tree.body if isinstance(s, ast.FunctionDef) and s.name == 'main']


def _chosen_class(tree: ast.Module) -> str | None:
    """
    Return the Node subclass the file runs: the one its entry code constructs, once.

    Without such a call, the file's one most-derived Node subclass; None when it has none, or
    several and nothing says which.
    """
    classes = _node_classes(tree)
    constructed = {_call_name(call)
                   for call in _constructed(_entry(tree), {c.name for c in classes})}
    candidates = constructed or {c.name for c in _most_derived(classes)}
    return next(iter(candidates)) if len(candidates) == 1 else None


def node_class(source: str) -> str | None:
    """
    Return the name of the Node subclass the node file ``source`` runs, or None.

    The one its ``main()`` (or ``__main__`` block) constructs, else its one most-derived Node
    subclass (a base class of helpers is not the node); None when the file does not parse.
    """
    try:
        return _chosen_class(ast.parse(source))
    except (SyntaxError, ValueError):
        return None


def _methods(node_class: ast.ClassDef, classes: dict[str, ast.ClassDef],
             seen: frozenset[str] = frozenset()) -> dict[str, ast.FunctionDef]:
    """Return ``node_class``'s methods by name, with those it inherits from ``classes``."""
    methods = {}
    seen = seen | {node_class.name}
    for base in node_class.bases:
        if isinstance(base, ast.Name) and base.id in classes and base.id not in seen:
            methods.update(_methods(classes[base.id], classes, seen))
    methods.update((f.name, f) for f in node_class.body if isinstance(f, ast.FunctionDef))
    return methods


def _callback_sleep(node_class: ast.ClassDef, classes: dict[str, ast.ClassDef]) -> str | None:
    """
    Return why a callback of ``node_class`` that sleeps cannot be stepped, or None.

    Its methods include those it inherits from ``classes`` (the file's other Node subclasses).
    """
    methods = _methods(node_class, classes)
    callbacks = set()
    for call in (c for method in methods.values() for c in ast.walk(method)):
        index = CALLBACK_ARGUMENT.get(_call_name(call)) if isinstance(call, ast.Call) else None
        if index is not None and len(call.args) > index:
            callback = call.args[index]
            if isinstance(callback, ast.Attribute) and callback.attr in methods:
                callbacks.add(callback.attr)
    for name in sorted(callbacks):
        for call in ast.walk(methods[name]):
            seconds = _sleep_seconds(call) if isinstance(call, ast.Call) else None
            if seconds is not None and seconds < HANG_SLEEP_S:
                return (f'the callback {name}() calls time.sleep (line {call.lineno}): sleeping '
                        'freezes simulated time in a stepped run')
    return None


def has_main_guard(source: str) -> bool:
    """Tell whether ``source`` has an ``if __name__ == '__main__'`` block (False: no parse)."""
    try:
        return any(map(_is_main_guard, ast.parse(source).body))
    except (SyntaxError, ValueError):
        return False


def decide(source: str) -> Decision:
    """
    Return whether the node file ``source`` allows stepping, with a one-line reason.

    A file without ``main()`` or ``__main__`` block (a module of Node classes) and a file that
    does not parse (the loader then reports the syntax error) allow stepping.
    """
    try:
        tree = ast.parse(source)
    except (SyntaxError, ValueError):
        return Decision(True, 'the file does not parse: the loader says why')
    classes = _node_classes(tree)
    entry = _entry(tree)
    if not entry:
        return Decision(True, 'no main(): its Node subclass is stepped')
    reason = _entry_reason(entry, {c.name for c in classes})
    chosen = _chosen_class(tree)
    if reason is None and chosen is None:
        leaves = _most_derived(classes)
        reason = (f'it defines {len(leaves)} Node subclasses' if leaves
                  else 'it defines no Node subclass')
        reason += ': main() decides what runs'
    by_name = {c.name: c for c in classes}
    for name in by_name:
        reason = reason or _callback_sleep(by_name[name], by_name)
    if reason is not None:
        return Decision(False, reason)
    if len(classes) == 1:
        return Decision(True, 'main() only spins its one Node subclass')
    return Decision(True, f'main() only spins its Node subclass {chosen}')
