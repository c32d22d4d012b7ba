"""
Benchmark reading a printed line: time (us) against the count of numbers on the line.

Prints, for each reader of sim_bridge.scoring.printed_text, the time to read a line of 2,000,
16,000 and 48,000 numbers with the per-line cap lifted (reading is linear when each row's
ratio to the first is about the ratio of their lengths: 8x and 24x), then with the cap
(LINE_CHARS) in force (the same time whatever the length).

Run: python test/bench/bench_printed_text.py [--quick]
"""

from sim_bridge.scoring import printed_text
from timing import microseconds_per_call

COUNTS = (2000, 16000, 48000)
READERS = ('read_range_ahead', 'read_regions', 'read_closest')


def line_of(count: int) -> str:
    """Return a printed line of ``count`` numbers."""
    return ', '.join(['1.234'] * count)


def main() -> None:
    """Print the figures (see the module)."""
    cap = printed_text.LINE_CHARS
    for capped in (False, True):
        printed_text.LINE_CHARS = cap if capped else 10 ** 9
        print(f"per-line cap {'on' if capped else 'lifted'} ({cap} characters):")
        for reader in READERS:
            function = getattr(printed_text, reader)
            times = [microseconds_per_call(function, lambda text=line_of(count): [text])
                     for count in COUNTS]
            ratios = '  '.join(f'{t / times[0]:5.1f}x' for t in times)
            print(f"  {reader:17} {'  '.join(f'{t:10.0f} us' for t in times)}   {ratios}")
    printed_text.LINE_CHARS = cap


if __name__ == '__main__':
    main()
