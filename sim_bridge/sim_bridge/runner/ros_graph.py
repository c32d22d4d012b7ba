"""
The runner's own ROS nodes and its checks of the ROS graph.

Its nodes: its client node, the teleop of a scenario's ``drive:``. Its checks: parameters a
node never declared, topics no node connects to.
"""

import difflib
from typing import Any, Iterable, Protocol, Sequence

from rclpy.parameter import Parameter
from sim_bridge.ros.drive import DrivePlan, Segment
from sim_bridge.runner.options import BRIDGE_NODE, EVERY_NODE, Params, RUNNER_BRIDGE_PARAMETERS
from sim_bridge.simulation.world import World


#: ROS's own topics of every node (and /clock, of every use_sim_time node): a node's use of
#: them says nothing about how it is wired to the simulator.
ROS_TOPICS = ('/rosout', '/parameter_events', '/clock')
#: The runner's teleop node (a scenario's ``drive:``), and how often (Hz of sim time) it
#: publishes the command, as a held key of teleop_twist_keyboard repeats it.
TELEOP_NODE = 'teleop'
TELEOP_RATE_HZ = 20.0
NANOSECONDS_PER_SECOND = 10 ** 9
# The runner's own nodes serve nothing: the service is one more entity in every wait.
NO_TYPE_DESCRIPTION_SERVICE = Parameter('start_type_description_service', value=False)


class RunGraph(Protocol):
    """What the runner's own nodes join: the run's trusted side (a LockstepRun)."""

    bridge: Any

    def node(self, name: str, sim_time: bool = False, sink: bool = False) -> Any:
        """
        Create one of the runner's own nodes in the run's context and executor.

        ``sink``: its subscriptions' callbacks make nothing ready (they publish nothing,
        trigger nothing, create nothing), see sim_bridge.runner.stepping.spin_after_publishing.
        """


def nearest_topic(topic: str, topics: Iterable[str]) -> str | None:
    """Return the topic of ``topics`` most like ``topic``: of the same last name, else by text."""
    topics = sorted(topics)
    base = topic.rpartition('/')[2]
    same = [candidate for candidate in topics if candidate.rpartition('/')[2] == base]
    near = same or difflib.get_close_matches(topic, topics, n=1)
    return near[0] if near else None


def parameter_warnings(params: Params, declared: dict[str, set[str] | None],
                       targets: Iterable[str]) -> list[str]:
    """
    Return a warning for each node in ``params`` not running, and each parameter not declared.

    ``declared`` holds the parameter names each running node declared, by node name (the
    simulator's among them; None for a node that did not say: nothing is warned of it);
    ``targets`` names the target nodes. ROS ignores a params file's entry for a node that is
    not running, and rclpy an override of a parameter a node never declares: a misspelt name
    would otherwise grade the default in silence. A parameter for every node (EVERY_NODE) is
    one that none of the target nodes declares.
    """
    targets = list(targets)
    absent = [name for name in params if name not in declared and name != EVERY_NODE]
    warnings = [f"parameters given for node(s) {', '.join(absent)}, but the nodes are "
                f"{', '.join(declared)}; they were ignored"] if absent else []
    for node_name, values in params.items():
        for name in values:
            if name == 'use_sim_time' or node_name in absent or (
                    node_name == BRIDGE_NODE and name in RUNNER_BRIDGE_PARAMETERS):
                continue
            if node_name == EVERY_NODE:
                names = [declared[target] for target in targets]
                if None not in names and not any(name in each for each in names):
                    warnings.append(f"no node declared parameter '{name}' (given for every "
                                    f'node, {EVERY_NODE}); it was ignored')
            elif declared[node_name] is not None and name not in declared[node_name]:
                warnings.append(f"node '{node_name}' did not declare parameter '{name}' "
                                '(given by --param or the params file); it was ignored')
    return warnings


def unconnected_topics(bridge, nodes: Iterable[tuple[str, str]]) -> list[str]:
    """
    Return a warning for each topic one of ``nodes`` uses with nothing at its other end.

    ``nodes`` are (name, namespace) of the target nodes, in this process or another on the
    run's ROS domain. A subscription that nothing publishes, a publisher that nothing
    subscribes to, read from the ROS graph as the SimBridge node ``bridge`` sees it, each with
    the simulator's topic most like it and the remapping rule that would connect them.
    ROS_TOPICS are left out.
    """
    ends = {'publishes': {publisher.topic_name for publisher in bridge.publishers},
            'subscribes to': {sub.topic_name for sub in bridge.subscriptions}
            | {bridge.command_topic}}
    uses = (('subscribes to', bridge.get_subscriber_names_and_types_by_node,
             bridge.count_publishers, 'nothing publishes it', 'publishes'),
            ('publishes', bridge.get_publisher_names_and_types_by_node,
             bridge.count_subscribers, 'nothing subscribes to it', 'subscribes to'))
    warnings = []
    for name, namespace in nodes:
        for verb, topics_of, count, nothing, other_end in uses:
            for topic, _ in topics_of(name, namespace):
                if topic in ROS_TOPICS or count(topic):
                    continue
                near = nearest_topic(topic, ends[other_end] - set(ROS_TOPICS))
                hint = (f' (the simulator {other_end} {near}: --remap {topic}:={near})'
                        if near else '')
                warning = f'{name} {verb} {topic}: {nothing}{hint}'
                if warning not in warnings:
                    warnings.append(warning)
    return warnings


def runner_node(name: str, context, sim_time: bool):
    """Return a node of the runner's own: no services or /rosout; on sim time if asked."""
    from rclpy.node import Node
    return Node(name, context=context, use_global_arguments=False,
                start_parameter_services=False, enable_rosout=False,
                parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE,
                                     *([Parameter('use_sim_time', value=True)] if sim_time
                                       else [])])


class Teleop:
    """
    The person at the teleop: a node of the runner's driving the robot by a DrivePlan.

    Every 1/TELEOP_RATE_HZ s of sim time it publishes the plan's command on the simulator's
    command topic (its type: Twist, or TwistStamped), as teleop_twist_keyboard publishes while
    a key is held; once the plan is done, a zero command, and nothing more. The robot's centre
    is the simulator's ground truth (what the person sees), for segments that end near an
    obstacle of ``world``.
    """

    def __init__(self, graph: 'RunGraph', bridge, world: World,
                 segments: Sequence[Segment]):
        self.bridge = bridge
        self.msg_type = bridge.subscribe_command()
        self.node = graph.node(TELEOP_NODE, sim_time=True)
        self.publisher = self.node.create_publisher(self.msg_type, bridge.command_topic, 10)
        self.plan = DrivePlan(segments, lambda name, x, y: world.obstacle(name).distance(x, y))
        self.timer = self.node.create_timer(1.0 / TELEOP_RATE_HZ, self.tick)
        self.tick()  # the first segment starts with the run

    def tick(self) -> None:
        """Publish the command of the plan at the current sim time."""
        now = self.node.get_clock().now()
        x, y, _ = self.bridge.sim.pose
        command = self.plan.command(now.nanoseconds / NANOSECONDS_PER_SECOND, x, y)
        if command is None:
            self.timer.cancel()
        message = self.msg_type()
        twist = getattr(message, 'twist', message)
        twist.linear.x, twist.angular.z = command or (0.0, 0.0)
        if twist is not message:
            message.header.stamp = now.to_msg()
        self.publisher.publish(message)
