"""What the validators of world, scenario and drive files say of a value, and test it for."""

import difflib
import math
from typing import Any


def is_number_not_nan(value: Any) -> bool:
    """Return True for an int or float (not a bool) that is not NaN: infinities allowed."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and \
        not math.isnan(value)


def is_finite_number(value: Any) -> bool:
    """Return True for a finite int or float (not a bool)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def described(value: Any) -> str:
    """Return ``value`` as an error message names it: 'a mapping', "the text 'x'", 'int 3'."""
    if value is None:
        return 'nothing'
    return {dict: 'a mapping', list: 'a list', str: f'the text {value!r}'}.get(
        type(value), f'{type(value).__name__} {value!r}')


def with_type(value: Any) -> str:
    """Return ``value`` with its Python type, as in ``'3' (str)``."""
    return f'{value!r} ({type(value).__name__})'


def unknown_key_problem(key: str | None, known: list[str]) -> str:
    """Return why ``key`` is refused: unknown, the known key it looks like a misspelling of."""
    close = difflib.get_close_matches(str(key), known, n=1)
    hint = f' (did you mean {close[0]!r}?)' if close else ''
    return f"unknown key{hint}; expected one of {', '.join(known)}"
