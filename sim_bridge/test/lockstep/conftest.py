"""Fixtures that install the lockstep runtime around a test and always uninstall it."""

import pytest

from sim_bridge import lockstep


@pytest.fixture
def runtime():
    """Install a lockstep runtime for the test; ``import rclpy`` resolves to it."""
    fresh = lockstep.install()
    try:
        yield fresh
    finally:
        lockstep.uninstall()


@pytest.fixture
def logs(runtime):
    """Collect the log records the runtime's nodes produce during the test."""
    records = []
    runtime.set_log_sink(records.append)
    return records


@pytest.fixture
def rclpy(runtime):
    """Initialise the runtime's rclpy without ROS arguments; shut it down afterwards."""
    import rclpy as lockstep_rclpy
    lockstep_rclpy.init(args=[])
    try:
        yield lockstep_rclpy
    finally:
        lockstep_rclpy.try_shutdown()
