"""
Every import of both packages is declared in its package.xml under a rosdep key that exists.

A ROS 2 machine installs the packages' dependencies with ``rosdep install --from-paths src``,
which reads only package.xml: a third-party module a package imports and does not declare is
missing there until a user meets the ImportError. Imports are read from the source (the AST,
imports inside functions included): the package's modules and launch files need an
``exec_depend`` (or ``depend``), its tests a ``test_depend`` or an ``exec_depend``.
IMPORT_KEYS names the key of each module; a module with no key (NO_KEY) must be in
requirements.txt instead. The keys are checked against test/rosdep_keys.txt, a record of
ros/rosdistro's keys for Jazzy on Ubuntu 24.04, and against rosdistro itself when
$ROSDISTRO_DIR names a folder with its ``base.yaml``, ``python.yaml`` and
``jazzy_packages.txt`` (the names of jazzy/distribution.yaml's packages).
"""

import ast
import os
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ElementTree

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('scan_pkg', 'sim_bridge')
#: The rosdep key of each third-party module the packages import (a ROS package's module is
#: its package name, and its key too, unless named here).
IMPORT_KEYS = {
    'numpy': 'python3-numpy', 'yaml': 'python3-yaml', 'matplotlib': 'python3-matplotlib',
    # contourpy comes with matplotlib (its dependency, in Ubuntu's package too).
    'contourpy': 'python3-matplotlib',
    'shapely': 'python3-shapely', 'collada': 'python3-collada', 'PIL': 'python3-pil',
    'jinja2': 'python3-jinja2', 'rich': 'python3-rich', 'pydantic': 'python3-pydantic',
    'pytest': 'python3-pytest', 'hypothesis': 'python3-hypothesis',
    'trimesh': 'python3-trimesh-pip', 'pybullet': 'python3-pybullet-pip',
    'rosbags': 'python3-rosbags-pip',
    # mcap-ros2-support depends on mcap, the writer and reader of the files.
    'mcap': 'mcap-ros2-support', 'mcap_ros2': 'mcap-ros2-support',
    # The Python module tf2_ros is tf2_ros_py's; the package tf2_ros is C++.
    'tf2_ros': 'tf2_ros_py',
    # URDF robots: xacro and urdfdom_py are Jazzy packages; lxml reads lenient XML.
    'xacro': 'xacro', 'urdf_parser_py': 'urdfdom_py', 'lxml': 'python3-lxml',
}
#: Modules that no rosdep key installs, and the requirement that does (requirements.txt).
NO_KEY = {'imageio_ffmpeg': 'imageio-ffmpeg'}
#: Modules whose apt package on Ubuntu 24.04 is too old for the kit, and the requirement the
#: ROS machine's venv gets instead (python3-pydantic is 1.x; the world files' models need 2).
APT_TOO_OLD = {'pydantic': 'pydantic'}
#: Test files that are student nodes, importing what a student may (or may not) have.
STUDENT_FIXTURES = 'fixtures'


def key_records() -> list[list[str]]:
    """Return test/rosdep_keys.txt's lines: key, where rosdistro defines it[, pip package]."""
    lines = (ROOT / 'test' / 'rosdep_keys.txt').read_text().splitlines()
    return [line.split() for line in lines if line and not line.startswith('#')]


def known_keys() -> dict[str, str]:
    """Return each known key and where rosdistro defines it."""
    return {record[0]: record[1] for record in key_records()}


def requirement_names(name: str) -> set[str]:
    """Return the distribution names a requirements file at the top of the workspace lists."""
    lines = (ROOT / name).read_text().splitlines()
    return {re.split(r'[<>=!~ ;\[]', line, maxsplit=1)[0].lower()
            for line in lines if line.strip() and not line.startswith(('#', '-'))}


def declared(package: str) -> dict[str, set[str]]:
    """Return the keys package.xml declares, by dependency tag (format 3)."""
    root = ElementTree.parse(ROOT / package / 'package.xml').getroot()
    assert root.get('format') == '3', f'{package}/package.xml is not package format 3'
    tags: dict[str, set[str]] = {}
    for element in root:
        tags.setdefault(element.tag, set()).add((element.text or '').strip())
    return tags


def imported_modules(path: Path) -> set[str]:
    """Return the top-level modules ``path`` imports absolutely, anywhere in the file."""
    modules = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), str(path))):
        if isinstance(node, ast.Import):
            modules.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            modules.add(node.module.split('.')[0])
    return modules


def third_party_imports(package: str, tests: bool) -> dict[str, Path]:
    """Return each third-party module imported by ``package``'s code or tests, and a file."""
    found: dict[str, Path] = {}
    for path in sorted((ROOT / package).rglob('*.py')):
        parts = path.relative_to(ROOT / package).parts
        if path.name == 'setup.py' or STUDENT_FIXTURES in parts or (parts[0] == 'test') != tests:
            continue
        for module in imported_modules(path):
            if module not in sys.stdlib_module_names and module != package:
                found.setdefault(module, path.relative_to(ROOT))
    return found


def key_of(module: str) -> str | None:
    """Return the rosdep key of ``module``, None when it has none (NO_KEY)."""
    if module in NO_KEY:
        return None
    return IMPORT_KEYS.get(module, module)


#: What each kind of code may rely on: the tags whose keys it sees, and the tag it needs.
DECLARING_TAGS = {False: (('exec_depend', 'depend'), 'exec_depend'),
                  True: (('exec_depend', 'depend', 'test_depend'), 'test_depend')}


@pytest.mark.parametrize('tests', [False, True], ids=['runtime', 'tests'])
@pytest.mark.parametrize('package', PACKAGES)
def test_every_import_is_declared(package, tests):
    """Modules and launch files need an exec_depend (or depend); tests a test_depend too."""
    tags = declared(package)
    seen, needed = DECLARING_TAGS[tests]
    available = set().union(*(tags.get(tag, set()) for tag in seen))
    missing = [f'{module} ({path}): <{needed}>{key_of(module)}</{needed}>'
               for module, path in third_party_imports(package, tests).items()
               if key_of(module) is not None and key_of(module) not in available]
    assert not missing, f'{package}/package.xml does not declare: ' + '; '.join(missing)


@pytest.mark.parametrize('package', PACKAGES)
def test_every_declared_key_exists(package):
    keys = known_keys()
    workspace = set(PACKAGES)
    unknown = sorted(key for tag in ('exec_depend', 'depend', 'test_depend', 'build_depend')
                     for key in declared(package).get(tag, set())
                     if key not in keys and key not in workspace)
    assert not unknown, (f'{package}/package.xml declares keys rosdep has no rule for on Jazzy '
                         f'(test/rosdep_keys.txt): {unknown}')


def test_modules_without_a_key_are_in_requirements():
    requirements = (ROOT / 'requirements.txt').read_text()
    imported = set().union(*(third_party_imports(package, tests)
                             for package in PACKAGES for tests in (False, True)))
    for module, requirement in NO_KEY.items():
        assert module in imported, f'NO_KEY names {module}, which nothing imports'
        assert f'\n{requirement}' in requirements, f'{requirement} is not in requirements.txt'


def test_the_ros_machine_s_pip_file_has_what_rosdep_installs_with_pip_or_cannot():
    """On Ubuntu 24.04 rosdep's pip rules fail (PEP 668): the venv gets them (docs/install.md)."""
    declared_keys = set().union(*(keys for package in PACKAGES
                                  for keys in declared(package).values()))
    pip_rules = {record[2] for record in key_records()
                 if len(record) > 2 and record[0] in declared_keys}
    assert requirement_names('requirements-ros-machine.txt') == \
        pip_rules | set(NO_KEY.values()) | set(APT_TOO_OLD.values())


def test_every_import_has_a_known_key():
    """A new import needs its key named here (IMPORT_KEYS) or in rosdep_keys.txt."""
    keys = known_keys()
    for package in PACKAGES:
        for tests in (False, True):
            for module, path in third_party_imports(package, tests).items():
                key = key_of(module)
                assert key is None or key in keys or key in PACKAGES, (
                    f'{path} imports {module}: name its rosdep key in IMPORT_KEYS (or NO_KEY) '
                    'and test/rosdep_keys.txt')


@pytest.mark.skipif('ROSDISTRO_DIR' not in os.environ, reason='set ROSDISTRO_DIR to check '
                    'test/rosdep_keys.txt against a rosdistro checkout')
def test_recorded_keys_are_rosdistros():
    rosdistro = Path(os.environ['ROSDISTRO_DIR'])
    rules = {}
    for name in ('base.yaml', 'python.yaml'):
        rules.update(yaml.safe_load((rosdistro / name).read_text()))
    jazzy = set((rosdistro / 'jazzy_packages.txt').read_text().split())
    for key, source, *pip_package in key_records():
        if source == 'jazzy':
            assert key in jazzy, f'{key} is not a package of Jazzy'
            continue
        rule = rules.get(key) or {}
        assert 'ubuntu' in rule or '*' in rule, f'{key} has no Ubuntu rule in {source}'
        ubuntu = rule.get('ubuntu', rule.get('*'))
        if pip_package:  # {'pip': {'packages': [name]}} or {'pip': [name]}
            pip = ubuntu['pip']
            assert pip_package[0] in (pip['packages'] if isinstance(pip, dict) else pip), key
