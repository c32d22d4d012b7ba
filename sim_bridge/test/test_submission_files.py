"""A student's node files found as students hand them in: flat, in a folder, a package, a zip."""

import zipfile

import pytest

from sim_bridge.grading import submission_files
from sim_bridge.grading.submission_files import find_node_files, missing_text

WANTED = ['scan_ahead.py', 'wanderbot.py', 'scan_around.py', 'wall_follow.py']


def hand_in(folder, files):
    for name, text in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return folder


def zipped(path, files):
    with zipfile.ZipFile(path, 'w') as archive:
        for name, text in files.items():
            archive.writestr(name, text)
    return path


PACKAGE = {'scan_pkg/setup.py': '', 'scan_pkg/package.xml': '',
           'scan_pkg/scan_pkg/__init__.py': '', 'scan_pkg/scan_pkg/wanderbot.py': '# mine',
           'scan_pkg/scan_pkg/wall_follow.py': '# mine',
           # colcon's copy of an older build is not what the student hands in
           'build/scan_pkg/build/lib/scan_pkg/wall_follow.py': '# old'}


@pytest.mark.parametrize('layout', [
    {'wanderbot.py': '# mine', 'wall_follow.py': '# mine'},
    {'lab8_ana/wanderbot.py': '# mine', 'lab8_ana/wall_follow.py': '# mine'},
    PACKAGE,
])
def test_node_files_are_found_at_the_top_in_a_folder_or_in_the_handouts_package(tmp_path,
                                                                                layout):
    found = find_node_files(hand_in(tmp_path / 'sub', layout), WANTED, tmp_path / 'scratch')
    assert sorted(found.files) == ['wall_follow.py', 'wanderbot.py']
    assert {path.read_text() for path in found.files.values()} == {'# mine'}


def test_a_zip_of_the_package_is_unpacked_and_searched(tmp_path):
    submission = tmp_path / 'sub'
    submission.mkdir()
    zipped(submission / 'lab8.zip', PACKAGE)
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert sorted(found.files) == ['wall_follow.py', 'wanderbot.py']
    assert found.files['wanderbot.py'].is_relative_to(tmp_path / 'scratch')
    assert 'wanderbot.py: graded lab8.zip/scan_pkg/scan_pkg/wanderbot.py' in found.notes


@pytest.mark.parametrize('members, refused', [
    ({'../../escape.py': 'x'}, "its file '../../escape.py' would unpack outside it"),
    ({'/etc/escape.py': 'x'}, "its file '/etc/escape.py' would unpack outside it"),
    ({f'f{index}.py': '' for index in range(6)}, '6 files (at most 5)'),
])
def test_a_zip_that_would_unpack_outside_its_folder_or_too_much_is_refused(
        tmp_path, monkeypatch, members, refused):
    monkeypatch.setattr(submission_files, 'MAX_MEMBERS', 5)
    submission = tmp_path / 'sub'
    submission.mkdir()
    zipped(submission / 'lab8.zip', members)
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert found.files == {}
    assert found.notes == [f'lab8.zip: not unpacked: {refused}']
    assert not (tmp_path / 'escape.py').exists()


def test_a_file_that_unpacks_larger_than_the_zip_says_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(submission_files, 'MAX_FILE_BYTES', 100)
    submission = tmp_path / 'sub'
    submission.mkdir()
    zipped(submission / 'bomb.zip', {'wanderbot.py': '#' * 1000})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert found.files == {}
    assert found.notes[0].startswith('bomb.zip: not unpacked: ')


def test_a_missing_file_says_what_was_found_and_what_was_expected(tmp_path):
    submission = hand_in(tmp_path / 'sub', {'wander_bot.py': '', 'notes.txt': '',
                                            'src/wallfollower.py': ''})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert missing_text(['wanderbot.py', 'wall_follow.py'], found, WANTED, 'ana') == (
        'no wanderbot.py, wall_follow.py in ana/ (found: wander_bot.py, src/wallfollower.py; '
        'expected scan_ahead.py, wanderbot.py, scan_around.py, wall_follow.py at the top, in a '
        'folder, in scan_pkg/scan_pkg/ or in a zip)')
    empty = find_node_files(hand_in(tmp_path / 'empty', {}), WANTED, tmp_path / 'scratch2')
    assert 'found: no Python file;' in missing_text(['wanderbot.py'], empty, WANTED, 'ana')
