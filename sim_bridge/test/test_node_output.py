"""What the nodes write is kept with the simulated time of the code that wrote it (log.jsonl)."""

import json
import os
from pathlib import Path
import re
import sys
import time

from rcl_interfaces.msg import Log
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader
from rosbags.typesys import get_typestore, Stores
from sim_bridge.runner.node_output import (
    console_pattern, log_entry, LOG_FILE, NodeLog, StreamLines, terminal_colours)
from sim_bridge.runner.run import run_simulation

FIXTURES = Path(__file__).parent / 'fixtures'
KEYS = ['t', 'node', 'level', 'text', 'line']
CONSOLE_LINE = r'\[INFO\] \[\d+\.\d{{9}}\] \[{name}\]: Count: {count}'


def read_log(out_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (out_dir / LOG_FILE).read_text().splitlines()]


def test_default_console_format_is_read_back():
    entry = log_entry(1.5, '', 'STDERR', '\x1b[32m[WARN] [1712.300000000] [ns.scan_ahead]: '
                      'Range ahead: [1.23]\x1b[0m', console_pattern())
    assert entry == {'t': 1.5, 'node': 'ns.scan_ahead', 'level': 'WARN',
                     'text': 'Range ahead: [1.23]',
                     'line': '[WARN] [1712.300000000] [ns.scan_ahead]: Range ahead: [1.23]'}
    raw = log_entry(2.0, 'scan_ahead', 'STDOUT', '[1, 2] not a log line', console_pattern())
    assert raw == {'t': 2.0, 'node': 'scan_ahead', 'level': 'STDOUT',
                   'text': '[1, 2] not a log line', 'line': '[1, 2] not a log line'}
    # A traceback's text from a file name that is not UTF-8, a bell: JSON-able, inert.
    odd = log_entry(0.0, '', 'STDERR', 'open caf\udce9.txt\a', console_pattern())
    assert odd['text'] == odd['line'] == 'open caf\\xe9.txt\\x07'


def test_a_custom_console_format_is_read_back():
    pattern = console_pattern('{time} {severity} {name} {file_name}:{line_number}> {message}')
    entry = log_entry(0.0, '', 'STDERR', '1712.3 ERROR wall_follow f.py:3> lost: {x}', pattern)
    assert (entry['node'], entry['level'], entry['text']) == (
        'wall_follow', 'ERROR', 'lost: {x}')
    assert console_pattern('{time}: {message}') is None  # no severity: every line is raw


def test_rcutils_keeps_its_colours_on_a_terminal_while_captured(monkeypatch):
    monkeypatch.delenv('RCUTILS_COLORIZED_OUTPUT', raising=False)
    monkeypatch.setattr(sys.stderr, 'isatty', lambda: True)
    with terminal_colours():
        assert os.environ['RCUTILS_COLORIZED_OUTPUT'] == '1'
    assert 'RCUTILS_COLORIZED_OUTPUT' not in os.environ
    monkeypatch.setenv('RCUTILS_COLORIZED_OUTPUT', '0')  # the user's choice stands
    with terminal_colours():
        assert os.environ['RCUTILS_COLORIZED_OUTPUT'] == '0'


def test_a_flood_of_lines_is_capped(monkeypatch):
    monkeypatch.setattr('sim_bridge.runner.node_output.MAX_LINES', 3)
    log = NodeLog()
    for count in range(5):
        log.add(count, '', 'STDOUT', f'line {count}')
    assert [entry['text'] for entry in log.entries] == ['line 0', 'line 1', 'line 2']
    assert '2 more were not kept' in log.warning()


def test_stream_lines_stamp_each_line_at_the_cut_that_saw_its_first_byte(capfd):
    log = NodeLog(record=False)
    lines = StreamLines(log)
    lines.take('STDOUT', b'whole line\n')
    lines.take('STDERR', b'[WARN] [1.000000000] [ticker]: half ')
    lines.cut(0, 'ticker')
    lines.take('STDERR', b'and the rest\n')
    lines.take('STDOUT', b'no newline at the end')
    lines.cut(2_000_000_000, '')
    lines.close(3_000_000_000)
    assert log.entries == [
        {'t': 0.0, 'node': 'ticker', 'level': 'STDOUT', 'text': 'whole line',
         'line': 'whole line'},
        {'t': 0.0, 'node': 'ticker', 'level': 'WARN', 'text': 'half and the rest',
         'line': '[WARN] [1.000000000] [ticker]: half and the rest'},
        {'t': 2.0, 'node': '', 'level': 'STDOUT', 'text': 'no newline at the end',
         'line': 'no newline at the end'}]
    out, err = capfd.readouterr()
    assert out == 'whole line\nno newline at the end\n'
    assert err == '[WARN] [1.000000000] [ticker]: half and the rest\n'


def test_stream_lines_keep_up_to_their_cap_and_show_the_rest_after_it(capfd):
    log = NodeLog(record=False)
    lines = StreamLines(log, quiet=True, cap_bytes=10)
    lines.take('STDOUT', b'kept\n')
    lines.take('STDOUT', b'shown, not kept\n')
    lines.close(0)
    assert [entry['text'] for entry in log.entries] == ['kept', 'shown']
    assert lines.warning() == ('the nodes wrote 21 bytes of output; the first 10 were kept, '
                               '11 were not')
    assert capfd.readouterr().out == 'kept\nshown, not kept\n'


def test_a_stepped_run_keeps_log_and_print_lines_at_the_sim_time_of_their_callback(
        tmp_path, capfd):
    result = run_simulation('wall_follow_box', [str(FIXTURES / 'counting_logger.py')],
                            duration_s=3.5, out_dir=tmp_path, plot=False)
    assert result.ok
    log = read_log(tmp_path)
    assert all(list(entry) == KEYS for entry in log)
    assert log[0] == {'t': 0.0, 'node': 'counting_logger', 'level': 'STDOUT',
                      'text': 'counting_logger started', 'line': 'counting_logger started'}
    logged = [entry for entry in log if entry['level'] == 'INFO']
    printed = [entry for entry in log[1:] if entry['level'] == 'STDOUT']
    assert [(entry['t'], entry['node'], entry['text']) for entry in logged] == [
        (float(count), 'counting_logger', f'Count: {count}') for count in (1, 2, 3)]
    assert [(entry['t'], entry['node'], entry['text']) for entry in printed] == [
        (float(count), 'counting_logger', f'printed count {count}') for count in (1, 2, 3)]
    for count, entry in enumerate(logged, start=1):
        assert re.fullmatch(CONSOLE_LINE.format(name='counting_logger', count=count),
                            entry['line'])
    # The terminal still shows them, as the nodes wrote them.
    out, err = capfd.readouterr()
    assert 'printed count 3\n' in out
    assert logged[-1]['line'] + '\n' in err
    # And the recording has them on /rosout at their sim time, each a Log as rcl writes it:
    # stamped with the wall clock (the time the console line shows, else when it was read).
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(tmp_path / 'run') as bag:
        rosout = [(time, typestore.deserialize_cdr(raw, connection.msgtype))
                  for connection, time, raw in bag.messages(
                      [c for c in bag.connections if c.topic == '/rosout'])]
        assert {c.msgtype for c in bag.connections if c.topic == '/rosout'} == {
            'rcl_interfaces/msg/Log'}
    assert [(time, msg.level, msg.name, msg.msg) for time, msg in rosout] == [
        (round(entry['t'] * 1e9), 20, entry['node'], entry['text'])
        for entry in log]  # INFO and STDOUT are both Log.INFO
    wall = [msg.stamp.sec + msg.stamp.nanosec * 1e-9 for _, msg in rosout]
    assert wall == sorted(wall) and time.time() - 600 < wall[0] <= wall[-1] <= time.time()
    for entry, (_, msg) in zip(log, rosout):
        if entry['level'] == 'INFO':
            assert f'[{msg.stamp.sec}.{msg.stamp.nanosec:09d}]' in entry['line']


def test_rosout_messages_carry_the_console_line_s_time_file_function_and_line():
    pattern = console_pattern('[{severity}] [{time}] [{name}] {file_name}:{function_name}:'
                              '{line_number}: {message}')
    log = NodeLog(pattern=pattern)
    log.add(2_500_000_000, '', 'STDERR',
            '[WARN] [1795726188.671792913] [wall_follow] /ws/wall_follow.py:on_scan:42: lost')
    log.add(3_000_000_000, 'wall_follow', 'STDOUT', 'printed, no logger')
    before = time.time_ns()
    (logged_ns, logged), (printed_ns, printed) = [
        (t_ns, deserialize_message(data, Log)) for t_ns, data in log.take_rosout()]
    assert (logged_ns, printed_ns) == (2_500_000_000, 3_000_000_000)
    assert (logged.stamp.sec, logged.stamp.nanosec) == (1795726188, 671792913)
    assert (logged.level, logged.name, logged.msg) == (30, 'wall_follow', 'lost')
    assert (logged.file, logged.function, logged.line) == ('/ws/wall_follow.py', 'on_scan', 42)
    assert (printed.file, printed.function, printed.line, printed.msg) == (
        '', '', 0, 'printed, no logger')
    assert before - 10 ** 9 < printed.stamp.sec * 10 ** 9 + printed.stamp.nanosec <= before
    assert not list(log.take_rosout())


def test_a_node_error_s_traceback_is_among_the_node_s_lines_at_the_time_it_raised(tmp_path):
    result = run_simulation('obstacles', [str(FIXTURES / 'raising_node.py')], duration_s=2.0,
                            out_dir=tmp_path, quiet=True, plot=False, record=False)
    assert not result.ok
    log = read_log(tmp_path)
    assert [entry['text'] for entry in log[:4]] == [
        f'scan {count}: 36 beams' for count in (1, 2, 3, 4)]
    traceback = log[4:]
    assert {(entry['t'], entry['node'], entry['level']) for entry in traceback} == {
        (0.5, 'raiser', 'STDERR')}
    assert traceback[0]['text'] == 'Traceback (most recent call last):'
    assert traceback[-1]['text'] == 'ZeroDivisionError: no valid beam to average'
    assert '\n'.join(entry['line'] for entry in traceback) + '\n' == \
        result.metrics['node_errors'][0]['traceback']


def test_a_quiet_run_keeps_the_lines_and_shows_only_the_printed_ones(tmp_path, capfd):
    run_simulation('wall_follow_box', [str(FIXTURES / 'counting_logger.py')], duration_s=2.5,
                   out_dir=tmp_path, plot=False, record=False, quiet=True)
    assert [entry['text'] for entry in read_log(tmp_path)] == [
        'counting_logger started', 'Count: 1', 'printed count 1', 'Count: 2', 'printed count 2']
    out, err = capfd.readouterr()
    assert out == 'counting_logger started\nprinted count 1\nprinted count 2\n'
    assert 'Count' not in err
