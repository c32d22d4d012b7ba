"""Run the grader's command (sim_bridge.commands.grade) as ``python -m sim_bridge.grade``."""

import sys

from sim_bridge.commands.grade import main

sys.exit(main())
