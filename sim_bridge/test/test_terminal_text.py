"""A video's terminal text: stamps as a live run prints them, the teleop's keys."""

from sim_bridge.media.terminal_text import live_stamped, teleop_lines


def test_a_stepped_runs_lines_get_the_stamps_of_a_live_run_at_real_time():
    # A stepped run wrote these 2 ms apart in wall time, 0.1 s and 25.9 s apart in sim time.
    lines = [(0.1, '[INFO] [1795726253.603172832] [scan_ahead]: Range ahead: 2.99'),
             (0.2, '[INFO] [1795726253.605172832] [scan_ahead]: Range ahead: 3.01'),
             (26.0, '[WARN] [1795726253.607172832] [scan_ahead]: Range ahead: 10'),
             (26.0, 'a print() without a stamp')]
    assert live_stamped(lines) == [
        '[INFO] [1795726253.603172832] [scan_ahead]: Range ahead: 2.99',
        '[INFO] [1795726253.703172832] [scan_ahead]: Range ahead: 3.01',
        '[WARN] [1795726279.503172832] [scan_ahead]: Range ahead: 10',
        'a print() without a stamp']


def test_the_teleop_says_each_key_held_once():
    commands = [(0.05, 0.0, 0.0), (1.0, 0.3, 0.0), (1.05, 0.3, 0.0), (5.0, 0.0, 0.8),
                (7.0, 0.0, -0.8), (9.0, 0.0, 0.0)]
    assert teleop_lines(commands) == [
        (0.05, "key 'k': stop"),
        (1.0, "key 'i': linear.x +0.30 m/s, angular.z +0.00 rad/s"),
        (5.0, "key 'j': linear.x +0.00 m/s, angular.z +0.80 rad/s"),
        (7.0, "key 'l': linear.x +0.00 m/s, angular.z -0.80 rad/s"),
        (9.0, "key 'k': stop")]
