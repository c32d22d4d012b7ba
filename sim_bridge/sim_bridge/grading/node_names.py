"""
Which of a submission's Python files a student meant for a node of the lab, when none has its name.

Students name their files their own way (``wall_follower.py``, ``WallFollow.py``,
``wall_following_node.py`` for the lab's ``wall_follow``), name their node
(``super().__init__('wall_follower')``) and, in the handout's package, give ``setup.py`` an
entry point (``'wall_follow = scan_pkg.wall_follower:main'``). :func:`candidates` reads those
as text only: file names, and Python's :mod:`ast` of files of at most MAX_PARSED_BYTES (at
most MAX_PARSED_FILES of them); nothing a student wrote is imported or executed. Names are
compared by :func:`name_keys`: their words, lower case, without endings (``-er``, ``-ing``,
``-s``), digits and filler words (``node``, ``my``, ``lab``, ``task``). Plain files: no rclpy.
"""

import ast
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
import re

from sim_bridge.common.text import printable

#: Python files larger than this (bytes) are matched by their names only, never parsed.
MAX_PARSED_BYTES = 256 * 1024
#: At most this many files of a submission are parsed (the shallowest first).
MAX_PARSED_FILES = 200
#: Words of a name that say nothing of which node it is.
FILLER_WORDS = frozenset({'node', 'nodes', 'my', 'lab', 'task', 'ros', 'ros2', 'py', 'main',
                          'final', 'new', 'v'})
#: Endings of a word left out when names are compared: follow, follower, following, follows.
ENDINGS = ('ing', 'er', 's')
#: The shortest word left once an ending is taken off it (so 'ros' keeps its 's').
MIN_STEM_CHARS = 4
#: The most characters of a student's node or script name a reason quotes.
QUOTED_CHARS = 60
#: A setup.py string naming a console script: 'wall_follow = scan_pkg.wall_follower:main'.
ENTRY_POINT = re.compile(r'\s*(?P<script>[\w.-]+)\s*=\s*(?P<module>[A-Za-z_][\w.]*)\s*:'
                         r'\s*[A-Za-z_]\w*\s*')
#: The words of a name: 'WallFollowingNode', 'wall_follower', 'HTTPNode2'.
WORDS = re.compile(r'[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+')


@dataclass(frozen=True)
class Candidate:
    """A file that could be a node: its path, how reports show it, and why it could be it."""

    path: Path
    shown: str
    why: str


def stem(word: str) -> str:
    """Return ``word`` without one of ENDINGS ('follower' -> 'follow'), if long enough."""
    for ending in ENDINGS:
        if word.endswith(ending) and len(word) - len(ending) >= MIN_STEM_CHARS:
            return word[:-len(ending)]
    return word


def name_keys(name: str) -> frozenset[str]:
    """
    Return what a file, node or script name says of the node it is ({'wallfollow'}).

    Its words (lower case, no digits or FILLER_WORDS) joined, each without its ending, and
    the joined words without the last one's: 'wander_bot' and 'wanderbot' share 'wanderbot',
    'wall_follower' and 'wallfollower' 'wallfollow'. Names are the same node's when their
    keys meet; a name of filler words only has none.
    """
    words = [word.lower() for word in WORDS.findall(name)]
    words = [word for word in words if word not in FILLER_WORDS and not word.isdigit()]
    if not words:
        return frozenset()
    return frozenset({''.join(map(stem, words)), stem(''.join(words))})


def quoted(name: str) -> str:
    """Return a student's name quoted for a reason: printable, at most QUOTED_CHARS."""
    shown = printable(name)
    return repr(shown if len(shown) <= QUOTED_CHARS else shown[:QUOTED_CHARS - 3] + '...')


def parsed(path: Path) -> ast.Module | None:
    """Return the syntax tree of a Python file, or None when too large or not Python."""
    try:
        with open(path, 'rb') as file:
            source = file.read(MAX_PARSED_BYTES + 1)
        if len(source) > MAX_PARSED_BYTES:
            return None
        return ast.parse(source, filename=path.name)
    except (OSError, SyntaxError, ValueError, RecursionError, MemoryError):
        return None


def node_names(tree: ast.Module) -> list[str]:
    """
    Return the node names a file gives: ``super().__init__('n')``, ``Node.__init__(self, 'n')``.

    Also ``Node('n')``, ``rclpy.create_node('n')`` and ``node_name='n'`` in those calls.
    """
    names = []
    for call in ast.walk(tree):
        if not isinstance(call, ast.Call):
            continue
        function = call.func
        called = function.attr if isinstance(function, ast.Attribute) else getattr(
            function, 'id', '')
        if called not in ('__init__', 'Node', 'create_node'):
            continue
        given = [argument for argument in call.args if not isinstance(argument, ast.Name)]
        given += [keyword.value for keyword in call.keywords if keyword.arg == 'node_name']
        if given and isinstance(given[0], ast.Constant) and isinstance(given[0].value, str):
            names.append(given[0].value)
    return names


def entry_points(tree: ast.Module) -> list[tuple[str, str]]:
    """Return (script, module) of each console script a ``setup.py`` names in its strings."""
    return [(match['script'], match['module']) for constant in ast.walk(tree)
            if isinstance(constant, ast.Constant) and isinstance(constant.value, str)
            for match in [ENTRY_POINT.fullmatch(constant.value)] if match]


def syntax_trees(files: list[tuple[str, Path]]) -> dict[Path, ast.Module | None]:
    """Return the syntax tree of each of the first MAX_PARSED_FILES ``files`` (see parsed)."""
    return {path: parsed(path) for _, path in files[:MAX_PARSED_FILES]}


def candidates(files: list[tuple[str, Path]], node: str,
               trees: dict[Path, ast.Module | None]) -> list[Candidate]:
    """
    Return the files of ``files`` ((shown path, path), shallowest first) that could be ``node``.

    A ``setup.py`` entry point of the node's name decides alone (the module it names, when
    that file is among ``files``); otherwise each file whose name, or a node name it gives,
    is the node's (:func:`name_keys`), once. ``trees``: the files' :func:`syntax_trees`.
    """
    keys = name_keys(node)
    if not keys:
        return []
    by_path = {path: shown for shown, path in files}
    named = []
    for shown, path in files:
        tree = trees.get(path)
        if path.name != 'setup.py' or tree is None:
            continue
        for script, module in entry_points(tree):
            target = path.parent / PurePosixPath(*module.split('.')).with_suffix('.py')
            if keys & name_keys(script) and target in by_path:
                named.append(Candidate(target, by_path[target],
                                       f"{shown}'s entry point {quoted(script)}"))
    if named:
        return list({candidate.path: candidate for candidate in named}.values())
    found = []
    for shown, path in files:
        if keys & name_keys(path.stem):
            found.append(Candidate(path, shown, 'its name'))
            continue
        given = [name for name in node_names(trees[path]) if keys & name_keys(name)] \
            if trees.get(path) is not None else []
        if given:
            found.append(Candidate(path, shown, f"its node's name {quoted(given[0])}"))
    return found
