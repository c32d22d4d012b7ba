"""A student's node files found as students hand them in: flat, in a folder, a package, a zip."""

import zipfile

import pytest

from sim_bridge.grading import node_names, submission_files
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


def test_the_kits_sim_bridge_beside_the_students_package_is_not_their_work(tmp_path):
    # The handout's workspace: src/scan_pkg (theirs) and src/sim_bridge (the kit's, with its
    # worked examples, one a node named closest_obstacle).
    workspace = hand_in(tmp_path / 'ros2_ws', {
        'src/scan_pkg/package.xml': '<package format="3"><name>scan_pkg</name></package>',
        'src/scan_pkg/scan_pkg/wanderbot.py': '# mine',
        'src/sim_bridge/package.xml': '<package format="3">\n  <name>sim_bridge</name>\n',
        'src/sim_bridge/examples/closest_obstacle_from_zero.py':
            "import rclpy\nrclpy.create_node('closest_obstacle')\n",
        'src/sim_bridge/examples/wall_follow.py': '# the kit'})
    found = find_node_files(workspace, [*WANTED, 'closest_obstacle.py'], tmp_path / 'scratch')
    assert found.files == {'wanderbot.py': workspace / 'src/scan_pkg/scan_pkg/wanderbot.py'}
    assert not [seen for seen in found.seen if 'sim_bridge' in seen]


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
    submission = hand_in(tmp_path / 'sub', {'lab8.py': '', 'notes.txt': '',
                                            'src/helpers.py': ''})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert missing_text(['wanderbot.py', 'wall_follow.py'], found, WANTED, 'ana') == (
        'no wanderbot.py, wall_follow.py in ana/ (found: lab8.py, src/helpers.py; '
        'expected scan_ahead.py, wanderbot.py, scan_around.py, wall_follow.py or files named '
        'after them, at the top, in a folder, in scan_pkg/scan_pkg/ or in a zip)')
    empty = find_node_files(hand_in(tmp_path / 'empty', {}), WANTED, tmp_path / 'scratch2')
    assert 'found: no Python file;' in missing_text(['wanderbot.py'], empty, WANTED, 'ana')


#: A wall follower as a student writes it, its node named ``name``.
FOLLOWER = """import rclpy
from rclpy.node import Node


class Follower(Node):
    def __init__(self):
        super().__init__({name!r})


def main(args=None):
    rclpy.init(args=args)
    rclpy.spin(Follower())
"""
SCAN_AHEAD = FOLLOWER.format(name='scan_ahead')


@pytest.mark.parametrize('files, graded, why', [
    ({'wall_follower.py': FOLLOWER.format(name='wf')}, 'wall_follower.py', 'its name'),
    ({'WallFollow.py': FOLLOWER.format(name='wf')}, 'WallFollow.py', 'its name'),
    ({'src/wall_following_node.py': FOLLOWER.format(name='wf')},
     'src/wall_following_node.py', 'its name'),
    ({'lab4.py': FOLLOWER.format(name='wall_follower')}, 'lab4.py',
     "its node's name 'wall_follower'"),
    ({'lab4.py': 'class F(Node):\n    def __init__(self):\n'
                 "        Node.__init__(self, 'WallFollower')\n"}, 'lab4.py',
     "its node's name 'WallFollower'"),
    ({'my_pkg/setup.py': "from setuptools import setup\nsetup(entry_points={'console_scripts': "
                         "['wall_follow = my_pkg.follow_the_wall:main']})\n",
      'my_pkg/my_pkg/follow_the_wall.py': FOLLOWER.format(name='wf'),
      'my_pkg/my_pkg/wall_follower_old.py': FOLLOWER.format(name='wf')},
     'my_pkg/my_pkg/follow_the_wall.py', "my_pkg/setup.py's entry point 'wall_follow'"),
])
def test_the_file_a_student_meant_is_graded_and_said(tmp_path, files, graded, why):
    submission = hand_in(tmp_path / 'sub', {'scan_ahead.py': SCAN_AHEAD, **files})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert found.files['wall_follow.py'] == submission / graded
    assert found.files['scan_ahead.py'] == submission / 'scan_ahead.py'
    assert f'graded {graded} as wall_follow ({why})' in found.notes
    assert 'wanderbot.py' not in found.files and not found.choices


def test_a_file_is_read_as_text_never_run(tmp_path):
    marker = tmp_path / 'ran'
    submission = hand_in(tmp_path / 'sub', {
        'setup.py': f'open({str(marker)!r}, "w")\n',
        'lab.py': f'open({str(marker)!r}, "w")\nNode.__init__(self, "wall_follow")\n'})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert found.files['wall_follow.py'] == submission / 'lab.py'
    assert not marker.exists()


def test_a_file_too_large_to_parse_is_matched_by_its_name_only(tmp_path, monkeypatch):
    monkeypatch.setattr(node_names, 'MAX_PARSED_BYTES', 100)
    submission = hand_in(tmp_path / 'sub', {
        'lab.py': FOLLOWER.format(name='wall_follow') + '#' * 100,
        'wallfollower.py': '#' * 200})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert found.files['wall_follow.py'] == submission / 'wallfollower.py'


@pytest.mark.parametrize('source', ['x = ' + '-' * 200_000 + '1', 'a' + '.b' * 100_000,
                                    '(' * 100_000, '\x00not python'])
def test_a_file_that_breaks_the_parser_is_matched_by_its_name_and_stops_nothing(
        tmp_path, source):
    submission = hand_in(tmp_path / 'sub', {'wall_follower.py': source, 'lab.py': source})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert found.files == {'wall_follow.py': submission / 'wall_follower.py'}


def test_several_files_that_could_be_a_node_are_listed_in_one_line_and_none_graded(tmp_path):
    submission = hand_in(tmp_path / 'sub', {
        'scan_ahead.py': SCAN_AHEAD, 'wall_follower.py': FOLLOWER.format(name='wf'),
        'old/WallFollow.py': FOLLOWER.format(name='wf'),
        'lab4.py': FOLLOWER.format(name='wall_following')})
    found = find_node_files(submission, WANTED, tmp_path / 'scratch')
    assert 'wall_follow.py' not in found.files
    text = missing_text(['wall_follow.py'], found, WANTED, 'ana')
    assert text == ("no wall_follow.py in ana/: lab4.py (its node's name 'wall_following'), "
                    'wall_follower.py (its name), old/WallFollow.py (its name) could each be '
                    'wall_follow.py (rename the one to grade)')
    assert '\n' not in text


@pytest.mark.parametrize('name, node, same', [
    ('WallFollowingNode', 'wall_follow', True), ('wallfollower', 'wall_follow', True),
    ('lab8_wall_follows2', 'wall_follow', True), ('wander_bot', 'wanderbot', True),
    ('wanderer', 'wanderbot', False), ('scan_around', 'scan_ahead', False),
    ('ScanAhead', 'scan_ahead', True), ('node', 'wall_follow', False),
])
def test_names_are_compared_by_their_words(name, node, same):
    assert bool(node_names.name_keys(name) & node_names.name_keys(node)) == same
