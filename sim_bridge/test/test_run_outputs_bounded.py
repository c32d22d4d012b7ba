"""
Every output of a run is bounded, and a full disk fails that run alone, in one line.

The hostile nodes of fixtures/hostile: commands stamped with a long frame_id (a bag that grows),
a flood of control characters (each kept as an escape, twice, in log.jsonl). The full disk is
simulated: the bag's file (or every output) raises ENOSPC once a small quota is written, as a
full disk does.
"""

import errno
import json
from pathlib import Path

import pytest
from sim_bridge.common.errors import RunError
from sim_bridge.runner import outputs, record
from sim_bridge.runner.boundary.outside import link
from sim_bridge.runner.run import run_simulation

HOSTILE = Path(__file__).parent / 'fixtures' / 'hostile'


def run(tmp_path, node, duration_s=3.0, **kwargs):
    return run_simulation('obstacles', [str(node)], duration_s=duration_s, out_dir=tmp_path,
                          quiet=True, plot=False, **kwargs).metrics


class QuotaFile:
    """A file that raises ENOSPC once ``quota`` bytes were written to it: a full disk."""

    def __init__(self, file, quota: int):
        self.file = file
        self.quota = quota

    def write(self, data) -> int:
        if self.file.tell() + len(data) > self.quota:
            raise OSError(errno.ENOSPC, 'No space left on device')
        return self.file.write(data)

    def __getattr__(self, name):
        return getattr(self.file, name)


def quota_open(quota: int):
    def opened(path, mode='r', *args, **kwargs):
        file = open(path, mode, *args, **kwargs)
        return QuotaFile(file, quota) if 'w' in mode else file
    return opened


def test_a_recording_stops_at_its_cap_and_fails_the_run_in_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(outputs, 'BAG_CAP_BYTES', 2 ** 20)
    # 60 kB a command, under the cap of a string: the bag grows by 0.6 MB a second
    metrics = run(tmp_path, HOSTILE / 'long_frame_id.py',
                  params={'padder': {'frame_id_bytes': 60_000}})
    [error] = metrics['node_errors']
    assert error['error'].endswith('its recording reached its cap of 1048576 bytes of '
                                   'messages (its nodes published too much)')
    assert 1.0 < metrics['sim_time_s'] < 3.0
    assert (tmp_path / 'run' / 'run_0.mcap').stat().st_size < 2 ** 20 + 2 ** 16
    assert json.loads((tmp_path / 'metrics.json').read_text())['node_errors'] == [error]


@pytest.mark.parametrize('quota, duration_s', [(20_000, 5.0), (2_000, 1.0)])
def test_a_disk_full_while_recording_fails_the_run_in_one_line(tmp_path, monkeypatch, quota,
                                                               duration_s):
    # Full as the run goes (a chunk of the bag written), or as the bag is closed (its index).
    monkeypatch.setattr(record, 'open', quota_open(quota), raising=False)
    metrics = run(tmp_path, HOSTILE.parent / 'spin_once_loop.py', duration_s=duration_s)
    [error] = metrics['node_errors']
    assert error['node'] == 'sim_bridge' and error['error'].endswith(
        'its recording could not be written (No space left on device)')
    assert '\n' not in error['error']


def test_a_disk_full_for_every_output_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(record, 'open', quota_open(200_000), raising=False)
    monkeypatch.setattr(outputs, 'write_log', lambda *args: (_ for _ in ()).throw(
        OSError(errno.ENOSPC, 'No space left on device')))
    with pytest.raises(RunError) as error:
        run(tmp_path, HOSTILE.parent / 'spin_once_loop.py')
    assert str(error.value) == "cannot write the run's outputs (No space left on device)"
    assert error.value.traceback is None


def test_a_flood_of_control_characters_keeps_the_log_file_within_its_cap(
        tmp_path, monkeypatch):
    # Each byte is kept printable (an escape) and twice (text, line): ~10 bytes of log.jsonl.
    monkeypatch.setattr(link, 'OUTPUT_CAP_BYTES', 2 ** 20)
    monkeypatch.setattr(outputs, 'LOG_CAP_BYTES', 2 ** 21)
    metrics = run(tmp_path, HOSTILE / 'control_flood.py', duration_s=1.0, record=False)
    assert (tmp_path / 'log.jsonl').stat().st_size <= 2 ** 21
    assert any(warning.startswith('log.jsonl holds the lines that fit its cap of 2097152 '
                                  'bytes;') for warning in metrics['warnings'])
