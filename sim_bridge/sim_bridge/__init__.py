"""sim_bridge: pybullet stand-in for Gazebo, its ROS 2 bridge, the runner and the grader."""
