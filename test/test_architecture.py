"""
sim_bridge's shape: its sub-packages import only the layers below them, and no module is long.

The layers and the forbidden imports are the contracts of ``.importlinter`` at the top of the
repository (import-linter reads every import, those inside functions too).
"""

from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / 'sim_bridge' / 'sim_bridge'
#: The longest a module may be (lines).
MAX_MODULE_LINES = 600
#: Modules still over the limit, each at most its length now (lines): split them, never grow.
LONGER_FOR_NOW: dict[str, int] = {}


def test_the_import_contracts_are_kept():
    lint_imports = Path(sys.executable).with_name('lint-imports')
    result = subprocess.run([str(lint_imports), '--no-cache', str(ROOT / '.importlinter')],
                            cwd=ROOT.parent, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'broken' in result.stdout and '0 broken' in result.stdout


def test_no_module_is_longer_than_the_limit():
    too_long = {}
    for path in PACKAGE.rglob('*.py'):
        name = path.relative_to(PACKAGE).as_posix()
        lines = len(path.read_text().splitlines())
        if lines > LONGER_FOR_NOW.get(name, MAX_MODULE_LINES):
            too_long[name] = lines
    assert not too_long, f'modules over {MAX_MODULE_LINES} lines: {too_long}'
