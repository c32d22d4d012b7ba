"""
``python -m sim_bridge.bridge``: the simulator's ROS 2 node (sim_bridge.ros.bridge), at the path
users type.
"""

from sim_bridge.ros.bridge import main

if __name__ == '__main__':
    main()
