"""When something sent at a rate is due on the simulator's clock, which advances in steps."""

from fractions import Fraction
import math

#: Seconds to nanoseconds.
NANOSECONDS_PER_SECOND = 10 ** 9


class UpdateSchedule:
    """
    When something sent at ``rate_hz`` is due, on a clock that advances in physics steps.

    Update n (n = 1, 2, ...) is due at n / rate_hz s and happens at the first physics step at or
    after that time, as a Gazebo sensor updates (its next update time moves on one period per
    update): the rate is kept exactly on average whatever the physics step, e.g. 30 scans per
    simulated second from a 30 Hz lidar on 100 Hz physics, 3 or 4 steps apart. Updates due
    within one step (a rate above the physics rate) make one. Times are exact fractions of a
    ns: deterministic, no drift.
    """

    def __init__(self, rate_hz: float) -> None:
        self.period_ns = Fraction(NANOSECONDS_PER_SECOND) / Fraction(rate_hz)
        self.updates = 0
        self.last_ns = 0
        #: The time (ns) from the previous update (or the start) to the last one.
        self.elapsed_ns = 0
        #: The first whole ns at or after the next update's exact time: asked every physics
        #: step, so a comparison of integers (n < x for a whole n is n < ceil(x)).
        self.next_ns = math.ceil(self.period_ns)

    def due(self, now_ns: int) -> bool:
        """Return whether an update is due at ``now_ns`` (ns); if so, it counts as made."""
        if now_ns < self.next_ns:
            return False
        # floor and ceil of fractions in whole numbers (p / q ns a period): exact, and fast
        periods, ns = self.period_ns.denominator, self.period_ns.numerator
        self.updates = now_ns * periods // ns
        self.next_ns = -(-(self.updates + 1) * ns // periods)
        self.elapsed_ns, self.last_ns = now_ns - self.last_ns, now_ns
        return True
