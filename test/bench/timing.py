"""Timing for the benchmark scripts: microseconds per call, the best of a few timings."""

import math
import sys
import time

#: Timings per figure; the best one counts.
REPEATS = 5
#: Wall time (s) all the timings of one figure take, about: less with --quick.
TARGET_S = 0.04 if '--quick' in sys.argv else 0.15


def microseconds_per_call(call, make_inputs) -> float:
    """
    Return the best of REPEATS timings (us per call) of ``call`` on each of ``make_inputs()``.

    ``make_inputs`` gives the list of inputs of one round; it is called outside the timed loop,
    so it may make fresh inputs for every round (nothing cached carries over) or return the
    same list. Each timing runs as many rounds as fill about ``TARGET_S / REPEATS`` seconds.
    """
    inputs = make_inputs()
    start = time.perf_counter()
    for item in inputs:
        call(item)
    rounds = max(1, int(TARGET_S / REPEATS / max(time.perf_counter() - start, 1e-9)))
    best = math.inf
    for _ in range(REPEATS):
        batch = [make_inputs() for _ in range(rounds)]
        start = time.perf_counter()
        for inputs in batch:
            for item in inputs:
                call(item)
        best = min(best, time.perf_counter() - start)
    return best / (rounds * len(inputs)) * 1e6
