"""The event loop: exact timer times, (time, sequence) order, determinism, spin and horizons."""

import pytest

from sim_bridge import lockstep
from sim_bridge.lockstep import LockstepError, NodeError, StalledError


def test_timers_fire_at_exact_multiples_of_their_period_without_drift(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []
    node.create_timer(0.1, lambda: times.append(runtime.now_ns))
    runtime.run_until(100 * 10 ** 9)
    assert times == [k * 100_000_000 for k in range(1, 1001)]
    assert runtime.now_ns == 100 * 10 ** 9


def test_timers_due_together_fire_in_creation_order_then_their_messages(rclpy, runtime):
    from std_msgs.msg import Int32
    node = rclpy.create_node('pair')
    order = []
    publisher = node.create_publisher(Int32, 'numbers', 10)
    node.create_subscription(Int32, 'numbers', lambda msg: order.append(('msg', msg.data)), 10)

    def fire(name, value):
        order.append((name, runtime.now_ns))
        publisher.publish(Int32(data=value))
    node.create_timer(0.5, lambda: fire('a', 1))
    node.create_timer(0.25, lambda: fire('b', 2))
    runtime.run_until(500_000_000)
    assert order == [('b', 250_000_000), ('msg', 2), ('a', 500_000_000), ('b', 500_000_000),
                     ('msg', 1), ('msg', 2)]


def test_run_until_runs_events_at_the_boundary_and_sets_the_clock(rclpy, runtime):
    node = rclpy.create_node('ticker')
    count = []
    node.create_timer(1.0, lambda: count.append(runtime.now_ns))
    runtime.run_until(999_999_999)
    assert count == [] and runtime.now_ns == 999_999_999
    runtime.run_until(1_000_000_000)
    assert count == [1_000_000_000]
    with pytest.raises(ValueError):
        runtime.run_until(0)


def test_a_timer_created_in_a_callback_starts_counting_from_then(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []

    def first():
        times.append(('first', runtime.now_ns))
        if len(times) == 1:
            node.create_timer(0.2, lambda: times.append(('second', runtime.now_ns)))
    node.create_timer(0.3, first)
    runtime.run_until(700_000_000)
    assert times == [('first', 300_000_000), ('second', 500_000_000), ('first', 600_000_000),
                     ('second', 700_000_000)]


def test_cancel_and_reset_follow_rcl(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []
    timer = node.create_timer(1.0, lambda: times.append(runtime.now_ns))
    runtime.run_until(1_500_000_000)
    timer.cancel()
    assert timer.is_canceled() and timer.time_until_next_call() is None
    runtime.run_until(3_000_000_000)
    timer.reset()
    assert timer.time_until_next_call() == 1_000_000_000
    runtime.run_until(4_000_000_000)
    assert times == [1_000_000_000, 4_000_000_000]


def test_a_timer_not_autostarted_waits_for_reset(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []
    timer = node.create_timer(1.0, lambda: times.append(runtime.now_ns), autostart=False)
    runtime.run_until(2_000_000_000)
    timer.reset()
    runtime.run_until(3_000_000_000)
    assert times == [3_000_000_000]


def test_a_zero_period_timer_is_refused_instead_of_freezing_sim_time(rclpy):
    with pytest.raises(ValueError, match='period must be positive'):
        rclpy.create_node('busy').create_timer(0.0, lambda: None)


def run_scenario() -> list:
    """Two nodes exchanging messages on timers; returns everything that happened."""
    runtime = lockstep.install()
    try:
        import rclpy
        from std_msgs.msg import Float64
        rclpy.init(args=[])
        events = []
        talker, listener = rclpy.create_node('talker'), rclpy.create_node('listener')
        publisher = talker.create_publisher(Float64, 'value', 10)
        talker.create_timer(0.07, lambda: publisher.publish(Float64(data=runtime.now_ns / 1e9)))
        listener.create_subscription(Float64, 'value',
                                     lambda msg: events.append((runtime.now_ns, msg.data)), 10)
        listener.create_timer(0.03, lambda: events.append((runtime.now_ns, 'tick')))
        runtime.run_until(5 * 10 ** 9)
        return events
    finally:
        lockstep.uninstall()


def test_two_identical_runs_produce_identical_event_sequences():
    first, second = run_scenario(), run_scenario()
    assert first == second and len(first) > 200


def test_callback_exception_leaves_run_until_as_node_error(rclpy, runtime):
    node = rclpy.create_node('broken')
    node.create_timer(0.5, lambda: 1 / 0)
    with pytest.raises(NodeError, match="node 'broken' raised ZeroDivisionError") as raised:
        runtime.run_until(10 ** 9)
    assert isinstance(raised.value.__cause__, ZeroDivisionError)
    assert runtime.now_ns == 500_000_000


def test_spin_stops_at_the_horizon(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []
    node.create_timer(0.4, lambda: times.append(runtime.now_ns))
    runtime.set_horizon(10 ** 9)
    rclpy.spin(node)
    assert times == [400_000_000, 800_000_000] and runtime.now_ns == 10 ** 9


def test_spin_without_anything_to_do_raises_instead_of_hanging(rclpy):
    node = rclpy.create_node('idle')
    with pytest.raises(StalledError, match='nothing left to do'):
        rclpy.spin(node)


def test_spin_returns_when_a_callback_shuts_rclpy_down(rclpy, runtime):
    node = rclpy.create_node('quitter')
    node.create_timer(0.5, rclpy.shutdown)
    rclpy.spin(node)
    assert runtime.now_ns == 500_000_000 and not rclpy.ok()


def test_spin_raises_the_callbacks_own_exception_like_rclpy(rclpy, runtime):
    node = rclpy.create_node('broken')
    node.create_timer(0.5, lambda: [][1])
    runtime.set_horizon(10 ** 9)
    with pytest.raises(IndexError) as raised:
        rclpy.spin(node)
    assert "node 'broken'" in raised.value.__notes__[0]
    assert runtime.last_node_error.node_name == 'broken'


def test_spin_once_runs_one_callback_or_waits_out_its_timeout(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []
    node.create_timer(1.0, lambda: times.append(runtime.now_ns))
    rclpy.spin_once(node, timeout_sec=0.25)
    assert times == [] and runtime.now_ns == 250_000_000
    rclpy.spin_once(node)
    assert times == [1_000_000_000]


def test_spinning_from_inside_a_callback_is_refused(rclpy, runtime):
    node = rclpy.create_node('nested')
    node.create_timer(0.5, lambda: rclpy.spin_once(node))
    with pytest.raises(NodeError) as raised:
        runtime.run_until(10 ** 9)
    assert isinstance(raised.value.original, LockstepError)
    assert 'inside a callback' in str(raised.value)


def test_shutdown_stops_every_callback_of_the_context(rclpy, runtime):
    node = rclpy.create_node('ticker')
    times = []
    node.create_timer(0.5, lambda: times.append(runtime.now_ns))
    runtime.run_until(10 ** 9)
    rclpy.shutdown()
    runtime.run_until(3 * 10 ** 9)
    assert times == [500_000_000, 1_000_000_000]


def test_a_spin_once_loop_ends_at_the_horizon_with_external_shutdown(rclpy, runtime):
    from rclpy.executors import ExternalShutdownException
    node = rclpy.create_node('polling')
    times = []
    node.create_timer(0.3, lambda: times.append(runtime.now_ns))
    runtime.set_horizon(10 ** 9)
    with pytest.raises(ExternalShutdownException):
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.1)
    assert times == [300_000_000, 600_000_000, 900_000_000] and runtime.now_ns == 10 ** 9
