"""
The handout's points of each lab task, measured from a run and judged one by one.

The handout marks each task by what it asks: task 2's wanderbot drives straight, stops when
something is within 0.7 m ahead, turns more than 90 degrees, resumes, repeats, without a
collision; task 4's wall follower loops the object in one direction of its choosing, keeping
the wall at a distance of its choosing, without a collision; tasks 1 and 3 print the range
ahead and the five region minima for every scan. Each point earns its share of the task's
marks on its own, so a fault costs the points it breaks, not the whole task.

Two steps, both pure (numpy, no rclpy): the *evidence* of a run (:func:`wander_evidence`,
:func:`wall_follow_evidence`) is computed from its ground-truth trace with the other metrics
and kept in ``metrics.json``; the *points* (:func:`judge_points`) are judged from the metrics
alone, so a report read back judges them again the same way. Each judged point has a one-line
reason when it is not earned.
"""

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from sim_bridge.scoring.metrics import (
    BRAKING_MARGIN, MAX_BLOCKED_DRIVING_S, STOP_DISTANCE, WALL_BAND)
from sim_bridge.scoring.printed_values import judge_printed, PARTS, RIGHT_WITHIN_M

#: A stop counts as for an obstacle when something is this close (m) in the cone ahead:
#: the handout's 0.7 m and the distance braking and a controller's margin add.
STOP_SLACK = 0.2
#: Stop-turn-resume cycles that make "repeats".
REPEATS = 3
#: The share of a run's turns that must satisfy a point about each turn: one odd turn (cut
#: short by the end of the run or by a wall) does not undo a behaviour seen in the others.
MOST = 0.8
#: The least distance (m) a robot must drive for points that only a moving robot can show.
MIN_DRIVEN = 1.0
#: The wall distance's mean error (m) around the chosen distance while following.
WALL_TOLERANCE = 0.15
#: ... and must then follow for at least this share of the run.
MIN_FOLLOWING = 0.5
#: The worst printed value's error (m) and the share of the scenario's scans a right line
#: must be about.
PRINTED_ERROR = RIGHT_WITHIN_M
PRINTED_SHARE = 0.9

#: The point sets a scenario's ``points:`` can name, and the printed kind each reads.
POINT_SETS = ('range_ahead', 'wander', 'regions', 'wall_follow', 'closest')


@dataclass(frozen=True)
class Point:
    """One point of a task judged on one run: what it asks, earned or not, and why not."""

    point: str
    earned: bool
    reason: str = ''
    #: The rule the point is judged by: the handout's sentence, what is measured, the margin.
    rule: str = ''

    def as_dict(self) -> dict[str, Any]:
        """Return the point for a JSON report."""
        return {'point': self.point, 'earned': self.earned, 'reason': self.reason,
                'rule': self.rule}


def _share(items: Sequence[Any], test: Callable[[Any], bool]) -> tuple[int, int]:
    return sum(1 for item in items if test(item)), len(items)


def wander_points(evidence: Mapping[str, Any], collisions: int) -> list[Point]:
    """Judge the handout's six wanderbot points on a run's evidence and collision count."""
    driven, straight = evidence['distance_m'], evidence['straight_m']
    turns = evidence['turns']
    moved = driven >= MIN_DRIVEN
    points = [Point('drives straight', moved and straight >= 0.5 * driven,
                    f'drove {straight:.1f} m of its {driven:.1f} m in a straight line (at least '
                    f'{MIN_DRIVEN:g} m and half of the path wanted)')]
    near, count = _share(turns, lambda turn: turn['ahead_m'] is not None
                         and turn['ahead_m'] <= STOP_DISTANCE + STOP_SLACK)
    blocked = evidence['blocked_driving_s']
    if not count:
        why = 'never stopped to turn'
    elif blocked > MAX_BLOCKED_DRIVING_S:
        why = (f'drove on for {blocked:.1f} s with the way ahead under '
               f'{STOP_DISTANCE - BRAKING_MARGIN:g} m')
    else:
        why = (f'{count - near} of {count} stops with nothing within '
               f'{STOP_DISTANCE + STOP_SLACK:g} m ahead')
    points.append(Point(f'stops when something is within {STOP_DISTANCE:g} m ahead',
                        count > 0 and blocked <= MAX_BLOCKED_DRIVING_S and near >= MOST * count,
                        why))
    wide, count = _share(turns, lambda turn: turn['deg'] > 90.0)
    smallest = min((turn['deg'] for turn in turns), default=0.0)
    points.append(Point('turns more than 90 degrees', count > 0 and wide >= MOST * count,
                        f'{count - wide} of {count} turns not more than 90 degrees (smallest '
                        f'{smallest:.0f})' if count else 'never stopped to turn'))
    decided = [turn for turn in turns if turn['resumed'] is not None]
    resumed, count = _share(decided, lambda turn: turn['resumed'])
    points.append(Point('resumes driving straight after a turn',
                        count > 0 and resumed >= MOST * count,
                        f'drove on after {resumed} of {count} turns' if count
                        else 'no turn to drive on from'))
    points.append(Point('repeats the sequence', resumed >= REPEATS,
                        f'{resumed} stop-turn-resume cycles ({REPEATS} wanted)'))
    points.append(Point('no collision', moved and collisions == 0,
                        f'{collisions} collision(s)' if collisions
                        else f'drove {driven:.1f} m only: no collision shown'))
    return points


def wall_follow_points(evidence: Mapping[str, Any], collisions: int) -> list[Point]:
    """Judge the handout's three wall-follower points on a run's evidence and collisions."""
    laps, winding = evidence['laps'], evidence['winding']
    points = [Point('loops the object in one direction', laps != 0,
                    f'went {abs(winding):.2f} of the way round the object: no full loop')]
    chosen, mae = evidence['chosen_m'], evidence['mae_m']
    how = 'its parameter' if evidence['declared_m'] is not None else 'its median'
    low, high = WALL_BAND
    if chosen is None:
        why = 'no wall distance measured'
    elif not low <= chosen <= high:
        why = f'wall distance {chosen:.2f} m ({how}) outside {low:g}-{high:g} m'
    elif mae is None or evidence['following'] < MIN_FOLLOWING:
        why = (f'followed the wall at {chosen:.2f} m ({how}) for '
               f"{100 * evidence['following']:.0f} % of the run only")
    elif mae > WALL_TOLERANCE:
        why = (f'wall distance off {chosen:.2f} m ({how}) by {mae:.2f} m on average '
               f'({WALL_TOLERANCE:g} m allowed)')
    elif evidence['distance_m'] < MIN_DRIVEN:
        why = f"drove {evidence['distance_m']:.1f} m only"
    else:
        why = ''
    points.append(Point('keeps the wall at the distance it chose', not why, why))
    points.append(Point('no collision', evidence['distance_m'] >= MIN_DRIVEN and not collisions,
                        f'{collisions} collision(s)' if collisions
                        else f"drove {evidence['distance_m']:.1f} m only: no collision shown"))
    return points


#: What each reading task prints, as its points name it.
_PRINTED_WHAT = {'range_ahead': 'the range ahead', 'regions': 'the five region minima',
                 'closest': 'the nearest obstacle'}
#: The handout's (or the guide's) sentence each reading task's points rest on.
_PRINTED_SENTENCE = {
    'range_ahead': 'Handout, task 1: "the range values from only the front-most laser must be '
                   'printed" as the robot moves.',
    'regions': 'Handout, task 3: five regions (right, front-right, front, front-left, left), '
               '"each region gives out the smallest value among its laser samples", Inf as '
               '10 m, "five values printed on the terminal at any given time".',
    'closest': 'Guide: the distance (and bearing) of the nearest obstacle, printed for each '
               'scan.'}
#: What counts as the right value, per reading task.
_PRINTED_TRUTH = {
    'range_ahead': 'a beam within one increment of straight ahead (beams 17 and 18 of the '
                   'lab lidar), or a value between them',
    'regions': "each region's minimum (36-degree bands centred on -72, -36, 0, 36, 72 "
               'degrees; a beam on the edge of two bands in either)',
    'closest': 'the nearest valid return'}


def printed_rules(kind: str) -> tuple[str, str]:
    """Return the rules of a reading task's two points: the handout, the measure, the margin."""
    sentence, truth = _PRINTED_SENTENCE[kind], _PRINTED_TRUTH[kind]
    within = (f'within {PRINTED_ERROR:g} m of {truth} of the scan it had just received, no '
              "return as 10 m, inf or the node's own cap")
    return (f"{sentence} Measured: every scan of the scenario's whole duration needs a line "
            f'whose value is {within}; a node that stops (raises, exits, hangs, is stopped '
            "at a limit) has missed every scan after it, and another beam's or region's range "
            f'does not count. Margin: {100 * PRINTED_SHARE:.0f} % of the scans.',
            f'{sentence} Measured: every value printed is {within}, and right values come '
            f'throughout the scenario: a right line in each of its {PARTS} equal parts (a '
            'node that stops or falls silent loses it). Margin: none beyond the '
            f'{PRINTED_ERROR:g} m.')


def _printed_hint(kind: str, scored: Mapping[str, Any]) -> str:
    """Return what the printed values match instead of the asked-for ones, or ''."""
    hints = []
    for match in scored.get('matches') or []:
        if kind == 'range_ahead':
            hints.append(f"the printed values match {match['source']}, not the beam ahead")
        elif kind == 'regions':
            hints.append(f"the values printed as {match['what']} match {match['source']}, "
                         f"not the {match['what']} region")
        else:
            hints.append(f"the printed values match {match['source']}, not the nearest return")
    return '; '.join(hints)


def _stopped(scored: Mapping[str, Any]) -> str:
    """Say when the run stopped before the scenario's end, or ''."""
    if not scored.get('not_run'):
        return ''
    return (f"the node stopped at t={scored['last_scan_s']:.1f} s: the {scored['not_run']} "
            'scans after it count as missed')


def printed_points(kind: str, scored: Mapping[str, Any] | None) -> list[Point]:
    """
    Judge a reading task's two points on its printed values' scores (printed_values).

    Printed for each scan: PRINTED_SHARE of the scenario's scans have a line giving the value
    asked for within PRINTED_ERROR m (capped as the node caps: no return as the lab's 10 m, inf
    or a word, or the node's own cap where it keeps one; see printed_values). Right: every
    value printed within PRINTED_ERROR m, and right lines in each of the scenario's PARTS
    parts. The rules, as :func:`printed_rules` states them, go with the points.
    """
    what = _PRINTED_WHAT[kind]
    scored = scored or {}
    scans, share = scored.get('scans') or 0, scored.get('right_fraction')
    lines = scored.get('lines') or 0
    each, right = printed_rules(kind)
    if share is None:
        missing = 'no scan to print about'
    else:
        missing = (f"{scans - scored['right']} of {scans} scans with no line giving {what} "
                   f'within {PRINTED_ERROR:g} m ({100 * share:.0f} % printed right, '
                   f'{100 * PRINTED_SHARE:.0f} % wanted)')
        if kind == 'regions' and scored.get('unprinted') and lines:
            missing += f" ({', '.join(scored['unprinted'])} never printed)"
    worst_right, why = judge_printed(kind, scored, max_error_m=PRINTED_ERROR,
                                     min_matched_fraction=0.0)
    parts = scored.get('parts_right') or 0
    if worst_right and parts < PARTS:
        why = (f"right values in {parts} of the scenario's {PARTS} parts only"
               + (f" ({', '.join(scored['unprinted'])} never printed)"
                  if kind == 'regions' and scored.get('unprinted') else ''))
    reasons = [_joined(missing, _stopped(scored), _printed_hint(kind, scored)),
               _joined(why, _stopped(scored), _printed_hint(kind, scored))]
    return [Point(f'prints {what} for each scan', share is not None and share >= PRINTED_SHARE,
                  reasons[0], each),
            Point(f'{what} printed right (capped as the node caps)',
                  worst_right and lines > 0 and parts >= PARTS, reasons[1], right)]


def _joined(*parts: str) -> str:
    return '; '.join(part for part in parts if part)


def judge_points(point_set: str, metrics: Mapping[str, Any]) -> list[Point]:
    """
    Judge the points of ``point_set`` (one of POINT_SETS) on a run's metrics.

    A run whose node raised loses every point it had not shown yet: the metrics hold only
    what happened before. Earned points have no reason.
    """
    collisions = int(metrics.get('collisions') or 0)
    if point_set == 'wander':
        points = wander_points(metrics['wander'], collisions)
    elif point_set == 'wall_follow':
        points = wall_follow_points(metrics['wall_follow'], collisions)
    else:
        points = printed_points(point_set, (metrics.get('printed') or {}).get(point_set))
    return [Point(point.point, point.earned, '' if point.earned else point.reason, point.rule)
            for point in points]


#: The metrics of a run that showed nothing: what a run that never ran is judged on.
_NOTHING_SHOWN = {
    'collisions': 0, 'printed': {},
    'wander': {'distance_m': 0.0, 'straight_m': 0.0, 'blocked_driving_s': 0.0, 'turns': []},
    'wall_follow': {'laps': 0, 'winding': 0.0, 'distance_m': 0.0, 'chosen_m': None,
                    'declared_m': None, 'following': 0.0, 'mae_m': None}}


def unearned_points(point_set: str, reason: str) -> list[Point]:
    """Return the points of ``point_set``, none earned, each for ``reason`` (one line)."""
    return [Point(point.point, False, reason, point.rule)
            for point in judge_points(point_set, _NOTHING_SHOWN)]
