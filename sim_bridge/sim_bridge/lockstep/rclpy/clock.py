"""
rclpy.clock for the lockstep runtime: every clock reads the simulated time.

The lockstep loop has no wall clock: ``Clock()`` (SYSTEM_TIME), ``Clock(clock_type=STEADY_TIME)``
and a node's ROS clock all return the runtime's sim time, as a node started with
``use_sim_time:=true`` sees it. Sleeping on a clock would block the single-threaded loop, so
``sleep_for``/``sleep_until`` raise instead; use a timer.
"""

from sim_bridge.lockstep import loop
from sim_bridge.lockstep.errors import LockstepError
from sim_bridge.lockstep.rclpy.clock_type import ClockType
from sim_bridge.lockstep.rclpy.time import Time

__lockstep__ = True
__all__ = ['Clock', 'ClockType', 'ROSClock']


class Clock:
    """A clock of the given type; ``now()`` is the runtime's sim time."""

    def __init__(self, *, clock_type: ClockType = ClockType.SYSTEM_TIME):
        if not isinstance(clock_type, ClockType):
            raise TypeError('Clock type must be a ClockType enum')
        self._clock_type = clock_type

    @property
    def clock_type(self) -> ClockType:
        """Return the type this clock was created with."""
        return self._clock_type

    def __repr__(self) -> str:
        return f'Clock(clock_type={self.clock_type.name})'

    def now(self) -> Time:
        """Return the current sim time as a Time of this clock's type."""
        return Time(nanoseconds=loop.current().now_ns, clock_type=self._clock_type)

    def sleep_until(self, until: Time, context=None) -> bool:
        """Refuse: sleeping would block the only thread that advances sim time."""
        raise LockstepError('Clock.sleep_until() would block the single-threaded lockstep loop '
                            'forever; use a timer (node.create_timer) instead')

    def sleep_for(self, rel_time, context=None) -> bool:
        """Refuse: sleeping would block the only thread that advances sim time."""
        return self.sleep_until(None, context)


class ROSClock(Clock):
    """The node clock: ROS time, always active (driven by the simulation)."""

    def __init__(self):
        super().__init__(clock_type=ClockType.ROS_TIME)

    @property
    def ros_time_is_active(self) -> bool:
        """True: ROS time is the simulated time."""
        return True

    def _set_ros_time_is_active(self, enabled: bool) -> None:
        """Ignored: sim time is always active in the lockstep runtime."""
