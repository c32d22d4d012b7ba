"""
The handout's points of each lab task, measured from a run and judged one by one.

The handout marks each task by what it asks: task 2's wanderbot drives straight, stops when
something is within 0.7 m ahead, turns more than 90 degrees, resumes, repeats, without a
collision; task 4's wall follower loops the object in one direction of its choosing, keeping
the wall at a distance of its choosing, without a collision; tasks 1 and 3 print the range
ahead and the five region minima for every scan. Each point earns its share of the task's
marks on its own, so a fault costs the points it breaks, not the whole task. A point is
evidence that the node did what it names, over the whole run, not the absence of a failure:
the motion points count only what an obstacle caused, a robot that wandered, a wall followed.

Two steps, both pure (numpy, no rclpy): the *evidence* of a run
(:mod:`sim_bridge.scoring.motion_evidence`, the printed values' scores) is computed from its
ground-truth trace with the other metrics and kept in ``metrics.json``; the *points*
(:func:`judge_points`) are judged from the metrics alone, so a report read back judges them
again the same way. Each judged point has a one-line reason when it is not earned, and each
motion point its rule (the handout's sentence, what is measured, the margin).
"""

from dataclasses import dataclass
import math
from typing import Any, Callable, Mapping, Sequence

from sim_bridge.scoring.motion_evidence import (
    BRAKING_MARGIN, CAUSE_DISTANCE, DRIVING_SPEED, MAX_BLOCKED_DRIVING_S, RESUME_DISTANCE,
    RESUME_WINDOW_S, STALL_S, STOP_CONE, STOP_DISTANCE, STRAIGHT_ANGULAR, WALL_BAND,
    WALL_SETTLED)
from sim_bridge.scoring.printed_values import judge_printed, PARTS, RIGHT_WITHIN_M

#: Stop-turn-resume cycles that make "repeats".
REPEATS = 3
#: The share of a run's turns that must satisfy a point about each turn: one odd turn (cut
#: short by the end of the run or by a wall) does not undo a behaviour seen in the others.
MOST = 0.8
#: The least distance (m) a robot must drive for points that only a moving robot can show.
MIN_DRIVEN = 1.0
#: A wanderbot wandered when it moved (DRIVING_SPEED) for at least this share of its run: less
#: is a robot stuck (pinned on a wall, stopped for good) for most of it.
WANDERED_SHARE = 0.5
#: A turn is more than 90 degrees when measured at 90 plus this (deg) or more: above the
#: measurement's error, the turn of one 0.01 s physics step at the handout's 3.14 rad/s (1.8).
TURN_MARGIN_DEG = 2.0
#: A follower follows the wall once it moved along the object this share of a loop.
FOLLOW_LOOP_SHARE = 0.75
#: The wall distance's mean error (m) around the chosen distance while following.
WALL_TOLERANCE = 0.15
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


#: How each motion point is judged (shown beside it): the handout's sentence, what is
#: measured, the margin. Keyed by the point's name.
WANDER_RULES = {
    'drives straight': (
        f'"The robot normally drives in a straight line." Only for a robot that wandered: it '
        f'moved (over {DRIVING_SPEED:g} m/s) for {100 * WANDERED_SHARE:.0f} % of the run or more; '
        f'then at least half of its path, and {MIN_DRIVEN:g} m, driven with the turn rate under '
        f'{STRAIGHT_ANGULAR:g} rad/s.'),
    f'stops when something is within {STOP_DISTANCE:g} m ahead': (
        f'"When the robot sees an obstacle in front within {STOP_DISTANCE:g} meters, it will '
        f'stop." A stop-and-turn counts when an obstacle caused it: something within '
        f'{CAUSE_DISTANCE:g} m in the ±{math.degrees(STOP_CONE):.0f}° cone ahead as it began, '
        f'and no collision on the way there (a turn after hitting a wall does not count). At '
        f'least one, and {100 * MOST:.0f} % of its stop-and-turns (else this point and the '
        f'next three are lost: its turns are not for obstacles but, say, a timer); never driving '
        f'on for more than {MAX_BLOCKED_DRIVING_S:g} s with under '
        f'{STOP_DISTANCE - BRAKING_MARGIN:g} m straight ahead.'),
    'turns more than 90 degrees': (
        f'"The turn should be more than 90 degrees." {100 * MOST:.0f} % of the caused '
        f'stop-and-turns measured at {90 + TURN_MARGIN_DEG:g}° or more (ground-truth heading; '
        f'{TURN_MARGIN_DEG:g}° above the error of the measurement, one 0.01 s step of turning at '
        f'3.14 rad/s); standing {STALL_S:g} s or more facing an obstacle within '
        f'{CAUSE_DISTANCE:g} m without turning counts as a turn not made.'),
    'resumes driving straight after a turn': (
        f'"The robot then resumes moving in the straight line." After {100 * MOST:.0f} % of '
        f'the caused stop-and-turns (and stops that never turned) it drove on '
        f'{RESUME_DISTANCE:g} m within {RESUME_WINDOW_S:g} s; lost by a robot stuck for most '
        f'of the run (moving less than {100 * WANDERED_SHARE:.0f} % of it).'),
    'repeats the sequence': (
        f'"This sequence is repeated." {REPEATS} caused stop-turn-resume cycles; lost by a '
        f'robot stuck for most of the run.'),
    'no collision': (
        f'"A wandering robot which simply turns away from obstacles": no contact with '
        f'anything, only for a robot that wandered (moved for {100 * WANDERED_SHARE:.0f} % of '
        f'the run or more).'),
}
WALL_FOLLOW_RULES = {
    'loops the object in one direction': (
        '"The robot move around the model object either in clockwise or counterclockwise '
        'manner": a full loop round the object (the robot winds once round every point inside '
        'it), one way.'),
    'keeps the wall at the distance it chose': (
        f'"The robot must use its lasers to track the wall of the object." Judged only while '
        f'the robot moves along the object (over {DRIVING_SPEED:g} m/s within '
        f'{WALL_BAND[1]:g} m of it), for '
        f'{FOLLOW_LOOP_SHARE:g} of a loop or more: the distance it chose (its parameter, else '
        f'its median while moving along) within {WALL_BAND[0]:g}-{WALL_BAND[1]:g} m, a mean '
        f'error of at most {WALL_TOLERANCE:g} m from the first time within {WALL_SETTLED:g} m '
        f'of it.'),
    'no collision': (
        f'"Move along walls without hitting them": no contact, only for a robot that moved '
        f'along the object for {FOLLOW_LOOP_SHARE:g} of a loop or more (a parked or crashed '
        f'robot shows none).'),
}


def _share(items: Sequence[Any], test: Callable[[Any], bool]) -> tuple[int, int]:
    return sum(1 for item in items if test(item)), len(items)


def _ruled(points: list[tuple[str, bool, str]], rules: Mapping[str, str]) -> list[Point]:
    """Return the (point, earned, reason) triples as Points with each one's rule."""
    return [Point(point, earned, reason, rules[point]) for point, earned, reason in points]


def wander_points(evidence: Mapping[str, Any], collisions: int) -> list[Point]:
    """Judge the handout's six wanderbot points on a run's evidence and collision count."""
    driven, straight = evidence['distance_m'], evidence['straight_m']
    duration, moving = evidence.get('duration_s', 0.0), evidence.get('moving_s', 0.0)
    wandered = driven >= MIN_DRIVEN and moving >= WANDERED_SHARE * duration > 0.0
    stuck = '' if wandered else (f'moved {moving:.0f} s of {duration:.0f} s only: stuck for '
                                 'most of the run, not wandering')
    turns, stalls = evidence['turns'], evidence.get('stalls') or []
    caused = [turn for turn in turns if turn.get('caused')]
    points = [('drives straight', wandered and straight >= 0.5 * driven, stuck or (
        f'drove {straight:.1f} m of its {driven:.1f} m in a straight line'))]
    blocked = evidence['blocked_driving_s']
    uncaused = (f'{len(turns) - len(caused)} of {len(turns)} stop-and-turns not caused by an '
                'obstacle ahead' if turns else 'never stopped to turn')
    for_obstacles = bool(caused) and len(caused) >= MOST * len(turns)
    points.append((f'stops when something is within {STOP_DISTANCE:g} m ahead',
                   for_obstacles and blocked <= MAX_BLOCKED_DRIVING_S,
                   uncaused if not for_obstacles else (
                       f'drove on for {blocked:.1f} s with the way ahead under '
                       f'{STOP_DISTANCE - BRAKING_MARGIN:g} m')))
    wide, count = _share(caused, lambda turn: turn['deg'] >= 90.0 + TURN_MARGIN_DEG)
    count += len(stalls)
    smallest = min((turn['deg'] for turn in caused), default=0.0)
    never = f', {len(stalls)} stop(s) that never turned' if stalls else ''
    points.append(('turns more than 90 degrees', for_obstacles and wide >= MOST * count,
                   f'{count - wide} of {count} stops without a turn of {90 + TURN_MARGIN_DEG:g}° '
                   f'or more (smallest {smallest:.1f}°{never})' if for_obstacles else uncaused))
    decided = [turn for turn in caused if turn['resumed'] is not None]
    resumed, count = _share(decided, lambda turn: turn['resumed'])
    count += len(stalls)
    points.append(('resumes driving straight after a turn',
                   wandered and for_obstacles and count > 0 and resumed >= MOST * count,
                   stuck or (f'drove on after {resumed} of {count} stops for an obstacle'
                             if for_obstacles else uncaused)))
    points.append(('repeats the sequence', wandered and for_obstacles and resumed >= REPEATS,
                   stuck or (f'{resumed} stop-turn-resume cycles for an obstacle ({REPEATS} '
                             'wanted)' if for_obstacles else uncaused)))
    points.append(('no collision', wandered and collisions == 0,
                   f'{collisions} collision(s)' if collisions else stuck))
    return _ruled(points, WANDER_RULES)


def wall_follow_points(evidence: Mapping[str, Any], collisions: int) -> list[Point]:
    """Judge the handout's three wall-follower points on a run's evidence and collisions."""
    laps, winding = evidence['laps'], evidence['winding']
    along = evidence.get('along_turns', 0.0)
    followed = along >= FOLLOW_LOOP_SHARE
    never = ('' if followed else f'moved along the object for {along:.2f} of a loop only '
             f'({FOLLOW_LOOP_SHARE:g} wanted): not following it')
    points = [('loops the object in one direction', laps != 0,
               f'went {abs(winding):.2f} of the way round the object: no full loop')]
    chosen, mae = evidence['chosen_m'], evidence['mae_m']
    how = 'its parameter' if evidence['declared_m'] is not None else 'its median'
    low, high = WALL_BAND
    if never:
        why = never
    elif chosen is None or mae is None:
        why = 'no wall distance measured'
    elif not low <= chosen <= high:
        why = f'wall distance {chosen:.2f} m ({how}) outside {low:g}-{high:g} m'
    elif mae > WALL_TOLERANCE:
        why = (f'wall distance off {chosen:.2f} m ({how}) by {mae:.2f} m on average '
               f'({WALL_TOLERANCE:g} m allowed)')
    else:
        why = ''
    points.append(('keeps the wall at the distance it chose', not why, why))
    points.append(('no collision', followed and not collisions,
                   f'{collisions} collision(s)' if collisions else never))
    return _ruled(points, WALL_FOLLOW_RULES)


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
    'wander': {'duration_s': 0.0, 'moving_s': 0.0, 'distance_m': 0.0, 'straight_m': 0.0,
               'blocked_driving_s': 0.0, 'turns': [], 'stalls': []},
    'wall_follow': {'laps': 0, 'winding': 0.0, 'distance_m': 0.0, 'along_turns': 0.0,
                    'chosen_m': None, 'declared_m': None, 'mae_m': None}}


def unearned_points(point_set: str, reason: str) -> list[Point]:
    """Return the points of ``point_set``, none earned, each for ``reason`` (one line)."""
    return [Point(point.point, False, reason, point.rule)
            for point in judge_points(point_set, _NOTHING_SHOWN)]
