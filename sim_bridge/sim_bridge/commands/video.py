"""
``./lab video``: every video the kit makes, one command (the console script ``lab_video``).

``./lab video TASK --node FILE --names "..."`` films a lab task (a task's name or the handout's
number) as the handout asks (sim_bridge.commands.task_video); ``./lab video OUT_DIR --names
"..."`` films a finished run from its output folder (``./lab run --out``, ``./lab live
--record``; sim_bridge.commands.run_video). The first argument decides: a lab task's name or
number is a task, anything else a run's folder.
"""

import sys
from typing import Sequence

from sim_bridge.commands import run_video, task_video
from sim_bridge.live.lab_tasks import HANDOUT_NUMBERS, TASK_SCENARIOS


def names_a_task(text: str) -> bool:
    """Return whether ``text`` is a lab task's name (wall_follow) or number (4, task4)."""
    numbers = {str(number) for number in HANDOUT_NUMBERS.values()}
    return text in TASK_SCENARIOS or text.removeprefix('task') in numbers


def main(argv: Sequence[str] | None = None) -> int:
    """Make a task's video or a finished run's; return the exit status (0, 1 or 2)."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    if arguments and not arguments[0].startswith('-') and not names_a_task(arguments[0]):
        return run_video.main(arguments)
    return task_video.main(arguments)


if __name__ == '__main__':
    sys.exit(main())
