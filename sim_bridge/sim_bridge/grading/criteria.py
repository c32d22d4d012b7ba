"""
A scenario's criteria: ``METRIC OP NUMBER`` on the run's metrics, and printed-value criteria.

``wall_distance_m.mean_abs_error_m <= 0.1``, ``min(gaps) > 0``: a metric of
sim_bridge.scoring.metrics (a dotted path into ``metrics.json``, optionally inside one of
min/max/len/all/any/abs) against a number. ``printed_<kind>`` judges what a node printed
(sim_bridge.scoring.printed_values) against the scans. The scenario file format is
sim_bridge.grading.scenario's.
"""

from collections.abc import Mapping
from dataclasses import dataclass
import math
import operator
import re
from typing import Any, Callable

from sim_bridge.common.values import described, is_number_not_nan
from sim_bridge.scoring.metrics import METRIC_KINDS
from sim_bridge.scoring.printed_values import judge_printed, KINDS as PRINTED_KINDS

#: A printed-value criterion's key: ``printed_<kind>`` for each kind of printed_values.KINDS.
PRINTED_PREFIX = 'printed_'
#: A printed-value criterion's settings, and whether each is required.
PRINTED_SETTINGS = {'max_error_m': True, 'min_matched_fraction': True,
                    'max_bearing_error_deg': False}
_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    '<=': operator.le, '>=': operator.ge, '==': operator.eq, '!=': operator.ne,
    '<': operator.lt, '>': operator.gt}
_FUNCTIONS = ('min', 'max', 'len', 'all', 'any', 'abs')
_NAME = r'[A-Za-z_][A-Za-z0-9_]*'
_CRITERION = re.compile(
    rf'^\s*(?:(?P<function>{_NAME})\s*\(\s*(?P<inner>{_NAME}(?:\.{_NAME})*)\s*\)'
    rf'|(?P<plain>{_NAME}(?:\.{_NAME})*))'
    r'\s*(?P<op><=|>=|==|!=|<|>)\s*'
    r'(?P<number>[-+]?(?:inf|(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?))\s*$')


def format_value(value: Any) -> str:
    """Return a short text for a measured value: 4 significant digits for floats."""
    if value is None:
        return 'null'
    if isinstance(value, bool) or not isinstance(value, float):
        return str(value)
    return f'{value:.4g}'


@dataclass(frozen=True)
class CriterionResult:
    """One criterion judged on one run's metrics: ``value`` is what was measured (JSON-able)."""

    criterion: str
    passed: bool
    value: Any
    shown: str

    def as_dict(self) -> dict[str, Any]:
        """Return the result for the JSON report."""
        return {'criterion': self.criterion, 'passed': self.passed, 'value': self.value,
                'shown': self.shown}


@dataclass(frozen=True)
class Criterion:
    """A parsed pass criterion ``function(path) op threshold`` (``function`` may be None)."""

    text: str
    path: tuple[str, ...]
    op: str
    threshold: float
    function: str | None = None

    def evaluate(self, metrics: Mapping[str, Any]) -> CriterionResult:
        """Judge the criterion on a run's metrics."""
        value = metrics
        for key in self.path:
            value = value.get(key) if isinstance(value, Mapping) else None
        compare = _OPERATORS[self.op]

        def holds(number: Any) -> bool:
            return isinstance(number, (int, float)) and compare(number, self.threshold)

        if self.function in ('all', 'any'):
            values = list(value or [])
            passed = (all if self.function == 'all' else any)(holds(item) for item in values)
            shown = (f'{len(values)} values, min {format_value(min(values))}, max '
                     f'{format_value(max(values))}' if values else 'no values')
            return CriterionResult(self.text, passed, values, shown)
        if self.function in ('min', 'max'):
            value = (min if self.function == 'min' else max)(value) if value else None
        elif self.function == 'len':
            value = len(value) if value is not None else None
        elif self.function == 'abs' and value is not None:
            value = abs(value)
        return CriterionResult(self.text, holds(value), value, format_value(value))


@dataclass(frozen=True)
class PrintedCriterion:
    """
    A criterion on what the nodes print: ``kind`` of printed_values.KINDS within tolerances.

    ``max_error_m`` (m) bounds the worst printed value's error, ``min_matched_fraction`` the
    share of scans a line gave the value for; ``max_bearing_error_deg`` (deg) the closest
    obstacle's printed bearing, when it is printed.
    """

    text: str
    kind: str
    max_error_m: float
    min_matched_fraction: float
    max_bearing_error_deg: float | None = None

    def evaluate(self, metrics: Mapping[str, Any]) -> CriterionResult:
        """Judge the criterion on a run's metrics; the measured value is the one-line why."""
        scored = (metrics.get('printed') or {}).get(self.kind)
        passed, why = judge_printed(self.kind, scored, max_error_m=self.max_error_m,
                                    min_matched_fraction=self.min_matched_fraction,
                                    max_bearing_error_deg=self.max_bearing_error_deg)
        return CriterionResult(self.text, passed, why, why)


def parse_printed_criterion(item: Mapping[Any, Any]) -> PrintedCriterion:
    """
    Parse ``{printed_<kind>: {max_error_m: .., min_matched_fraction: ..}}``.

    ValueError says what is wrong: the key, a setting unknown or missing, a value out of range.
    """
    names = ', '.join(PRINTED_PREFIX + kind for kind in PRINTED_KINDS)
    if len(item) != 1:
        raise ValueError(f'a printed-value criterion is one key ({names}), got {len(item)}')
    key, settings = next(iter(item.items()))
    kind = str(key)[len(PRINTED_PREFIX):] if str(key).startswith(PRINTED_PREFIX) else None
    if kind not in PRINTED_KINDS:
        raise ValueError(f"unknown criterion '{key}'; a mapping criterion is one of {names}")
    if not isinstance(settings, Mapping):
        raise ValueError(f"'{key}' must map settings to numbers, e.g. {{max_error_m: 0.05, "
                         f'min_matched_fraction: 0.95}}, got {described(settings)}')
    allowed = [name for name in PRINTED_SETTINGS
               if kind == 'closest' or name != 'max_bearing_error_deg']
    for name, value in settings.items():
        if name not in allowed:
            raise ValueError(f"'{key}.{name}': unknown setting; expected {', '.join(allowed)}")
        limit = 1.0 if name == 'min_matched_fraction' else math.inf
        if not is_number_not_nan(value) or not 0.0 <= value <= limit:
            wanted = 'from 0 to 1' if limit == 1.0 else 'at least 0'
            raise ValueError(f"'{key}.{name}' must be a number {wanted}, got {described(value)}")
    for name in allowed:
        if PRINTED_SETTINGS[name] and name not in settings:
            raise ValueError(f"'{key}.{name}' is missing")
    shown = [f'{name} {settings[name]:g}' for name in allowed if name in settings]
    text = f'{key}: ' + ', '.join(shown)
    return PrintedCriterion(text, kind, **{name: float(value)
                                           for name, value in settings.items()})


def parse_criterion(text: str) -> Criterion:
    """
    Parse ``<value> <op> <number>`` (see the module docstring); ValueError says what is wrong.

    The metric must be one ``compute_metrics`` produces, of a kind the function fits.
    """
    if not isinstance(text, str):
        raise ValueError(f'must be a text like "collisions == 0" (or a mapping like '
                         f'printed_range_ahead: {{...}}), got {text!r}')
    match = _CRITERION.match(text)
    if match is None:
        raise ValueError(f"cannot read '{text}': expected '<metric> <op> <number>' with <op> "
                         f"one of {' '.join(_OPERATORS)}, e.g. 'laps <= -1' or "
                         "'min(turns_deg) > 90'")
    function = match['function']
    dotted = match['inner'] or match['plain']
    if function is not None and function not in _FUNCTIONS:
        raise ValueError(f"'{text}': unknown function '{function}'; use one of "
                         f"{', '.join(_FUNCTIONS)}")
    kind = _metric_kind(dotted)
    if kind is None:
        raise ValueError(f"'{text}': unknown metric '{dotted}'; metrics are "
                         f"{', '.join(_metric_names())}")
    needed = 'number' if function in (None, 'abs') else 'list'
    if kind != needed:
        hint = (f'use min({dotted}), max(...), len(...), all(...) or any(...)'
                if kind == 'list' else f'{function}() needs a list metric')
        raise ValueError(f"'{text}': '{dotted}' is a {kind}; {hint}")
    return Criterion(text.strip(), tuple(dotted.split('.')), match['op'],
                     float(match['number']), function)


def _metric_kind(dotted: str) -> str | None:
    kind: Any = METRIC_KINDS
    for key in dotted.split('.'):
        if not isinstance(kind, dict) or key not in kind:
            return None
        kind = kind[key]
    return kind if isinstance(kind, str) else 'group of metrics'


def _metric_names() -> list[str]:
    return [f'{key}.{sub}' if isinstance(kind, dict) else key
            for key, kind in METRIC_KINDS.items()
            for sub in (kind if isinstance(kind, dict) else [None])]
