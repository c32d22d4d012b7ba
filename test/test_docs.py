"""
README.md and docs/ name only what exists, and each command has one name (issue 35).

Every relative link reaches a file, and an anchor a heading of it; every ``./lab VERB`` is a verb
of ``./lab``; every ``python -m X`` names a module the venv imports; every console script named
(``.venv/bin/X``, ``ros2 run PKG X``, ``lab_X``) is an entry point of the packages' setup.py.
The console script ``lab_VERB`` is the command ``./lab VERB`` runs (``./lab video`` and
``lab_video`` were two different commands; ``lab_run`` and ``lab_grade`` had no verb).
"""

import ast
import importlib.util
from pathlib import Path
import re

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
#: A verb of ./lab's ``main`` that execs a module: ``run) setup; exec ... -m MODULE "$@" ;;``.
VERB_MODULE = re.compile(r'^\s*([a-z]+)\) setup[^;]*;.*exec "\$venv/bin/python" -m ([\w.]+)',
                         re.M)
#: Every label of ./lab's ``case "$command"``: ``demo)``, ``-h|--help|help)``.
VERB_LABEL = re.compile(r'^ {8}([\w|-]+)\)', re.M)
LINK = re.compile(r'\[[^\]]*\]\(([^)\s]+)\)')
LAB_COMMAND = re.compile(r'\./lab ([a-z][\w-]*)')
PYTHON_MODULE = re.compile(r'python3? -m ([A-Za-z_]\w*(?:\.\w+)*)')
VENV_SCRIPT = re.compile(r'\.venv/bin/([A-Za-z_][\w-]*)')
ROS2_RUN = re.compile(r'ros2 run (scan_pkg|sim_bridge) ([A-Za-z_]\w*)')
LAB_SCRIPT = re.compile(r'`(lab_[a-z]+)`')
#: What .venv/bin holds besides the packages' console scripts.
VENV_TOOLS = {'python', 'python3', 'pip', 'activate', 'colcon', 'pytest'}


def lab_verbs() -> dict[str, str]:
    """Return every verb of ``./lab`` that runs a Python module, with that module."""
    return dict(VERB_MODULE.findall((ROOT / 'lab').read_text()))


def lab_labels() -> set[str]:
    """Return every word ``./lab`` takes as its first argument."""
    labels = VERB_LABEL.findall((ROOT / 'lab').read_text())
    return {word for label in labels for word in label.split('|')} - {'*'}


def console_scripts(package: str) -> dict[str, str]:
    """Return a package's console scripts (its setup.py entry points), name to module."""
    tree = ast.parse((ROOT / package / 'setup.py').read_text())
    entries = next(node for node in ast.walk(tree) if isinstance(node, ast.Dict)
                   and any(getattr(key, 'value', None) == 'console_scripts'
                           for key in node.keys))
    scripts = next(value for key, value in zip(entries.keys, entries.values)
                   if key.value == 'console_scripts')
    pairs = (ast.literal_eval(item).split('=') for item in scripts.elts)
    return {name.strip(): target.strip().split(':')[0] for name, target in pairs}


def heading_anchors(page: Path) -> set[str]:
    """Return the anchors GitHub makes of a Markdown page's headings (outside code blocks)."""
    anchors, seen, in_code = set(), {}, False
    for line in page.read_text().splitlines():
        if line.startswith('```'):
            in_code = not in_code
        if in_code or not re.match(r'#+ ', line):
            continue
        slug = re.sub(r'[^\w\- ]', '', line.lstrip('#').strip().lower()).replace(' ', '-')
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        anchors.add(slug if count == 0 else f'{slug}-{count}')
    return anchors


def named(pattern: re.Pattern) -> list[tuple[str, str]]:
    """Return (page, match) for every match of ``pattern`` in README.md and docs/."""
    return [(page.relative_to(ROOT).as_posix(), match)
            for page in DOCS for match in pattern.findall(page.read_text())]


def test_the_docs_are_the_readme_and_a_page_per_reader():
    assert {page.name for page in DOCS} >= {
        'README.md', 'students.md', 'instructors.md', 'simulator.md', 'grading.md',
        'internals.md'}


def test_every_relative_link_reaches_a_file_and_its_anchor():
    broken = []
    for page in DOCS:
        for target in LINK.findall(page.read_text()):
            if re.match(r'[a-z]+:', target):
                continue  # https:, mailto:
            path, _, anchor = target.partition('#')
            linked = (page.parent / path).resolve() if path else page
            if not linked.exists():
                broken.append(f'{page.name}: {target}: no such file')
            elif anchor and linked.suffix == '.md' and anchor not in heading_anchors(linked):
                broken.append(f'{page.name}: {target}: no such heading')
    assert broken == []


def test_every_lab_command_named_is_a_verb_of_lab():
    labels = lab_labels()
    assert [(page, verb) for page, verb in named(LAB_COMMAND) if verb not in labels] == []


def test_every_python_module_named_imports():
    modules = {module for _, module in named(PYTHON_MODULE)}
    assert modules and [m for m in sorted(modules) if importlib.util.find_spec(m) is None] == []


def test_every_console_script_named_is_an_entry_point():
    scripts = {**console_scripts('scan_pkg'), **console_scripts('sim_bridge')}
    found = named(VENV_SCRIPT) + [(page, match[1]) for page, match in named(ROS2_RUN)] \
        + named(LAB_SCRIPT)
    unknown = [(page, name) for page, name in found
               if name not in scripts and name not in VENV_TOOLS]
    assert found and unknown == []


def test_lab_has_a_verb_for_every_command_a_user_runs():
    assert {'demo', 'test', 'setup', 'run', 'grade', 'check', 'live', 'video', 'autograder',
            'record'} <= lab_labels()


@pytest.mark.parametrize('script', ['lab_run', 'lab_grade', 'lab_check', 'lab_video'])
def test_each_lab_console_script_is_its_verbs_command(script):
    module = console_scripts('sim_bridge')[script]
    assert lab_verbs().get(script.removeprefix('lab_')) == module
