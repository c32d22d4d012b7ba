# noqa: A005 (rclpy has a module of this name; it is only aliased, never on sys.path)
"""rclpy.time for the lockstep runtime: Time points with Jazzy's arithmetic and comparisons."""

from typing import Tuple, Union

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.rclpy.clock_type import ClockType
from sim_bridge.lockstep.rclpy.constants import S_TO_NS
from sim_bridge.lockstep.rclpy.duration import Duration

__lockstep__ = True


class Time:
    """A point in time: nanoseconds since the clock's epoch, and the clock's type."""

    __slots__ = ('_nanoseconds', '_clock_type')

    def __init__(self, *, seconds: Union[int, float] = 0, nanoseconds: Union[int, float] = 0,
                 clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        if not isinstance(clock_type, ClockType):
            raise TypeError('Clock type must be a ClockType enum')
        if seconds < 0:
            raise ValueError('Seconds value must not be negative')
        if nanoseconds < 0:
            raise ValueError('Nanoseconds value must not be negative')
        total = int(seconds * S_TO_NS) + int(nanoseconds)
        if total >= 2 ** 63:
            raise OverflowError('Total nanoseconds value is too large to store in C time point.')
        self._nanoseconds = total
        self._clock_type = clock_type

    @property
    def nanoseconds(self) -> int:
        """Nanoseconds since the clock's epoch (the start of the simulation)."""
        return self._nanoseconds

    @property
    def clock_type(self) -> ClockType:
        """The type of clock that produced this time."""
        return self._clock_type

    def seconds_nanoseconds(self) -> Tuple[int, int]:
        """Return (seconds, nanoseconds) with 0 <= nanoseconds < 1e9."""
        return divmod(self._nanoseconds, S_TO_NS)

    def __repr__(self) -> str:
        return f'Time(nanoseconds={self.nanoseconds}, clock_type={self.clock_type.name})'

    def __add__(self, other: Duration) -> 'Time':
        if isinstance(other, Duration):
            try:
                return Time(nanoseconds=self.nanoseconds + other.nanoseconds,
                            clock_type=self.clock_type)
            except OverflowError as error:
                raise OverflowError('Addition leads to overflow in C storage.') from error
        return NotImplemented

    def __radd__(self, other: Duration) -> 'Time':
        return self.__add__(other)

    def __sub__(self, other: Union['Time', Duration]) -> Union['Time', Duration]:
        if isinstance(other, Time):
            if self.clock_type != other.clock_type:
                raise TypeError("Can't subtract times with different clock types")
            return Duration(nanoseconds=self.nanoseconds - other.nanoseconds)
        if isinstance(other, Duration):
            try:
                return Time(nanoseconds=self.nanoseconds - other.nanoseconds,
                            clock_type=self.clock_type)
            except ValueError as error:
                raise ValueError('Subtraction leads to negative time.') from error
        return NotImplemented

    def _comparable(self, other: object) -> bool:
        if not isinstance(other, Time):
            return False
        if self.clock_type != other.clock_type:
            raise TypeError("Can't compare times with different clock types")
        return True

    def __eq__(self, other: object) -> bool:
        return self.nanoseconds == other.nanoseconds if self._comparable(other) \
            else NotImplemented

    def __lt__(self, other: 'Time') -> bool:
        return self.nanoseconds < other.nanoseconds if self._comparable(other) \
            else NotImplemented

    def __le__(self, other: 'Time') -> bool:
        return self.nanoseconds <= other.nanoseconds if self._comparable(other) \
            else NotImplemented

    def __gt__(self, other: 'Time') -> bool:
        return self.nanoseconds > other.nanoseconds if self._comparable(other) \
            else NotImplemented

    def __ge__(self, other: 'Time') -> bool:
        return self.nanoseconds >= other.nanoseconds if self._comparable(other) \
            else NotImplemented

    def to_msg(self):
        """Return the time as a builtin_interfaces/msg/Time."""
        seconds, nanoseconds = self.seconds_nanoseconds()
        return message_class('builtin_interfaces/msg/Time')(sec=seconds, nanosec=nanoseconds)

    @classmethod
    def from_msg(cls, msg, clock_type: ClockType = ClockType.ROS_TIME) -> 'Time':
        """Create a Time from a builtin_interfaces/msg/Time."""
        if not isinstance(msg, message_class('builtin_interfaces/msg/Time')):
            raise TypeError('Must pass a builtin_interfaces.msg.Time object')
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec, clock_type=clock_type)
