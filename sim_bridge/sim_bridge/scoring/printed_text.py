"""
What a line a node printed says: its numbers, the range ahead, region minima, the nearest obstacle.

Numbers are read from free-form text as students write it ("Range ahead: 1.23", "F=1.2 m",
"1.234", "inf", "front_left: 0.9 | left: 2.1"): indices (``ranges[17]``, "beam 17") are not
values; a length in cm or mm is converted to m; inf, and the words students print for no return
(nan, none, nothing, out of range, no obstacle), read as +inf. A bearing's unit is the one
written after it (deg, degrees, °, rad, radians); without one it is read as rad (REP-103),
unless its magnitude exceeds 2 pi, which only degrees can.

Reading is linear in a line's length and bounded: a line is read up to its first LINE_CHARS
characters (the lab's 36 ranges printed in full take about 800), and a label is looked for in
the LABEL_CHARS characters before its number.

Pure: the standard library and the grader's region names, no rclpy.
"""

from dataclasses import dataclass
import math
import re
from typing import Sequence

from sim_bridge.scoring.scan_geometry import REGION_NAMES

#: Characters of a printed line that are read: what follows is not.
LINE_CHARS = 2000
#: Characters before a number in which its label ("front distance is ") is looked for.
LABEL_CHARS = 40

_INF = r'[-+]?(?:inf(?:inity)?|\u221e)'
# What students print instead of a number for no return: read as +inf.
_NO_RETURN = (r'(?:[-+]?nan|none|nothing|out[\s_-]+of[\s_-]+range'
              r'|no[\s_-]+(?:obstacles?|returns?|echo))(?![A-Za-z])')
_DECIMAL = r'[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?'
_UNIT = (r'(?:\s*(?P<unit>mm|cm|m|meters?|metres?|deg(?:rees?)?|\u00b0|rad(?:ians?)?'
         r'|s|sec|seconds?|ms|%)(?![A-Za-z]))?')
_NUMBER = re.compile(rf'(?<![\w.])(?P<number>{_INF}|{_NO_RETURN}|{_DECIMAL})(?![\w.]*\d)'
                     + _UNIT, re.IGNORECASE)
# An index, not a value: ``ranges[17]``, ``[0:7]``, ``[len(r)//2]`` (brackets without a
# decimal number), "beam 17", "index: 3", "#4".
_INDEXED = re.compile(r'\[(?:[^\[\].]|\.(?!\d))*\]'
                      r'|(?<![A-Za-z])(?:index|idx|beam|ray|sample|scan|seq|count|no\.|#)'
                      r'\s*[:=#]?\s*\d+(?![\d.])', re.IGNORECASE)
# Between a label and its number: "front: ", "F=", "front distance is ", "['left'] = [".
_SEPARATOR = r"""['"\])}]*\s*(?:(?:[:=]|->|=>|\bis\b|\bwas\b|\bat\b)\s*)*\[?\s*"""
_LENGTH_UNITS = {'m': 1.0, 'meter': 1.0, 'meters': 1.0, 'metre': 1.0, 'metres': 1.0,
                 'cm': 0.01, 'mm': 0.001}
_ANGLE_UNITS = {'deg': 'deg', 'degree': 'deg', 'degrees': 'deg', '\u00b0': 'deg',
                'rad': 'rad', 'radian': 'rad', 'radians': 'rad'}
_TIME_UNITS = frozenset({'s', 'sec', 'second', 'seconds', 'ms', '%'})
_AHEAD_WORDS = re.compile(r'(?<![A-Za-z])(?:ahead|front|forward|straight|f|range|distance|dist'
                          r'|d)(?![A-Za-z])' + _SEPARATOR + r'$', re.IGNORECASE)
_DISTANCE_WORDS = re.compile(r'(?<![A-Za-z])(?:closest|nearest|min(?:imum)?|distance|dist'
                             r'|range|obstacle|d|r)(?![A-Za-z])' + _SEPARATOR + r'$',
                             re.IGNORECASE)
_BEARING_WORDS = re.compile(r'(?<![A-Za-z])(?:angle|bearing|heading|direction|dir|theta|yaw'
                            r'|\u03b8)(?![A-Za-z])' + _SEPARATOR + r'$', re.IGNORECASE)
_AT = re.compile(r'(?<![A-Za-z])at\s*$', re.IGNORECASE)
_NOTHING = re.compile(r'(?<![A-Za-z])(?:no|none|nothing|clear|free)(?![A-Za-z])', re.IGNORECASE)
# Region labels as students write them, the longer first so "front-right" is not "front".
_REGION_LABELS = (
    ('front_right', r'front[\s_-]*right|right[\s_-]*front|fright|f[_-]?r'),
    ('front_left', r'front[\s_-]*left|left[\s_-]*front|fleft|f[_-]?l'),
    ('front', r'front|ahead|f'),
    ('right', r'right|r'),
    ('left', r'left|l'),
)
_REGION = re.compile(
    r'(?<![A-Za-z])(?P<label>' + '|'.join(f'(?P<{name}>{pattern})'
                                          for name, pattern in _REGION_LABELS)
    + r')(?:[\s_-]*(?:min(?:imum)?|region|sector|zone|side|dist(?:ance)?|range))?(?![A-Za-z])'
    + _SEPARATOR + rf'(?P<number>{_INF}|{_NO_RETURN}|{_DECIMAL})(?![\w.]*\d)' + _UNIT,
    re.IGNORECASE)


@dataclass(frozen=True)
class Number:
    """A number read from a line: its value (m for a length, as written otherwise), where."""

    value: float
    written: str
    start: int
    unit: str | None


def numbers_in(text: str) -> list[Number]:
    """
    Return the numbers of a line of text, indices left out, lengths in m.

    ``ranges[17]``, "beam 17", "index 3" are indices, not values. A length written in cm or
    mm is converted to m; inf, infinity and the infinity sign read as +inf (or -inf), and so
    do the words for no return (nan, none, nothing, out of range, no obstacle). Only the
    first LINE_CHARS characters are read.
    """
    blanked = _INDEXED.sub(lambda match: ' ' * len(match.group()), text[:LINE_CHARS])
    found = []
    for match in _NUMBER.finditer(blanked):
        unit = (match['unit'] or '').lower() or None
        value = _parse(match['number']) * _LENGTH_UNITS.get(unit, 1.0)
        found.append(Number(value, _written(match), match.start(), unit))
    return found


def _written(match: re.Match) -> str:
    return match['number'] + (f" {match['unit']}" if match['unit'] else '')


def _parse(written: str) -> float:
    sign = -1.0 if written.startswith('-') else 1.0
    digits = written.lstrip('+-').lower()
    if digits[:1].isalpha() and not digits.startswith('inf'):
        return math.inf  # a word for no return: NaN is no return too
    return sign * math.inf if digits.startswith(('inf', '\u221e')) else float(written)


def _labelled(text: str, numbers: Sequence[Number], words: re.Pattern) -> list[Number]:
    """Return the numbers ``words`` (a pattern ending in ``$``) label: within LABEL_CHARS."""
    return [number for number in numbers
            if _before(words, text, number.start)]


def _before(words: re.Pattern, text: str, end: int) -> re.Match | None:
    """Return the match of ``words`` ending at ``end`` in the LABEL_CHARS before it, or None."""
    return words.search(text, max(end - LABEL_CHARS, 0), end)


def read_range_ahead(text: str) -> Number | None:
    """
    Return the range ahead a line gives, or None when it gives none (or cannot be read).

    The number labelled as the range ("ahead: 1.2", "F=1.2", "distance 1.2"), else the first
    one written in a length unit, else the only number of the line. Times, angles and
    percentages are not ranges; neither are indices.
    """
    candidates = [number for number in numbers_in(text)
                  if number.unit not in _TIME_UNITS and number.unit not in _ANGLE_UNITS]
    labelled = _labelled(text, candidates, _AHEAD_WORDS)
    if labelled:
        return labelled[0]
    lengths = [number for number in candidates if number.unit in _LENGTH_UNITS]
    if lengths:
        return lengths[0]
    return candidates[0] if len(candidates) == 1 else None


def read_regions(text: str) -> list[tuple[str, Number]]:
    """
    Return the (region name, value) pairs a line gives, in the line's order.

    Labels are read as students write them: "front-right", "front_right", "Front Right",
    "fright", "FR", "right front"; "min_left", "left region", "left distance is ..."; "ahead"
    is the front ("Range ahead: 1.2", the handout's label, one region a line). A line
    of exactly five lengths and no label (``print(min(ranges[0:7]), ...)``) gives the regions
    right to left, in the order of the beams.
    """
    pairs = []
    blanked = _INDEXED.sub(lambda match: ' ' * len(match.group()), text[:LINE_CHARS])
    for match in _REGION.finditer(blanked):
        name = next(name for name, _ in _REGION_LABELS if match[name] is not None)
        unit = (match['unit'] or '').lower() or None
        if unit in _TIME_UNITS or unit in _ANGLE_UNITS:
            continue
        value = _parse(match['number']) * _LENGTH_UNITS.get(unit, 1.0)
        pairs.append((name, Number(value, _written(match), match.start('number'), unit)))
    if not pairs:
        lengths = [number for number in numbers_in(text)
                   if number.unit not in _TIME_UNITS and number.unit not in _ANGLE_UNITS]
        if len(lengths) == len(REGION_NAMES):
            pairs = list(zip(REGION_NAMES, lengths))
    return pairs


def read_closest(text: str) -> tuple[Number | None, float | None]:
    """
    Return (distance, bearing in rad) of the nearest obstacle a line gives; None for missing.

    A bearing is a number written in an angle unit, or labelled ("angle", "bearing", ...),
    or the number after "at" that follows the distance ("0.87 m at -35.0"); see the module
    text for its unit. The distance is the labelled one ("closest: 0.87"), else the first
    in a length unit, else the first other number. A line saying there is nothing ("No valid
    obstacle readings.") gives an infinite distance.
    """
    numbers = [number for number in numbers_in(text) if number.unit not in _TIME_UNITS]
    bearings = [number for number in numbers if number.unit in _ANGLE_UNITS]
    bearings = bearings or _labelled(text, numbers, _BEARING_WORDS)
    others = [number for number in numbers if number not in bearings]
    distance = next(iter(_labelled(text, others, _DISTANCE_WORDS)
                         or [number for number in others if number.unit in _LENGTH_UNITS]
                         or others), None)
    if not bearings and distance is not None:
        bearings = [number for number in others if number.start > distance.start
                    and number.unit is None and _before(_AT, text, number.start)]
    bearing = None
    if bearings:
        number = bearings[0]
        degrees = _ANGLE_UNITS.get(number.unit) == 'deg' or (
            number.unit is None and abs(number.value) > 2.0 * math.pi + 1e-6)
        bearing = math.radians(number.value) if degrees else number.value
        if not math.isfinite(bearing):
            bearing = None
    if distance is None and _NOTHING.search(text, 0, LINE_CHARS):
        distance = Number(math.inf, 'nothing', 0, None)
    return distance, bearing
