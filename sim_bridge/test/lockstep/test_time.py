"""Time, Duration and clocks read sim time and behave like rclpy's."""

import pytest


def test_node_clock_reads_sim_time_as_ros_time(rclpy, runtime):
    from rclpy.clock import ClockType
    node = rclpy.create_node('n')
    runtime.run_until(1_500_000_001)
    now = node.get_clock().now()
    assert now.nanoseconds == 1_500_000_001 and now.clock_type == ClockType.ROS_TIME
    assert now.seconds_nanoseconds() == (1, 500_000_001)
    stamp = now.to_msg()
    assert (stamp.sec, stamp.nanosec) == (1, 500_000_001)


def test_every_clock_kind_reads_sim_time(runtime):
    from rclpy.clock import Clock, ClockType
    runtime.run_until(42)
    assert Clock().now().nanoseconds == 42
    assert Clock(clock_type=ClockType.STEADY_TIME).now().nanoseconds == 42


def test_time_and_duration_arithmetic(runtime):
    from rclpy.duration import Duration
    from rclpy.time import Time
    start = Time(seconds=1.5)
    later = start + Duration(seconds=0.25)
    assert later.nanoseconds == 1_750_000_000
    assert later - start == Duration(nanoseconds=250_000_000)
    assert (later - Duration(seconds=1.75)).nanoseconds == 0
    with pytest.raises(ValueError):
        later - Duration(seconds=2)
    assert Duration(seconds=-1.5).to_msg().sec == -2


def test_times_of_different_clocks_do_not_compare(runtime):
    from rclpy.clock import ClockType
    from rclpy.time import Time
    with pytest.raises(TypeError, match='different clock types'):
        Time(clock_type=ClockType.ROS_TIME) < Time(clock_type=ClockType.SYSTEM_TIME)


def test_time_round_trips_through_its_message(runtime):
    from builtin_interfaces.msg import Time as TimeMsg
    from rclpy.time import Time
    assert Time.from_msg(TimeMsg(sec=3, nanosec=7)).nanoseconds == 3_000_000_007
    with pytest.raises(ValueError):
        Time(seconds=-1)


def test_sleeping_on_a_clock_is_refused(runtime):
    from rclpy.clock import Clock
    from rclpy.duration import Duration
    from sim_bridge.lockstep import LockstepError
    with pytest.raises(LockstepError, match='use a timer'):
        Clock().sleep_for(Duration(seconds=1))
