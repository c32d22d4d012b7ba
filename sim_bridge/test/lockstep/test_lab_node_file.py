"""An unmodified lab-style node file (fixtures/scan_counter.py) runs on the runtime."""

import importlib.util
from pathlib import Path
import sys

import pytest

NODE_FILE = Path(__file__).parent / 'fixtures' / 'scan_counter.py'


@pytest.fixture
def lab_module(runtime):
    """Import the node file from its path after install(), as the runner loads student files."""
    spec = importlib.util.spec_from_file_location('lockstep_fixture_scan_counter', NODE_FILE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def scan_source(rclpy, ranges, reliable: bool = True):
    """Create a node publishing one LaserScan on /scan every 0.1 s."""
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import LaserScan
    node = rclpy.create_node('fake_lidar')
    publisher = node.create_publisher(LaserScan, 'scan', 10 if reliable else
                                      qos_profile_sensor_data)
    node.create_timer(0.1, lambda: publisher.publish(LaserScan(
        angle_min=-1.57, angle_max=1.57, angle_increment=3.14 / 35, range_min=0.12,
        range_max=10.0, ranges=ranges)))


def counts_published(rclpy):
    from std_msgs.msg import Int32
    counts = []
    rclpy.create_node('listener').create_subscription(
        Int32, 'scan_count', lambda msg: counts.append(msg.data), 10)
    return counts


def test_the_node_class_counts_scans_and_publishes_the_count(lab_module, rclpy, runtime, logs):
    node = lab_module.ScanCounter()
    scan_source(rclpy, [2.0] * 35 + [0.75])
    counts = counts_published(rclpy)
    runtime.run_until(1_500_000_000)
    assert counts == [4, 9, 14]
    assert node.count == 15
    lines = [record.line() for record in logs]
    assert lines[0] == '[INFO] [0.100000000] [scan_counter]: Closest reading: 0.75 m'
    assert '[INFO] [0.500000000] [scan_counter]: Publishing: "4"' in lines


def test_best_effort_scans_never_reach_its_reliable_subscription(
        lab_module, rclpy, runtime, logs):
    node = lab_module.ScanCounter()
    scan_source(rclpy, [1.0] * 36, reliable=False)
    runtime.run_until(10 ** 9)
    assert node.count == 0
    assert any('offering incompatible QoS' in record.text for record in logs)


def test_main_runs_until_the_horizon_and_shuts_down_cleanly(lab_module, runtime, logs):
    import rclpy
    runtime.set_horizon(2 * 10 ** 9)
    lab_module.main(args=[])
    published = [record.text for record in logs if record.text.startswith('Publishing')]
    assert published == ['Publishing: "0"'] * 4
    assert runtime.now_ns == 2 * 10 ** 9 and not rclpy.ok()
