"""
``python -m sim_bridge.bridge``: the simulator's ROS 2 node, at the path users type.

Only its ``__main__`` runs it; the code is sim_bridge.ros.bridge's.
"""
