"""
Live runs of a lab task.

Live runs of a lab task: the task table, its processes, a live session's recording.

May import runner and below.
"""
