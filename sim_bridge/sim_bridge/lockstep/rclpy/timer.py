"""
rclpy.timer for the lockstep runtime: timers on the simulated clock.

A timer created at sim time S with period P fires at S + P, S + 2P, ... exactly (integer ns,
no drift); ``reset()`` restarts the count from the current time, as ``rcl_timer_reset`` does.
"""

from typing import Callable, Optional

from sim_bridge.lockstep.rclpy.exceptions import InvalidHandle

__lockstep__ = True


class Timer:
    """A periodic callback on the node's clock (sim time)."""

    def __init__(self, callback: Callable, callback_group, timer_period_ns: int, clock, *,
                 context=None, autostart: bool = True, lockstep_node=None):
        if timer_period_ns <= 0:
            raise ValueError(f'a timer period must be positive, got {timer_period_ns} ns: a '
                             'zero period would fire forever without sim time advancing')
        self.callback = callback
        self.callback_group = callback_group
        self._clock = clock
        self._context = context
        self._period_ns = int(timer_period_ns)
        self._runtime = lockstep_node._runtime
        self._lockstep_node_name = lockstep_node.get_name()
        self._generation = 0
        self._canceled = True
        self._destroyed = False
        self._next_ns = self._runtime.now_ns
        self._last_call_ns = self._runtime.now_ns
        if autostart:
            self.reset()

    @property
    def clock(self):
        """The clock the timer runs on."""
        return self._clock

    @property
    def timer_period_ns(self) -> int:
        """Period (ns); a new value applies from the next firing on."""
        return self._period_ns

    @timer_period_ns.setter
    def timer_period_ns(self, value: int) -> None:
        if value <= 0:
            raise ValueError('a timer period must be positive')
        self._period_ns = int(value)

    def _lockstep_fire(self, generation: int) -> None:
        if generation != self._generation:
            return
        self._last_call_ns = self._next_ns
        self._next_ns += self._period_ns
        self._runtime.schedule(self._next_ns, self, generation)
        self.callback()

    def _check_alive(self) -> None:
        if self._destroyed:
            raise InvalidHandle('cannot use Destroyable because destruction was requested')

    def is_ready(self) -> bool:
        """Tell whether a firing is due."""
        self._check_alive()
        return not self._canceled and self._runtime.now_ns >= self._next_ns

    def is_canceled(self) -> bool:
        """Tell whether the timer is canceled (or a timer not autostarted was never reset)."""
        self._check_alive()
        return self._canceled

    def cancel(self) -> None:
        """Stop firing; reset() starts again."""
        self._check_alive()
        self._canceled = True
        self._generation += 1

    def reset(self) -> None:
        """(Re)start: next firing one period from now."""
        self._check_alive()
        self._canceled = False
        self._generation += 1
        self._next_ns = self._runtime.now_ns + self._period_ns
        self._runtime.schedule(self._next_ns, self, self._generation)

    def time_since_last_call(self) -> int:
        """Nanoseconds since the last firing (or the start)."""
        self._check_alive()
        return self._runtime.now_ns - self._last_call_ns

    def time_until_next_call(self) -> Optional[int]:
        """Nanoseconds until the next firing; None when canceled."""
        self._check_alive()
        return None if self._canceled else self._next_ns - self._runtime.now_ns

    def _lockstep_stop(self) -> None:
        self._canceled = True
        self._generation += 1

    def destroy(self) -> None:
        """Destroy the timer: it never fires again."""
        self._lockstep_stop()
        self._destroyed = True
