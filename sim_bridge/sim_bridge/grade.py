"""
``python -m sim_bridge.grade``: the grader's command (sim_bridge.commands.grade), at the path users type.
"""

import sys

from sim_bridge.commands.grade import main

if __name__ == '__main__':
    sys.exit(main())
