"""
A video's terminals: the node's lines stamped as a live run stamps them, the teleop's, drawn.

rcutils stamps each console line with the system clock, ``[INFO] [1795726253.603172832]
[scan_ahead]: ...``, even under ``use_sim_time``. A live run goes at the simulator's pace, so
its stamps advance with the simulated clock; a stepped run is many times faster than real time,
so its stamps advance a few milliseconds a line, whatever the simulated time between them.
:func:`live_stamped` gives a run's lines the stamps a live run at real time would have printed:
the first line's stamp, advanced by the simulated time since it.

:func:`teleop_lines` says what the person at the teleop did, from the commands it published
(a scenario's ``drive:``): a line per key held, with teleop_twist_keyboard's keys.
:class:`TerminalPane` draws a terminal (Pillow; fonts found by matplotlib): its command at the
top, the lines written by then below, scrolling as a terminal does.
"""

from dataclasses import dataclass
import math
import re
from typing import Iterable, Sequence

from matplotlib.font_manager import findfont, FontProperties
import numpy as np
from PIL import Image, ImageDraw, ImageFont

#: Console text (px); DejaVu Sans Mono, the font matplotlib ships.
TERMINAL_FONT_SIZE = 13
TERMINAL_LINE_HEIGHT = 16
TERMINAL_MARGIN = 8
TERMINAL_BACKGROUND = (24, 24, 24)
TERMINAL_HEADER = (56, 56, 64)
TERMINAL_TEXT = (210, 210, 210)
LEVEL_COLOURS = {'DEBUG': (140, 140, 140), 'WARN': (240, 200, 60), 'ERROR': (240, 90, 80),
                 'FATAL': (240, 90, 80), 'STDERR': (240, 150, 120)}
#: Escape sequences a terminal interprets rather than shows (rcutils colours, cursor moves).
ANSI_ESCAPE = re.compile(r'\x1b\[[0-9;?]*[A-Za-z]')
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


@dataclass(frozen=True)
class LogLine:
    """A console line as the terminal showed it, at sim time ``t`` (s), of ``level``."""

    t: float
    level: str
    line: str


def font(family: str, size: int, weight: str = 'normal') -> ImageFont.FreeTypeFont:
    """Return the font matplotlib finds for ``family`` at ``size`` (px)."""
    path = findfont(FontProperties(family=family, weight=weight), fallback_to_default=True)
    return ImageFont.truetype(path, size)


def terminal_rows(text: str, columns: int) -> list[str]:
    """Return ``text`` as the rows a terminal ``columns`` wide shows (escapes out, wrapped)."""
    text = ANSI_ESCAPE.sub('', text).expandtabs(8)
    text = ''.join(char if char.isprintable() else '?' for char in text)
    return [text[start:start + columns] for start in range(0, len(text), columns)] or ['']


class TerminalPane:
    """
    The terminal of a video: the command at its top, the console lines below, scrolling.

    ``size`` (px); :meth:`image` of the first ``count`` lines is cached, so that frames with no
    new line cost nothing.
    """

    def __init__(self, size: tuple[int, int], commands: Sequence[str], log: Sequence[LogLine]):
        self.size = size
        self.font = font('DejaVu Sans Mono', TERMINAL_FONT_SIZE)
        advance = self.font.getlength('M')
        self.columns = max(20, int((size[0] - 2 * TERMINAL_MARGIN) // advance))
        self.header = [row for command in commands
                       for row in terminal_rows(f'$ {command}', self.columns)]
        self.header_height = TERMINAL_LINE_HEIGHT * len(self.header) + 2 * TERMINAL_MARGIN
        self.capacity = max(1, (size[1] - self.header_height - TERMINAL_MARGIN)
                            // TERMINAL_LINE_HEIGHT)
        self.log = list(log)
        self.times = np.array([entry.t for entry in self.log])
        self._cached: tuple[int, Image.Image] | None = None
        self._entry_rows: dict[int, list[tuple[str, tuple[int, int, int]]]] = {}
        self._row_images: dict[tuple[str, tuple[int, int, int]], Image.Image] = {}
        self._header = Image.new('RGB', self.size, TERMINAL_BACKGROUND)
        draw = ImageDraw.Draw(self._header)
        draw.rectangle((0, 0, self.size[0], self.header_height - TERMINAL_MARGIN // 2),
                       fill=TERMINAL_HEADER)
        for number, row in enumerate(self.header):
            draw.text((TERMINAL_MARGIN, TERMINAL_MARGIN + number * TERMINAL_LINE_HEIGHT), row,
                      font=self.font, fill=(255, 255, 255))

    def count_at(self, t: float) -> int:
        """Return how many lines had been written by sim time ``t`` (s)."""
        return int(np.searchsorted(self.times, t, side='right'))

    def image(self, count: int) -> Image.Image:
        """Return the pane after the first ``count`` lines: the last rows that fit."""
        if self._cached is not None and self._cached[0] == count:
            return self._cached[1]
        rows = []
        for index in range(max(0, count - self.capacity), count):
            if index not in self._entry_rows:
                entry = self.log[index]
                colour = LEVEL_COLOURS.get(entry.level.upper(), TERMINAL_TEXT)
                self._entry_rows[index] = [(row, colour)
                                           for row in terminal_rows(entry.line, self.columns)]
            rows += self._entry_rows[index]
        pane = self._header.copy()
        # Text is the costly part of a frame: each row is drawn once, then moved as it scrolls.
        drawn = {}
        for number, key in enumerate(rows[-self.capacity:]):
            drawn[key] = self._row_images.get(key) or drawn.get(key) or self._row(*key)
            pane.paste(drawn[key], (0, self.header_height + number * TERMINAL_LINE_HEIGHT))
        self._row_images = drawn
        self._cached = (count, pane)
        return pane

    def _row(self, text: str, colour: tuple[int, int, int]) -> Image.Image:
        row = Image.new('RGB', (self.size[0], TERMINAL_LINE_HEIGHT), TERMINAL_BACKGROUND)
        ImageDraw.Draw(row).text((TERMINAL_MARGIN, 0), text, font=self.font, fill=colour)
        return row
