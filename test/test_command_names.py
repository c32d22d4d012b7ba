"""
One name per command: ``./lab VERB``, and the console script ``lab_VERB`` is the same command.

Issue 35: ``./lab video`` and ``lab_video`` were two different commands, and ``lab_run`` and
``lab_grade`` had no verb. Read from ``./lab``'s dispatch and sim_bridge's setup.py.
"""

import ast
from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[1]
#: A verb of ./lab's ``main`` that execs a module: ``run) setup; exec ... -m MODULE "$@" ;;``.
VERB_LINE = re.compile(r'^\s*([a-z]+)\) setup[^;]*;.*exec "\$venv/bin/python" -m ([\w.]+)', re.M)


def lab_verbs() -> dict[str, str]:
    """Return every verb of ``./lab`` that runs a Python module, with that module."""
    return dict(VERB_LINE.findall((ROOT / 'lab').read_text()))


def console_scripts() -> dict[str, str]:
    """Return sim_bridge's console scripts (setup.py entry points), name to module."""
    tree = ast.parse((ROOT / 'sim_bridge' / 'setup.py').read_text())
    entries = next(node for node in ast.walk(tree) if isinstance(node, ast.Dict)
                   and any(getattr(key, 'value', None) == 'console_scripts'
                           for key in node.keys))
    scripts = next(value for key, value in zip(entries.keys, entries.values)
                   if key.value == 'console_scripts')
    pairs = (ast.literal_eval(item).split('=') for item in scripts.elts)
    return {name.strip(): target.strip().split(':')[0] for name, target in pairs}


def test_lab_has_a_verb_for_every_command_a_user_runs():
    assert {'demo', 'test', 'setup', 'run', 'grade', 'check', 'live', 'video',
            'autograder'} <= set(lab_verbs()) | {'test', 'setup'}


def test_each_lab_console_script_is_its_verbs_command():
    verbs = lab_verbs()
    scripts = {name: module for name, module in console_scripts().items()
               if name.startswith('lab_')}
    assert {'lab_run', 'lab_grade', 'lab_check', 'lab_video'} <= set(scripts)
    for name, module in scripts.items():
        verb = name.removeprefix('lab_')
        assert verbs.get(verb) == module, f'{name} runs {module}, ./lab {verb} runs ' \
                                          f'{verbs.get(verb)}'
