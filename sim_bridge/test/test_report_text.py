"""What a report's texts become: printable, bounded, strict JSON, without the grader's paths."""

import json
import os

import pytest

from sim_bridge.common.text import (
    cap_text, count_cell, first_line, format_measured, json_safe, one_line, PathNames,
    printable, reason)


def test_lone_surrogates_show_the_bytes_they_stand_for():
    assert printable(os.fsdecode(b'caf\xe9')) == 'caf\\xe9'
    assert printable('\ud800 alone') == '\\ud800 alone'
    assert printable('caf\u00e9') == 'caf\u00e9'


def test_control_characters_show_as_codes_so_a_terminal_does_nothing_with_them():
    # A student's coloured or \r-animated message, a NUL: inert on the console and in a page.
    shown = printable('\x1b[2J\x1b[31mTOO CLOSE\x1b[0m\x00\r\r\x9b1m\x7f')
    assert shown == '\\x1b[2J\\x1b[31mTOO CLOSE\\x1b[0m\\x00\\x0d\\x0d\\x9b1m\\x7f'
    assert printable('line 1\n\tline 2 \u00e9') == 'line 1\n\tline 2 \u00e9'
    assert '\x1b' not in cap_text('\x1b[2J' * 10_000, 1000)


def test_a_folder_name_with_a_newline_or_an_escape_stays_one_line_in_a_table():
    assert one_line('new\nline\tx\x1b[31m') == 'new\\nline\\tx\\x1b[31m'
    assert one_line(os.fsdecode(b'Jos\xe9')) == 'Jos\\xe9'


def test_a_long_text_keeps_its_ends_around_a_marker():
    text = 'start ' + 'x' * 100_000 + ' Error: the end'
    cut = cap_text(text, 1000)
    assert cut.startswith('start ') and cut.endswith(' Error: the end')
    assert f'\n... {len(text) - 1000} bytes cut ...\n' in cut
    assert len(cut.encode()) < 1100
    assert cap_text('short', 1000) == 'short'
    assert len(cap_text('\u00e9' * 1000, 1001).encode()) < 1100  # never half a character


def test_json_safe_values_dump_as_strict_json():
    value = {'gain': float('inf'), 'start': (0.0, float('nan')), os.fsdecode(b'k\xe9'): None}
    assert json.loads(json.dumps(json_safe(value), allow_nan=False)) == {
        'gain': 'inf', 'start': [0.0, 'nan'], 'k\\xe9': None}


def test_the_grader_folders_become_relative_names():
    names = PathNames({'/home/prof/out': '', '/home/prof': '~', '/': 'never the root'})
    assert names('File "/home/prof/out/ana/x.py", line 3') == 'File "ana/x.py", line 3'
    assert names('in /home/prof/notes.txt and /home/prof') == 'in ~/notes.txt and ~'
    assert names('/home/prof/out') == '.'
    assert names('/home/professor/x') == '/home/professor/x'
    assert names('/etc/passwd') == '/etc/passwd'


@pytest.mark.parametrize('criterion, value, shown', [
    ('min_clearance_m >= 0.05', 2.873e-09, '0.000 m'),
    ('wall_distance_m.mae <= 0.1', 0.0456, '0.046 m'),
    ('max_stationary_s < 5', 12.345, '12.3 s'),
    ('laps >= 1', 2, '2'),
    ('len(lap_times_s) >= 1', 3, '3'),
    ('all(turns_deg) > 90', [91.25, 178.5], '2 values, min 91.2 deg, max 178 deg'),
    ('coverage >= 0.5', None, 'no value'),
])
def test_measured_values_read_as_people_read_them(criterion, value, shown):
    assert format_measured(criterion, value) == shown


def test_a_class_cell_gives_the_worst_reason():
    passed, failed = {'passed': True}, {'passed': False, 'error': None, 'metrics': {}}
    missing = {'passed': False, 'error': 'not submitted: no x.py in ana/'}
    assert count_cell([passed, passed]) == ('2/2', '')
    assert count_cell([passed, failed]) == ('1/2', 'criteria failed')
    assert count_cell([failed, missing]) == ('0/2', 'not submitted')
    assert count_cell([]) == ('-', '')


def test_a_criterion_that_says_why_gives_the_reason_of_a_failed_run():
    why = "scan_ahead: range ahead printed 42 at t=0.1 s, truth 2.00 m: 'Range ahead: 42'"
    entry = {'passed': False, 'error': None, 'metrics': {'node_errors': []}, 'criteria': [
        {'criterion': 'collisions == 0', 'passed': True, 'value': 0, 'shown': '0'},
        {'criterion': 'printed_range_ahead: max_error_m 0.05', 'passed': False, 'value': why,
         'shown': why}]}
    assert reason(entry) == first_line(why)
