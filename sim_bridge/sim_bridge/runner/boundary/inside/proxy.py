"""
The agent's proxy node: what the student's nodes publish out, what the simulator sends in.

A node ``_lab_agent_proxy`` in the nodes' context takes what they publish (raw subscriptions,
so the CDR bytes cross as they are) and publishes what the trusted side sends them; the graph
says what the nodes are (names, topics, types, parameters). A mixin of the agent's Lockstep,
whose state (``proxy``, ``taps``, ``publishers``, ``graph``, ``shape``, ``nodes``) it uses.
"""

from importlib import import_module

from sim_bridge.runner.boundary.wire.frames import Message, type_name

#: ROS's own topics of every node: not forwarded (the run records the nodes' lines itself).
OWN_TOPICS = ('/rosout', '/parameter_events')
#: Messages the proxy keeps per topic between two exchanges.
PROXY_DEPTH = 1000


def message_class(name: str) -> type:
    """Return the message class of a ROS type name (``package/msg/Type``)."""
    package, _, kind = name.split('/')
    return getattr(import_module(f'{package}.msg'), kind)


class ProxyNode:
    """The proxy node's part of the agent's Lockstep: its taps, publishers and graph."""

    def _start_proxy(self, context) -> None:
        import rclpy
        if self.proxy is not None:
            return
        context = context or rclpy.utilities.get_default_context()
        if not context.ok():
            return
        from rclpy.node import Node
        self.proxy = Node.__new__(Node)
        self.proxy._lab_proxy = True
        Node.__init__(self.proxy, '_lab_agent_proxy', context=context,
                      use_global_arguments=False, start_parameter_services=False,
                      enable_rosout=False)

    def _graph(self) -> list:
        """Return what the student's nodes are: names, topics, types, parameters."""
        shape = [(id(node), *(len(getattr(node, name, ())) for name in (
            '_publishers', '_subscriptions', '_parameters'))) for node in self.nodes]
        if shape == self.shape:  # the same nodes with as many entities: the same graph
            return self.graph
        self.shape = shape
        graph = []
        for node in self.nodes:
            try:
                graph.append({
                    'name': node.get_name(), 'namespace': node.get_namespace(),
                    'publishes': sorted({(p.topic_name, type_name(p.msg_type))
                                         for p in node.publishers}),
                    'subscribes': sorted({(s.topic_name, type_name(s.msg_type))
                                          for s in node.subscriptions}),
                    'parameters': sorted(node._parameters),
                    'values': {name: parameter.value for name, parameter
                               in node._parameters.items()
                               if type(parameter.value) in (int, float)}})
            except Exception:  # noqa: B902 a destroyed node
                continue
        return [{**entry, 'publishes': [list(t) for t in entry['publishes']],
                 'subscribes': [list(t) for t in entry['subscribes']]} for entry in graph]

    def _taken(self) -> list[Message]:
        """Return the messages the nodes published since the last exchange, in order."""
        if self.proxy is None:
            return []
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        for entry in self.graph or ():
            for topic, name in entry['publishes']:
                if topic not in self.taps and topic not in OWN_TOPICS:
                    self.taps[topic] = self.proxy.create_subscription(
                        message_class(name), topic, lambda _: None,
                        QoSProfile(depth=PROXY_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT),
                        raw=True)
        taken = []
        for topic, tap in self.taps.items():
            while (got := tap.handle.take_message(tap.msg_type, True)) is not None:
                data, info = got
                taken.append((info['source_timestamp'], Message(
                    topic, type_name(tap.msg_type), data)))
        taken.sort(key=lambda item: item[0])
        return [message for _, message in taken]

    def _publisher(self, message: Message):
        if self.proxy is None:
            return None
        if message.topic not in self.publishers:
            from rclpy.qos import DurabilityPolicy, QoSProfile
            latched = any(info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                          for info in self.proxy.get_subscriptions_info_by_topic(message.topic))
            self.publishers[message.topic] = self.proxy.create_publisher(
                message_class(message.type_name), message.topic, QoSProfile(
                    depth=PROXY_DEPTH if not latched else 1,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                    else DurabilityPolicy.VOLATILE))
        return self.publishers[message.topic]
