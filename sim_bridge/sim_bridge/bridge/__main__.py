"""Run the simulator's ROS 2 node (sim_bridge.ros.bridge) as ``python -m sim_bridge.bridge``."""

import sys

from sim_bridge.ros.bridge import main

sys.exit(main())
