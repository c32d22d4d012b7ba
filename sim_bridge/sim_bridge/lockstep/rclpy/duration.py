"""rclpy.duration for the lockstep runtime: Duration with Jazzy's arithmetic and messages."""

import math
from typing import Union

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.rclpy.constants import S_TO_NS

__lockstep__ = True

# RMW_DURATION_INFINITE: the largest int64 count of nanoseconds.
_INFINITE_NS = 2 ** 63 - 1


class Duration:
    """A period between two time points, with nanosecond precision (may be negative)."""

    __slots__ = ('_nanoseconds',)

    def __init__(self, *, seconds: Union[int, float] = 0, nanoseconds: Union[int, float] = 0):
        total = int(seconds * S_TO_NS) + int(nanoseconds)
        if total >= 2 ** 63 or total < -2 ** 63:
            raise OverflowError('Total nanoseconds value is too large to store in C duration.')
        self._nanoseconds = total

    @property
    def nanoseconds(self) -> int:
        """Length of the duration (ns)."""
        return self._nanoseconds

    def __repr__(self) -> str:
        return f'Duration(nanoseconds={self.nanoseconds})'

    def __str__(self) -> str:
        if self == Infinite:
            return 'Infinite'
        return f'{self.nanoseconds} nanoseconds'

    def __add__(self, other: 'Duration') -> 'Duration':
        if isinstance(other, Duration):
            return Duration(nanoseconds=other.nanoseconds + self.nanoseconds)
        return NotImplemented

    def __sub__(self, other: 'Duration') -> 'Duration':
        if isinstance(other, Duration):
            return Duration(nanoseconds=self.nanoseconds - other.nanoseconds)
        return NotImplemented

    def __mul__(self, other: Union[int, float]) -> 'Duration':
        if isinstance(other, int):
            return Duration(nanoseconds=self.nanoseconds * other)
        if isinstance(other, float):
            if not math.isfinite(other):
                if other == math.inf:
                    return Infinite
                raise ValueError("Can't multiply duration with nan")
            return Duration(nanoseconds=int(self.nanoseconds * other))
        return NotImplemented

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Duration):
            return self.nanoseconds == other.nanoseconds
        return NotImplemented

    def __lt__(self, other: 'Duration') -> bool:
        if isinstance(other, Duration):
            return self.nanoseconds < other.nanoseconds
        return NotImplemented

    def __le__(self, other: 'Duration') -> bool:
        if isinstance(other, Duration):
            return self.nanoseconds <= other.nanoseconds
        return NotImplemented

    def __gt__(self, other: 'Duration') -> bool:
        if isinstance(other, Duration):
            return self.nanoseconds > other.nanoseconds
        return NotImplemented

    def __ge__(self, other: 'Duration') -> bool:
        if isinstance(other, Duration):
            return self.nanoseconds >= other.nanoseconds
        return NotImplemented

    def to_msg(self):
        """Return the duration as a builtin_interfaces/msg/Duration."""
        seconds, nanoseconds = divmod(self.nanoseconds, S_TO_NS)
        return message_class('builtin_interfaces/msg/Duration')(sec=seconds, nanosec=nanoseconds)

    @classmethod
    def from_msg(cls, msg) -> 'Duration':
        """Create a Duration from a builtin_interfaces/msg/Duration."""
        if not isinstance(msg, message_class('builtin_interfaces/msg/Duration')):
            raise TypeError('Must pass a builtin_interfaces.msg.Duration object')
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec)


Infinite = Duration(nanoseconds=_INFINITE_NS)
