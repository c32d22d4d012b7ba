"""
The runner: nodes run against the simulator.

Runs nodes against the simulator: options, stepping on simulated time, targets and node
styles, node output, recording, hints, the stepped run and the process run.

May import common, simulation, ros, scoring and media; never grading, live or commands.
"""
