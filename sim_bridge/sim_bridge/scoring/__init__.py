"""
What a run is scored by.

What a run is scored by: its trace, the metrics computed from it, what a printed line says
and the printed values judged against the scans.

May import common and simulation.
"""
