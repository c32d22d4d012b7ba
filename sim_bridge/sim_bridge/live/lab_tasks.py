"""
The lab's tasks: which scan_pkg node each one runs, and in which world.

One table shared by ``lab.launch.py`` (live ROS 2), ``sim_bridge.live.live`` (the same two
processes without launch) and the demo (stepped runner), so all start the same thing for a task.
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

#: The handout's numbers of the tasks handed in as videos (``labscan_task1.mp4`` ...).
HANDOUT_NUMBERS = {'scan_ahead': 1, 'wanderbot': 2, 'scan_around': 3, 'wall_follow': 4}
#: The shipped scenario (in scenarios/) whose first run a task's video shows.
TASK_SCENARIOS = {
    'scan_ahead': 'scan_ahead.yaml',
    'scan_around': 'scan_around.yaml',
    'closest_obstacle': 'closest_obstacle.yaml',
    'wanderbot': 'wanderbot.yaml',
    'wall_follow': 'wall_follow_box_cw.yaml',
}
#: A task whose node loops one way or the other (the handout lets the student choose): the
#: shipped scenario of each direction, the first the kit's own (TASK_SCENARIOS).
LOOP_SCENARIOS = {
    'wall_follow': {'clockwise': 'wall_follow_box_cw.yaml',
                    'counterclockwise': 'wall_follow_box_ccw.yaml'},
}


def video_name(task: str) -> str:
    """Return the file a task's video is handed in as: ``labscan_task4.mp4``."""
    number = HANDOUT_NUMBERS.get(task)
    return f'labscan_task{number}.mp4' if number is not None else f'labscan_{task}.mp4'
