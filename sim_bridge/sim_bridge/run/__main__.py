"""Run the runner's command (sim_bridge.commands.run) as ``python -m sim_bridge.run``."""

import sys

from sim_bridge.commands.run import main

sys.exit(main())
