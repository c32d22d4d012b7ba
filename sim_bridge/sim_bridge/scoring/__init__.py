"""
What a run is scored by.

What a run is scored by: its trace, the metrics computed from it (the motion tasks' evidence
among them), what a printed line says and the printed values judged against the scans.

May import common and simulation.
"""
