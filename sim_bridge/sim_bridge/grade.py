"""
``python -m sim_bridge.grade``: the grader's command, at the path users type.

The command itself is sim_bridge.commands.grade.
"""

import sys

from sim_bridge.commands.grade import main

if __name__ == '__main__':
    sys.exit(main())
