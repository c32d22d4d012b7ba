"""Tests of finding worlds and models in a checkout, an install, and Gazebo's model paths."""

from argparse import ArgumentTypeError
from pathlib import Path
import subprocess
import sys

import pytest

from sim_bridge.common import paths


def test_a_source_checkout_finds_its_own_worlds_and_models():
    root = paths.repo_root()
    assert root is not None
    assert paths.worlds_dir() == root / 'worlds'
    assert paths.models_dir() == root / 'models'
    assert {'obstacles', 'room'} <= set(paths.world_names())


def test_a_pip_install_finds_the_share_directory_under_its_prefix(tmp_path, monkeypatch):
    (tmp_path / 'share' / 'sim_bridge' / 'worlds').mkdir(parents=True)
    monkeypatch.setattr(sys, 'prefix', str(tmp_path))
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.setattr(paths, 'repo_root', lambda: None)
    assert paths.share_dir() == tmp_path / 'share' / 'sim_bridge'
    assert paths.worlds_dir() == tmp_path / 'share' / 'sim_bridge' / 'worlds'


def test_a_checkout_needs_no_sourced_workspace_with_ament_index_python_installed(monkeypatch):
    pytest.importorskip('ament_index_python')
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    assert paths.worlds_dir() == paths.repo_root() / 'worlds'
    assert paths.find_world('room').is_file()


def test_a_colcon_install_is_found_through_the_ament_index(tmp_path, monkeypatch):
    pytest.importorskip('ament_index_python')
    prefix = tmp_path / 'install' / 'sim_bridge'
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'sim_bridge'
    marker.parent.mkdir(parents=True)
    marker.write_text('')
    (prefix / 'share' / 'sim_bridge' / 'worlds').mkdir(parents=True)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    monkeypatch.setattr(paths, 'repo_root', lambda: None)
    assert paths.worlds_dir() == prefix / 'share' / 'sim_bridge' / 'worlds'


def test_no_install_and_no_checkout_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, 'prefix', str(tmp_path))
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.setattr(paths, 'repo_root', lambda: None)
    with pytest.raises(FileNotFoundError, match="cannot find the 'models' folder"):
        paths.models_dir()


def test_find_world_takes_a_name_or_a_path_and_names_the_shipped_worlds(tmp_path):
    assert paths.find_world('room') == paths.worlds_dir() / 'room.yaml'
    custom = tmp_path / 'mine.yaml'
    custom.write_text('name: mine\n')
    assert paths.find_world(str(custom)) == custom
    with pytest.raises(FileNotFoundError, match='shipped worlds are .*obstacles'):
        paths.find_world('atlantis')
    with pytest.raises(FileNotFoundError, match='world file not found'):
        paths.find_world(str(tmp_path / 'missing.yaml'))


def test_models_are_also_found_on_gazebos_resource_path(tmp_path, monkeypatch):
    model = tmp_path / 'my_crate'
    model.mkdir()
    (model / 'model.sdf').write_text('<sdf version="1.8"/>')
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path))
    assert paths.find_model('my_crate') == model
    assert paths.find_model('obstacle_box') == paths.models_dir() / 'obstacle_box'
    with pytest.raises(FileNotFoundError, match="model 'nothing' not found"):
        paths.find_model('nothing')
    assert Path(tmp_path) in paths.model_search_path()


def test_an_output_folder_that_is_a_file_is_a_one_line_command_line_error(tmp_path):
    """``./lab demo --out FILE`` and ``python -m sim_bridge.grade --out FILE``, say."""
    a_file = tmp_path / 'notes.txt'
    a_file.write_text('')
    assert paths.output_folder(str(tmp_path / 'new' / 'out')) == tmp_path / 'new' / 'out'
    assert paths.output_folder(str(tmp_path)) == tmp_path
    for out in (a_file, a_file / 'out'):
        with pytest.raises(ArgumentTypeError, match=f'{a_file} is a file, not a folder'):
            paths.output_folder(str(out))
    for program in (['sim_bridge.commands.demo', '--no-live'],
                    ['sim_bridge.grade', str(tmp_path)]):
        done = subprocess.run([sys.executable, '-m', *program, '--out', str(a_file / 'out')],
                              capture_output=True, text=True, timeout=60)
        assert done.returncode == 2 and 'Traceback' not in done.stderr
        assert done.stderr.splitlines()[-1].endswith(
            f'error: argument --out: {a_file} is a file, not a folder: name a folder for the '
            'outputs')


def test_models_are_searched_in_gazebos_order_with_the_kits_folder_last(tmp_path, monkeypatch):
    folders = {name: tmp_path / name for name in ('world', 'gz', 'ign', 'classic', 'home')}
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(folders['gz']))
    monkeypatch.setenv('IGN_GAZEBO_RESOURCE_PATH', str(folders['ign']))
    monkeypatch.setenv('GAZEBO_MODEL_PATH', str(folders['classic']))
    monkeypatch.setenv('HOME', str(folders['home']))
    assert paths.model_search_path(folders['world']) == [
        folders['world'], folders['gz'], folders['ign'], folders['classic'],
        folders['home'] / '.gazebo' / 'models', folders['home'] / '.gz' / 'models',
        paths.models_dir()]
    # The kit's TurtleBot3 gives way to one on the user's paths (ROBOTIS's real folder).
    assert paths.find_model('turtlebot3_burger') == paths.models_dir() / 'turtlebot3_burger'
    theirs = folders['home'] / '.gz' / 'models' / 'turtlebot3_burger'
    theirs.mkdir(parents=True)
    (theirs / 'model.config').write_text('<model><sdf version="1.8">model.sdf</sdf></model>')
    assert paths.find_model('turtlebot3_burger') == theirs
    assert paths.find_model('turtlebot3_burger', folders['world']) == theirs


def test_find_world_takes_gazebo_world_files_by_name_or_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ('lab.world', 'lab.sdf'):
        (tmp_path / name).write_text('<sdf/>')
        assert paths.find_world(name) == Path(name)
