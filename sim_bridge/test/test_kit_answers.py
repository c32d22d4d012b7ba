"""
No run of a student's node reads an answer of the kit, in any sandbox mode.

The answers: the kit's reference nodes (the modules of scan_pkg's console scripts), the
controllers they run (``scan_pkg.behaviors``), the worked examples (``examples/``) and the
grader's own scan geometry (``sim_bridge/scoring/scan_geometry.py``; in bubblewrap only), in any
copy (a build folder, a venv) and as bytecode. fixtures/hostile/answer_hunt.py is the hostile
student: a node file that walks / and names every file it can read holding one, matched by
contents. It runs in bubblewrap, and with the dedicated uid alone (PARTLY sandboxed: as root
where namespaces are refused, a Docker container such as Gradescope's may be one), where it
sees the whole machine: there, this kit's answers (in its folder and its Python) must be closed.
"""

import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile

import pytest

from sim_bridge.runner.boundary.outside import sandbox as sandbox_module
from sim_bridge.runner.boundary.outside.kit_answers import GRADER_KEYS, reference_node_sources
from sim_bridge.runner.boundary.outside.node_sandbox import NodeSandbox
from sim_bridge.runner.boundary.outside.sandbox import (
    isolation_mode, IsolationMode, SandboxLimits)
from sim_bridge.runner.boundary.outside.sandbox_view import is_within, KIT_PACKAGE

HOSTILE = Path(__file__).resolve().parent / 'fixtures' / 'hostile'
REPOSITORY = Path(__file__).resolve().parents[2]
#: Wall seconds the hunt may take (it walks the whole machine without namespaces).
HUNT_TIMEOUT_S = 300.0


def answer_sources(kit: Path, grader_key: bool = True) -> list[Path]:
    """Return the kit's answers: reference nodes, controllers, examples, the grader's key."""
    sources = [*map(Path, reference_node_sources()), *sorted((kit / 'examples').glob('*.py')),
               *(KIT_PACKAGE / name for name in GRADER_KEYS if grader_key)]
    assert len(sources) >= 10, sources  # the five nodes, the controllers, the examples
    return sources


def hunt(tmp_path: Path, python: str, answer_hunt, kit: Path = REPOSITORY,
         grader_key: bool = True) -> dict:
    """Run the hostile node as a student's node file in its sandbox; return what it found."""
    student = tmp_path / 'student'
    student.mkdir()
    shutil.copy(HOSTILE / 'answer_hunt.py', student / 'answer_hunt.py')
    library = kit / 'scan_pkg' / 'scan_pkg' / 'report.py'
    looked_for = json.dumps(answer_hunt.wanted(answer_sources(kit, grader_key), [library]))
    where = NodeSandbox(str(student / 'answer_hunt.py'), SandboxLimits())
    with where.sandbox as box, tempfile.TemporaryFile() as output:
        status = box.popen([python, where.target, looked_for], where.environment(),
                           stdout=output, stderr=subprocess.STDOUT).wait(HUNT_TIMEOUT_S)
        output.seek(0)
        text = output.read().decode()
    assert status == 0, text
    found = json.loads(text.splitlines()[-1])
    assert found['expected'] == [str(library)], found  # it reads what a student may
    assert found['readable'] > 100, found
    return found


@pytest.mark.skipif(not isolation_mode().bwrap, reason=isolation_mode().why)
def test_in_bubblewrap_no_file_a_run_can_read_holds_an_answer(tmp_path, answer_hunt):
    assert hunt(tmp_path, sys.executable, answer_hunt)['answers'] == []


def test_partly_sandboxed_no_file_of_the_kit_a_run_can_read_holds_an_answer(
        tmp_path, shared_python, monkeypatch, answer_hunt):
    if os.geteuid() != 0:
        pytest.skip('a dedicated uid needs root')
    monkeypatch.setattr(sandbox_module, 'LAUNCHER_PYTHON', shared_python)
    monkeypatch.setattr(sandbox_module, 'isolation_mode',
                        lambda: IsolationMode('uid', 'namespaces turned off by the test'))
    # The grader's key stays readable without namespaces (kit_answers): the grader reads it.
    found = hunt(tmp_path, shared_python, answer_hunt, grader_key=False)
    # The run sees the whole machine: other checkouts of the kit are other people's files.
    assert [path for path in found['answers'] if is_within(path, [str(REPOSITORY)])] == []
