"""
``python -m sim_bridge.run``: the runner's command (sim_bridge.commands.run), at the path users type.
"""

import sys

from sim_bridge.commands.run import main

if __name__ == '__main__':
    sys.exit(main())
