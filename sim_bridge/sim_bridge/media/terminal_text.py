"""
What a video's terminals show: the node's lines stamped as a live run stamps them, the teleop's.

rcutils stamps each console line with the system clock, ``[INFO] [1795726253.603172832]
[scan_ahead]: ...``, even under ``use_sim_time``. A live run goes at the simulator's pace, so
its stamps advance with the simulated clock; a stepped run is many times faster than real time,
so its stamps advance a few milliseconds a line, whatever the simulated time between them.
:func:`live_stamped` gives a run's lines the stamps a live run at real time would have printed:
the first line's stamp, advanced by the simulated time since it.

:func:`teleop_lines` says what the person at the teleop did, from the commands it published
(a scenario's ``drive:``): a line per key held, with teleop_twist_keyboard's keys. Pure text.
"""

import math
import re
from typing import Iterable, Sequence

#: rcutils' default console format: ``[SEVERITY] [SECONDS.NANOSECONDS] [node]: message``.
STAMP = re.compile(r'^(\[[A-Z]+\] \[)(\d+)\.(\d{9})(\])')
#: A command this close to zero (m/s, rad/s) is none.
STILL = 1e-6
#: teleop_twist_keyboard's key for each (forward sign, turn sign) (its MOVE_BINDINGS).
KEYS = {(1, 0): 'i', (1, 1): 'u', (1, -1): 'o', (0, 1): 'j', (0, -1): 'l', (-1, 0): ',',
        (-1, 1): '.', (-1, -1): 'm', (0, 0): 'k'}


def live_stamped(lines: Sequence[tuple[float, str]]) -> list[str]:
    """
    Return each line's text with the stamp a live run at real time would have printed.

    ``lines`` are (sim time s, console line) in time order; a line without rcutils' stamp is
    kept as it is. The first stamped line keeps its stamp; the others get it plus the simulated
    time (s) since that line, to the nanosecond.
    """
    base_ns = None
    result = []
    for t, line in lines:
        found = STAMP.match(line)
        if found is None:
            result.append(line)
            continue
        t_ns = round(t * 1e9)
        if base_ns is None:
            base_ns = int(found[2]) * 10 ** 9 + int(found[3]) - t_ns
        seconds, nanoseconds = divmod(base_ns + t_ns, 10 ** 9)
        result.append(f'{found[1]}{seconds}.{nanoseconds:09d}{found[4]}{line[found.end():]}')
    return result


def _sign(value: float) -> int:
    return 0 if abs(value) < STILL else int(math.copysign(1, value))


def teleop_lines(commands: Iterable[tuple[float, float, float]]) -> list[tuple[float, str]]:
    """
    Return (sim time s, text) of each change of the teleop's command.

    ``commands`` are (sim time s, linear.x m/s, angular.z rad/s) as published, in time order;
    a command repeated (a held key repeats it) gives no new line.
    """
    lines = []
    last = None
    for t, linear, angular in commands:
        command = (round(linear, 6), round(angular, 6))
        if command == last:
            continue
        last = command
        key = KEYS[(_sign(linear), _sign(angular))]
        what = ('stop' if key == 'k'
                else f'linear.x {linear:+.2f} m/s, angular.z {angular:+.2f} rad/s')
        lines.append((t, f"key '{key}': {what}"))
    return lines
