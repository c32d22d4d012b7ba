"""
The runner: nodes run against the simulator.

Runs nodes against the simulator: options, stepping on simulated time, targets and node
styles, node output, recording, hints, the stepped run and the process run. The trust boundary
has a wing of its own, ``boundary``: what runs inside a node's sandboxed process, what runs
outside it, and the wire between (its docstring says what each may import).

May import common, simulation, ros, scoring and media; never grading, live or commands.

A node file runs in a process of its own under the agent (``boundary.inside.agent``), which
changes these, in that process only (``boundary.inside.node_patches``), and nothing else a node
can observe. Each is checked by
sim_bridge/test/test_agent_differential.py: the same node file under plain rclpy at real time
and stepped prints the same lines (text, severity, logger, caller's file, line and function,
``once``/``throttle_duration_sec``/``skip_first``) and publishes the same messages, in order
(the fixture named after each)::

    rclpy Executor.wait_for_ready_callbacks   a wait with nothing ready exchanges a step with
                                              the trusted side; on a thread other than the main
                                              one, waits for the step (two_severities,
                                              multithreaded, sleep_and_rate)
    rclpy MultiThreadedExecutor               a SingleThreadedExecutor: callbacks one at a
                                              time, in order (multithreaded, busy_poll_ticks)
    rclpy Rate.sleep                          until its timer's callback sets its event, as
                                              rclpy's; sim time passes to its next tick; a
                                              timer nothing runs ticks on its own
                                              (sleep_and_rate)
    time.sleep                                lasts its simulated time (sleep_and_rate)
    time.time, time.monotonic (and _ns);      the nodes' clock: sim time since the start, in a
    rclpy Clock.now of system, steady clocks  callback plus the wall time since its step, never
                                              back (sleep_and_rate, two_severities' throttle)
    rclpy Node.__init__                       notes each node made; counts console lines from
                                              then on (every fixture)
    rcutils' output handler (C)               rclpy's handler, called by a C function that
                                              counts the line first: rclpy's logger itself is
                                              untouched (two_severities)
    sys.stdout, sys.stderr                    wrapped to count writes (two_severities' print)
    the default context's on_shutdown         notes where rclpy.shutdown() was called
                                              (sleep_and_rate, busy_poll_ticks)

Besides: a proxy node ``_lab_agent_proxy`` in the nodes' context (it takes what they publish,
publishes what the simulator sends); a daemon thread ``lab_pacer`` that steps the run while
main()'s own code keeps the main thread busy (busy_poll_ticks; agent's docstring); SIGUSR1 and
faulthandler's SIGUSR2 handlers (the trusted side asks a stuck process where it is);
``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF``; line-buffered stdout; Python's ``random`` seeded (0)
and ``PYTHONHASHSEED=0``, so that a node drawing random turns, or iterating a set, is marked the
same at every grading (a node's own ``random.seed`` wins). Not patched: ``time.perf_counter``,
``time.process_time``, ``datetime`` (they measure the code's own work), ROS time (the
simulator's /clock).
"""
