"""Every test process keeps its ROS 2 traffic to itself (docs/internals.md, How a run works)."""

from sim_bridge.common.run_environment import keep_dds_in_process

keep_dds_in_process()
