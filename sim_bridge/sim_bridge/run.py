"""
``python -m sim_bridge.run``: the runner's command, at the path users type.

The command itself is sim_bridge.commands.run.
"""

import sys

from sim_bridge.commands.run import main

if __name__ == '__main__':
    sys.exit(main())
