"""
``python -m sim_bridge.grade``: the grader's command, at the path users type.

Only its ``__main__`` runs it; the code is sim_bridge.commands.grade's.
"""
