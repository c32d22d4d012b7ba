"""
``python -m sim_bridge.bridge``: the simulator's ROS 2 node, at the path users type.

The node itself is sim_bridge.ros.bridge.
"""

from sim_bridge.ros.bridge import main

if __name__ == '__main__':
    main()
