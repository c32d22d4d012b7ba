"""
sim_bridge: a pybullet stand-in for Gazebo, its ROS 2 bridge, the runner and the grader.

Sub-packages, bottom up (each may import only those before it; the layers are a contract that
test/test_architecture.py checks with import-linter):

- :mod:`.common`: paths, YAML, text, errors, the run's environment;
- :mod:`.simulation`: the simulator, pure Python with no rclpy;
- :mod:`.ros` (the bridge node, teleops) and :mod:`.scoring` (trace, metrics, printed values);
- :mod:`.media`: plots and videos;
- :mod:`.runner`: running nodes against the simulator, stepped or as processes;
- :mod:`.live` (live runs of a lab task) and :mod:`.grading` (the grader);
- :mod:`.commands`: every command line.
"""
