"""
What the lab's reading nodes print, read back and compared with the scans they received.

Lab tasks 1 and 3 (and the guide's closest-obstacle node) are graded on what a node prints on
every scan: the range straight ahead, the minimum of five regions, the nearest obstacle. A log
line (a dict ``{'t', 'node', 'level', 'text', 'line'}``: sim time s, node name, level, message
text, console line) is compared with the truth of the scan the node had just received: the last
scan published at or before the line's time. Lines on stderr (a traceback) and
the runner's own nodes' are not what a node prints. Numbers are read from free-form text as
students write it (:mod:`sim_bridge.scoring.printed_text`); a scan that no line gives a value
for counts as missed.

Truth, as the grader's own geometry computes it (:mod:`sim_bridge.scoring.scan_geometry`,
the lab's conventions that scan_pkg's nodes follow too): readings are capped at the lab's
``max_range`` (10 m: +inf and longer readings become 10 m, -inf and readings below range_min
become range_min, NaN is ignored), and a printed value is capped the same way (so "inf" for no
return is right, and so are "nan", "none", "out of range", "no obstacle" and "nothing", read
as inf). A node may cap at a distance of its own instead (its lidar's range_max, 3.5 m, 5 m,
12 m, a parameter of its own): the cap it applies is inferred from what it prints (see
:func:`score_printed`), and its values are judged against it when it is consistent. Where the
lab's definition leaves a choice, every reasonable choice is right:

- range ahead: any beam within one increment of straight ahead, or any value between them
  (one beam, their minimum or their mean);
- regions (``right``, ``front_right``, ``front``, ``front_left``, ``left``: 36 deg bands
  centred on -72, -36, 0, 36, 72 deg): a beam on the edge between two bands (within a quarter
  of an increment: the lab robot's beams 7, 14, 21 and 28 are 0.03 deg from one) may belong to
  either, so ``ranges[0:7]``, ``[7:14]``, ``[14:21]``, ``[21:28]``, ``[28:36]`` is right too;
  a beam on the outer edge (+-90 deg: beam 35 at +89.95 deg) belongs to its band;
- closest obstacle: the nearest valid return; with none, "nothing" (a line like "No valid
  obstacle readings." or a printed inf) is right. Its bearing, when printed, is compared
  modulo 2 pi.

Pure: numpy and the grader's scan geometry, no rclpy.
"""

import bisect
from dataclasses import dataclass
import math
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from sim_bridge.scoring.printed_match import matching_source
from sim_bridge.scoring.printed_text import Number, read_closest, read_range_ahead, read_regions
from sim_bridge.scoring.scan_geometry import (
    ANGLE_TOLERANCE, bearing_difference, RecordedScan as Scan, REGION_CENTRES, REGION_HALF_WIDTH,
    REGION_NAMES)

#: The printed values a run can be scored on, by the name metrics and scenarios use.
KINDS = ('range_ahead', 'regions', 'closest')
#: What each kind is called in a report.
KIND_TITLES = {'range_ahead': 'range ahead', 'regions': 'region minima',
               'closest': 'closest obstacle'}
#: The lab's cap (m) for no return and readings beyond it (the lab's nodes' ``max_range`` default).
LAB_MAX_RANGE = 10.0
#: The shortest lidar range (m) of a lab robot (TurtleBot3's LDS): a node's own cap is at
#: least this, or its lidar's range_max when that is shorter; a smaller value is never a cap.
SHORTEST_CAP = 3.5
#: Values a node prints for its cap differ by no more than this (m): its printing's rounding.
CAP_ROUNDING = 0.01
#: A line this much (s) later than a scan is still about it: sim times are exact to the ns.
TIME_SLACK_S = 1e-6
#: A beam this many increments from the edge between two regions may be in either.
EDGE_SLACK = 0.25
#: A printed value this close (m) to its scan's truth is the value asked for: one decimal
#: (+-0.05 m) and the float32 of a reading are close enough; another beam's range is not.
RIGHT_WITHIN_M = 0.06
#: The parts of a scenario's scans that must each hold a right line for values printed
#: "throughout" it: a node that stops, or falls silent, leaves parts without one.
PARTS = 10
#: Characters of a line quoted in a report.
QUOTE_CHARS = 70
#: Log levels that are not what a node prints about a scan: a traceback goes to stderr.
IGNORED_LEVELS = frozenset({'STDERR'})


def scan_of(snapshot: Any) -> Scan:
    """Return the :class:`Scan` of a recorded scan (a ``run_trace.ScanSnapshot``)."""
    return Scan.of(snapshot)


def _bounds(values: np.ndarray, cap: float) -> tuple[float, float] | None:
    """Return (min, max) of capped ``values`` (m), NaN ignored; all NaN: the cap."""
    if not len(values):
        return None
    values = values[~np.isnan(values)]
    if not len(values):
        return cap, cap
    return float(values.min()), float(values.max())


def range_ahead_truth(scan: Scan, cap: float = LAB_MAX_RANGE) -> tuple[float, float] | None:
    """
    Return the (lowest, highest) right range ahead (m), or None when no beam looks ahead.

    The capped readings of the beams within one increment of straight ahead.
    """
    if not len(scan):
        return None
    bearings = np.abs(scan.bearings())
    near = bearings <= abs(scan.angle_increment) + ANGLE_TOLERANCE
    return _bounds(scan.capped(cap)[near], cap)


def region_truths(scan: Scan,
                  cap: float = LAB_MAX_RANGE) -> dict[str, tuple[float, float] | None]:
    """
    Return each region's (lowest, highest) right minimum (m); None for a region with no beam.

    A beam within EDGE_SLACK increments of the edge shared by two bands may be in either:
    the lowest right minimum counts it in both, the highest in neither.
    """
    bearings = scan.bearings()
    ranges = scan.capped(cap)
    slack = EDGE_SLACK * abs(scan.angle_increment) + ANGLE_TOLERANCE
    shared = np.zeros(len(ranges), dtype=bool)
    # The bands are adjacent: each edge between two is midway between their centres.
    for edge in ((left + right) / 2.0 for left, right in zip(REGION_CENTRES, REGION_CENTRES[1:])):
        shared |= np.abs(bearings - edge) <= slack
    truths = {}
    for name, centre in zip(REGION_NAMES, REGION_CENTRES):
        inside = (np.abs(bearings - centre) <= REGION_HALF_WIDTH + ANGLE_TOLERANCE) | (
            shared & (np.abs(bearings - centre) <= REGION_HALF_WIDTH + slack))
        with_edges = _bounds(ranges[inside], cap)
        without = _bounds(ranges[inside & ~shared], cap)
        if with_edges is None:
            truths[name] = None
        else:
            truths[name] = (with_edges[0], (without or with_edges)[0])
    return truths


def closest_truth(scan: Scan, cap: float = LAB_MAX_RANGE) -> tuple[float, float | None]:
    """Return (distance m, bearing rad) of the nearest valid return; (cap, None) for none."""
    closest = scan.closest()
    if closest is None:
        return cap, None
    return min(closest[0], cap), closest[1]


@dataclass(frozen=True)
class Comparison:
    """One printed value against the truth of its scan: what it is, the line, the error (m)."""

    what: str
    printed: Number
    truth: tuple[float, float]
    error: float
    line: Mapping[str, Any]
    #: The index of the scan it is about.
    scan: int = -1


@dataclass(frozen=True)
class Cap:
    """
    The cap (m) printed values are judged with: what no return, and a reading beyond it, read as.

    ``clamps``: a printed value beyond the cap reads as the cap too. True for a cap at or beyond
    the lidar's range (no reading lies between them: 12 m is as right as 10 m); False for a
    node's own cap below it, which a larger printed value breaks.
    """

    at: float
    clamps: bool = True

    def read(self, value: float) -> float:
        """Return a printed value (m) as judged: below 0 as 0, no return as the cap."""
        if value < 0.0:
            return 0.0
        return self.at if math.isinf(value) or (self.clamps and value > self.at) else value


def _compare(what: str, printed: Number, truth: tuple[float, float], cap: Cap,
             line: Mapping[str, Any], scan: int) -> Comparison:
    value = cap.read(printed.value)
    low, high = truth
    return Comparison(what, printed, truth, max(low - value, value - high, 0.0), line, scan)


def _bearing_error(printed: float, truth: float) -> float:
    return bearing_difference(printed, truth)


def _lines_per_scan(kind: str, lines: Iterable[Mapping[str, Any]], times: Sequence[float],
                    ignored: set[str], truth_of: Callable[[int], Any],
                    cap: Cap) -> dict[int, list[tuple[list[Comparison], float | None]]]:
    """
    Return, per scan index, the comparisons (and printed bearing) of the lines about it.

    A line is about the last scan at or before its time ``t`` (s).
    """
    per_scan: dict[int, list[tuple[list[Comparison], float | None]]] = {}
    for line in lines:
        if line.get('node') in ignored or line.get('level') in IGNORED_LEVELS:
            continue
        values, bearing = _READERS[kind](str(line.get('text', '')))
        if not values:
            continue
        time = float(line['t'])
        index = bisect.bisect_right(times, time + TIME_SLACK_S) - 1
        found = (_compare_line(kind, values, truth_of(index), cap, line, index)
                 if index >= 0 else [])
        if found:
            per_scan.setdefault(index, []).append((found, bearing))
    return per_scan


def score_printed(kind: str, scans: Sequence[Any], lines: Iterable[Mapping[str, Any]], *,
                  cap: float = LAB_MAX_RANGE, ignore_nodes: Iterable[str] = (),
                  not_run_s: float = 0.0, scan_period_s: float | None = None) -> dict[str, Any]:
    """
    Compare the values of ``kind`` (one of KINDS) the lines print with their scans' truth.

    ``scans`` are the run's scans in time order (``run_trace.ScanSnapshot``: time s, ranges m,
    angle_min and angle_increment rad, range_min and range_max m); ``lines`` the nodes' log
    lines (dicts with ``t`` s, ``node``, ``level``, ``text``), those of ``ignore_nodes`` and
    of stderr left out. A line is about the last scan at or before its time (the node runs in
    lockstep with the simulator: it prints about the scan it has just received).
    ``not_run_s`` (s) is the part of the scenario the run did not reach (a node raised,
    exited, hung or was stopped at a limit): the scans the lidar would have sent in it, one
    every ``scan_period_s`` (s), are scans of the scenario with no line.

    No return and readings beyond ``cap`` (m) are right as ``cap`` or more. A node that caps
    at a distance of its own prints one value wherever the scan reads farther (at least
    SHORTEST_CAP m, or its lidar's range_max when shorter) and, when that is within the
    lidar's range, nothing larger but inf: its values are then judged against that cap
    (inf, or a word for no return, is right wherever the scan reads farther than it), when
    that makes their worst error smaller.

    Returns a JSON-ready dict: ``scans`` (those of the scenario a value is defined for, the
    ones not run included), ``not_run`` (of them, those after the run stopped), ``last_scan_s``
    (the time of the last scan sent, s; 0 for none), ``lines`` (lines a value was
    read from), ``missed`` (scans with no line giving it; for regions, giving all five),
    ``matched_fraction``, ``right`` and ``right_fraction`` (scans with a line giving it within
    RIGHT_WITHIN_M m; for regions, all five), ``parts_right`` (of the scenario's PARTS equal
    parts by scan, those with such a scan), ``cap_m`` (the cap judged with, m), ``mae_m`` and
    ``worst_error_m`` (m) and ``worst`` (the line of the worst error: ``t``, ``node``,
    ``text``, ``what``, ``printed`` as written, ``printed_m``, ``truth_m`` [lowest, highest
    right value]), ``matches`` (for each label whose values are mostly wrong, the beam or
    region they match, :mod:`sim_bridge.scoring.printed_match`: ``what``, ``source``,
    ``lines``, ``of``); for ``closest`` also ``bearing_lines``, ``bearing_mae_deg``,
    ``worst_bearing_error_deg`` and ``worst_bearing``; for ``regions``, ``unprinted``: the
    regions no line gave.
    """
    if kind not in KINDS:
        raise ValueError(f'unknown printed value {kind!r}; one of {", ".join(KINDS)}')
    lines, ignored = list(lines), set(ignore_nodes)
    not_run = 0
    if scan_period_s and not_run_s > 0.0:
        not_run = math.floor(not_run_s / scan_period_s + 0.5)
    scored, comparisons = _score_with(kind, scans, lines, Cap(cap), ignored)
    reach = min((float(snapshot.range_max) for snapshot in scans), default=cap)
    own = _own_cap(comparisons, min(reach, SHORTEST_CAP), reach)
    if own is not None:
        again, mine = _score_with(kind, scans, lines, Cap(own, clamps=own >= reach), ignored)
        if again['worst_error_m'] < scored['worst_error_m']:
            scored, comparisons = again, mine
    return _with_not_run(scored, not_run, float(scans[-1].time) if scans else 0.0)


def _with_not_run(scored: dict[str, Any], not_run: int, last_scan_s: float) -> dict[str, Any]:
    """Return ``scored`` with ``not_run`` more scans (after ``last_scan_s``, s), none printed."""
    counted = scored['scans'] + not_run
    right, printed = scored['right'], counted - scored['missed'] - not_run
    parts = scored.pop('right_scans')
    return {**scored, 'scans': counted, 'not_run': not_run, 'last_scan_s': last_scan_s,
            'missed': counted - printed,
            'matched_fraction': printed / counted if counted else None,
            'right_fraction': right / counted if counted else None,
            'parts_right': len({PARTS * index // counted for index in parts})}


def _own_cap(comparisons: Sequence[Comparison], lowest: float, reach: float) -> float | None:
    """
    Return the cap (m) a node's values keep, or None when they keep none.

    Its cap is the value it prints wherever the scan reads farther: every value (at least
    ``lowest`` m) printed below a farther truth is that one (to CAP_ROUNDING m), and below the
    lidar's ``reach`` (m) no value printed is larger.
    """
    printed = [comparison.printed.value for comparison in comparisons]
    beyond = [value for value, comparison in zip(printed, comparisons)
              if lowest <= value < comparison.truth[0]]
    if not beyond or max(beyond) - min(beyond) > CAP_ROUNDING:
        return None
    cap = max(beyond)
    kept = cap >= reach or all(value <= cap or math.isinf(value) for value in printed)
    return cap if kept else None


def _score_with(kind: str, scans: Sequence[Any], lines: Sequence[Mapping[str, Any]], cap: Cap,
                ignored: set[str]) -> tuple[dict[str, Any], list[Comparison]]:
    """Return :func:`score_printed`'s scores judged with ``cap``, and their comparisons."""
    times = [snapshot.time for snapshot in scans]
    truths: dict[int, Any] = {}

    def truth_of(index: int) -> Any:
        if index not in truths:
            truths[index] = _TRUTHS[kind](scan_of(scans[index]), cap.at)
        return truths[index]

    per_scan = _lines_per_scan(kind, lines, times, ignored, truth_of, cap)
    comparisons: list[Comparison] = []
    bearing_errors: list[tuple[float, Comparison, float]] = []
    matched_lines = counted = missed = 0
    right_scans: list[int] = []
    printed_regions: set[str] = set()
    for index in range(len(scans)):
        truth = truth_of(index)
        wanted = _wanted(kind, truth)
        if not wanted:
            continue
        got, right = set(), set()
        for found, bearing in per_scan.get(index, []):
            matched_lines += 1
            comparisons += found
            got |= {comparison.what for comparison in found}
            right |= {comparison.what for comparison in found
                      if comparison.error <= RIGHT_WITHIN_M}
            true_bearing = truth[1] if kind == 'closest' else None
            if bearing is not None and true_bearing is not None:
                bearing_errors.append((_bearing_error(bearing, true_bearing), found[0],
                                       true_bearing))
        if right >= wanted:
            right_scans.append(counted)
        counted += 1
        printed_regions |= got
        missed += not got >= wanted
    result: dict[str, Any] = {
        'scans': counted, 'lines': matched_lines, 'missed': missed,
        'right': len(right_scans), 'right_scans': right_scans,
        'cap_m': cap.at, 'mae_m': None, 'worst_error_m': None, 'worst': None,
        'matches': _matches(kind, comparisons, scans, cap)}
    if comparisons:
        worst = max(comparisons, key=lambda comparison: comparison.error)
        result['mae_m'] = float(np.mean([comparison.error for comparison in comparisons]))
        result['worst_error_m'] = worst.error
        result['worst'] = _quote(worst, cap)
    if kind == 'regions':
        result['unprinted'] = [_label(name) for name in REGION_NAMES
                               if _label(name) not in printed_regions]
    if kind == 'closest':
        result.update(_bearing_scores(bearing_errors, cap))
    return result, comparisons


def _bearing_scores(bearing_errors: list[tuple[float, Comparison, float]],
                    cap: Cap) -> dict[str, Any]:
    """Return the closest obstacle's bearing scores from (error rad, line, truth rad)."""
    scores: dict[str, Any] = {'bearing_lines': len(bearing_errors), 'bearing_mae_deg': None,
                              'worst_bearing_error_deg': None, 'worst_bearing': None}
    if bearing_errors:
        error, comparison, truth = max(bearing_errors, key=lambda item: item[0])
        scores['bearing_mae_deg'] = math.degrees(
            float(np.mean([item[0] for item in bearing_errors])))
        scores['worst_bearing_error_deg'] = math.degrees(error)
        scores['worst_bearing'] = {**_quote(comparison, cap), 'truth_deg': math.degrees(truth)}
    return scores


def _matches(kind: str, comparisons: Sequence[Comparison], scans: Sequence[Any],
             cap: Cap) -> list[dict[str, Any]]:
    """
    Return, for each label whose values are mostly wrong, the beam or region they match.

    Each a dict: ``what`` (the label), ``source`` (as printed_match names it), ``lines``
    (values it matches), ``of`` (values printed with the label).
    """
    by_label: dict[str, list[Comparison]] = {}
    for comparison in comparisons:
        by_label.setdefault(comparison.what, []).append(comparison)
    found = []
    for what, mine in by_label.items():
        right = sum(comparison.error <= RIGHT_WITHIN_M for comparison in mine)
        if right == len(mine):
            continue
        source = matching_source([cap.read(comparison.printed.value) for comparison in mine],
                                 [scan_of(scans[comparison.scan]) for comparison in mine],
                                 cap.at, RIGHT_WITHIN_M,
                                 (lambda scan: region_truths(scan, cap.at))
                                 if kind == 'regions' else None)
        if source is not None and source[1] > right:
            found.append({'what': what, 'source': source[0], 'lines': source[1],
                          'of': len(mine)})
    return found


def _label(name: str) -> str:
    """Return how a report names a region: 'front-left' for ``front_left``."""
    return name.replace('_', '-')


def _read_range_ahead_values(text: str) -> tuple[list[tuple[str, Number]], None]:
    printed = read_range_ahead(text)
    return ([('range ahead', printed)] if printed is not None else []), None


def _read_region_values(text: str) -> tuple[list[tuple[str, Number]], None]:
    return [(_label(name), printed) for name, printed in read_regions(text)], None


def _read_closest_values(text: str) -> tuple[list[tuple[str, Number]], float | None]:
    printed, bearing = read_closest(text)
    return ([('closest obstacle', printed)] if printed is not None else []), bearing


def _region_truths_by_label(scan: Scan, cap: float) -> dict[str, tuple[float, float]]:
    return {_label(name): truth for name, truth in region_truths(scan, cap).items()
            if truth is not None}


def _range_ahead_by_label(scan: Scan, cap: float) -> dict[str, tuple[float, float]]:
    truth = range_ahead_truth(scan, cap)
    return {'range ahead': truth} if truth is not None else {}


#: Per kind: what reads a line's values ([(what, Number)], bearing rad or None) ...
_READERS = {'range_ahead': _read_range_ahead_values, 'regions': _read_region_values,
            'closest': _read_closest_values}
#: ... and what gives a scan's truth: {what: (lowest, highest) m}, or for closest
#: (distance m, bearing rad or None).
_TRUTHS = {'range_ahead': _range_ahead_by_label, 'regions': _region_truths_by_label,
           'closest': closest_truth}


def _wanted(kind: str, truth: Any) -> set[str]:
    """Return what a line must give about a scan of ``truth``: nothing when none is defined."""
    return {'closest obstacle'} if kind == 'closest' else set(truth)


def _compare_line(kind: str, values: list[tuple[str, Number]], truth: Any, cap: Cap,
                  line: Mapping[str, Any], scan: int) -> list[Comparison]:
    """Return the comparisons of a line's values with scan ``scan``'s truth (those defined)."""
    if kind == 'closest':
        return [_compare(what, printed, (truth[0], truth[0]), cap, line, scan)
                for what, printed in values]
    return [_compare(what, printed, truth[what], cap, line, scan) for what, printed in values
            if what in truth]


def excerpt(text: str, at: int, chars: int = QUOTE_CHARS) -> str:
    """Return ``text``, or the ``chars`` of it around position ``at``, cuts marked '...'."""
    if len(text) <= chars:
        return text
    # The number read ends the excerpt's first two thirds: what labels it comes before it.
    start = min(max(at - 2 * chars // 3, 0), len(text) - chars)
    head = '...' if start > 0 else ''
    tail = '...' if start + chars < len(text) else ''
    return head + text[start + len(head):start + chars - len(tail)] + tail


def _quote(comparison: Comparison, cap: Cap) -> dict[str, Any]:
    line = comparison.line
    text = str(line.get('text', ''))
    return {'t': float(line['t']), 'node': str(line.get('node') or ''),
            'text': excerpt(text, comparison.printed.start),
            'what': comparison.what, 'printed': comparison.printed.written,
            'printed_m': cap.read(comparison.printed.value),
            'truth_m': list(comparison.truth)}


def _metres(value: float) -> str:
    return f'{value:.2f} m'


def _error(value: float) -> str:
    return f'{value:.3f} m'


def _nearest_truth(worst: Mapping[str, Any]) -> float:
    low, high = worst['truth_m']
    return min(max(worst['printed_m'], low), high)


def judge_printed(kind: str, scored: Mapping[str, Any] | None, *, max_error_m: float,
                  min_matched_fraction: float,
                  max_bearing_error_deg: float | None = None) -> tuple[bool, str]:
    """
    Judge a kind's scores (:func:`score_printed`) against tolerances; return (passed, why).

    ``why`` is one line: the worst printed value, where and what the truth was, how many lines
    and missed scans, the node's own cap when it has one (see :func:`score_printed`), e.g.
    ``scan_around: front-left printed 2.31 m at t=4.2 s, truth 1.05 m: 'front-left: 2.31 m'
    (worst of 38 lines; 12 of 50 scans with no line)``.
    """
    title = KIND_TITLES[kind]
    if not scored or not scored.get('scans'):
        return False, f'no scan to compare a printed {title} with'
    scans, lines, missed = scored['scans'], scored['lines'], scored['missed']
    fraction = scored['matched_fraction']
    tally = f'{lines} lines; {missed} of {scans} scans with no line'
    if kind == 'regions' and scored.get('unprinted') and lines:
        tally += f" ({', '.join(scored['unprinted'])} never printed)"
    if scored.get('cap_m') not in (None, LAB_MAX_RANGE):
        tally += f"; its own cap {scored['cap_m']:g} m"
    worst = scored.get('worst')
    if worst is None:
        return False, f'no line printed the {title} ({scans} scans)'
    who = f"{worst['node']}: " if worst['node'] else ''
    if scored['worst_error_m'] > max_error_m:
        return False, (f"{who}{worst['what']} printed {worst['printed']} at t={worst['t']:.1f} "
                       f"s, truth {_metres(_nearest_truth(worst))}: {worst['text']!r} "
                       f'(worst of {tally})')
    bearing = scored.get('worst_bearing') if kind == 'closest' else None
    if (bearing and max_bearing_error_deg is not None
            and scored['worst_bearing_error_deg'] > max_bearing_error_deg):
        return False, (f"{who}closest obstacle's bearing {bearing['text']!r} at "
                       f"t={bearing['t']:.1f} s, truth {bearing['truth_deg']:+.1f} deg "
                       f"(error {scored['worst_bearing_error_deg']:.1f} deg, worst of "
                       f"{scored['bearing_lines']} lines with a bearing)")
    if fraction < min_matched_fraction:
        return False, (f'{who}{missed} of {scans} scans with no line giving the {title} '
                       f'({100.0 * fraction:.0f} % printed, {100.0 * min_matched_fraction:.0f} '
                       f"% wanted; worst error {_error(scored['worst_error_m'])} in "
                       f'{lines} lines)')
    bearing_text = (f", bearing within {scored['worst_bearing_error_deg']:.1f} deg"
                    if bearing else '')
    return True, f"worst error {_error(scored['worst_error_m'])}{bearing_text} ({tally})"
