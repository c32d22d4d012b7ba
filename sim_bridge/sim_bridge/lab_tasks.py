"""
The lab's tasks: which scan_pkg node each one runs, and in which world.

One table shared by ``lab.launch.py`` (live ROS 2), ``sim_bridge.live`` (the same two processes
without launch) and the demo (stepped runner), so all start the same thing for a task.
"""

from typing import NamedTuple


class LabTask(NamedTuple):
    """A lab task: the scan_pkg node (console script) and the world it runs in."""

    node: str
    world: str


LAB_TASKS = {
    'scan_ahead': LabTask('scan_ahead', 'obstacles'),
    'scan_around': LabTask('scan_around', 'obstacles'),
    'closest_obstacle': LabTask('closest_obstacle', 'obstacles'),
    'wanderbot': LabTask('wanderbot', 'room'),
    'wall_follow': LabTask('wall_follow', 'wall_follow_box'),
}
