"""
The simulator's ROS 2 face.

The simulator's ROS 2 face: the ``sim_bridge`` node, the teleops, send_cmd_vel and the
drive plans a scenario's teleop follows.

May import common and simulation.
"""
