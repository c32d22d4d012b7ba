"""
Read a node file's source for what the runner needs before anything of it runs.

Which Node subclass a file runs (of several, the one its ``main()`` constructs, else the most
derived: a course's helper base class is not the node), and whether it has an ``if __name__ ==
'__main__'`` block. No rclpy here: plain source text in, an answer out.
"""

import ast


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


def has_main_guard(source: str) -> bool:
    """Tell whether ``source`` has an ``if __name__ == '__main__'`` block (False: no parse)."""
    try:
        return any(map(_is_main_guard, ast.parse(source).body))
    except (SyntaxError, ValueError):
        return False
