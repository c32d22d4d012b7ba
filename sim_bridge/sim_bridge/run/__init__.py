"""
``python -m sim_bridge.run``: the runner's command, at the path users type.

Only its ``__main__`` runs it; the code is sim_bridge.commands.run's.
"""
