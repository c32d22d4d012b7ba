"""
Pictures of a run.

Pictures of a run: its trajectory plot and its video.

May import common, simulation and scoring.
"""
