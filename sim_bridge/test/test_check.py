"""``./lab check``: a student's own folder graded on the shipped scenarios, marks and why lost."""

from pathlib import Path
import shutil

from sim_bridge.commands import check
from sim_bridge.common.paths import scenarios_dir

SCAN_AHEAD = Path(__file__).resolve().parents[2] / 'scan_pkg' / 'scan_pkg' / 'scan_ahead.py'


def test_check_prints_each_tasks_marks_and_every_lost_point_in_the_pages_words(
        tmp_path, capsys):
    folder = tmp_path / 'my_pkg'
    folder.mkdir()
    shutil.copyfile(SCAN_AHEAD, folder / 'scan_ahead.py')  # no scan_around.py yet
    out = tmp_path / 'out'
    status = check.main([str(folder), '--out', str(out), '--jobs', '1',
                         '--scenario', str(scenarios_dir() / 'scan_ahead.yaml'),
                         '--scenario', str(scenarios_dir() / 'scan_around.yaml'),
                         '--scenario', str(scenarios_dir() / 'closest_obstacle.yaml')])
    lines = capsys.readouterr().out.splitlines()
    assert status == 1
    # Notes only (how the runs were sandboxed, where not fully), then the marks: the grader's
    # table of runs is the TA's, on the pages.
    start = lines.index('marks 2/4')
    assert all(line.startswith('note: ') for line in lines[:start]), lines
    assert not [line for line in lines if 'criterion' in line]
    tasks = [line for line in lines[start:] if line.startswith('  ') and ':' in line
             and not line.startswith('    ')]
    # The guide's closest_obstacle is graded and carries no marks (was a TypeError).
    assert tasks == ['  task 1: 2/2', '  task 3: 0/2', '  extra: no marks']
    lost = [line for line in lines[start:] if line.startswith('    lost ')]
    assert len(lost) == 2 and all('not submitted: no scan_around.py' in line for line in lost)
    page = (out / 'report.html').read_text(encoding='utf-8')
    for line in lost:  # the point as the TA's page names it
        assert line.split(', ', 1)[1].split(':')[0] in page


def test_check_of_a_folder_that_is_not_there_is_one_line(tmp_path, capsys):
    assert check.main([str(tmp_path / 'nowhere')]) == 2
    error = capsys.readouterr().err
    assert error == f"error: {tmp_path / 'nowhere'} is not a folder of node files\n"
