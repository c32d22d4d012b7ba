"""
The trusted side's ends of a node process's topics, and the check of every message it sends.

Taps: raw subscriptions here to what the process's nodes subscribe to (what the simulator
publishes goes to them through these). Publishers: what its nodes publish, republished here
once each message is checked (its type the topic's, its bytes that type, its size within the
caps of boundary_checks). A topic more than MAX_TOPICS, or one rcl refuses, fails that run:
a node's error, never the trusted side's. A mixin of the link's Agent, whose state (``node``,
``graph``, ``taps``, ``publishers``, ``failure``) it uses.
"""

from typing import Any, Callable, Iterable, Sequence

from sim_bridge.runner.boundary.outside.boundary_checks import (
    allowed_class, MAX_TOPICS, message_refusal)
from sim_bridge.runner.boundary.wire.frames import Message, type_name
from sim_bridge.runner.hints import topic_type_hint

#: ROS's own topics of every node: they stay in the node's process.
OWN_TOPICS = ('/rosout', '/parameter_events')


class TopicEnds:
    """The Agent's taps and publishers here, for the topics of its process's nodes."""

    def update_taps(self) -> None:
        """Subscribe here (raw) to each topic the process's nodes subscribe to."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        for entry in self.graph:
            for topic, name in entry['subscribes']:
                msg_type = allowed_class(name)
                if topic in self.taps or topic in OWN_TOPICS or msg_type is None:
                    continue
                publishers = self.node.get_publishers_info_by_topic(topic)
                latched = publishers and all(
                    info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                    for info in publishers)
                qos = (QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
                       if latched else
                       QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
                self.taps[topic] = self.created(
                    topic, name, lambda: self.node.create_subscription(
                        msg_type, topic, lambda _: None, qos, raw=True))

    def update_publishers(self) -> None:
        """
        Publish here each topic the process's nodes publish, as soon as their graph says so.

        So that the trusted side's graph shows their publishers before their first message:
        the bridge subscribes to the command topic with the type they publish it as.
        """
        for entry in self.graph:
            for topic, name in entry['publishes']:
                msg_type = allowed_class(name)
                if topic in self.publishers or topic in OWN_TOPICS or msg_type is None:
                    continue
                self.publishers[topic] = (self.created(
                    topic, name, lambda: self.node.create_publisher(msg_type, topic, 1000)),
                    msg_type)

    def created(self, topic: str, name: str, create: Callable[[], Any]) -> Any:
        """
        Return what ``create()`` makes for ``topic`` (of type ``name``): a tap or a publisher.

        Its failure when the process has MAX_TOPICS already, or when rcl refuses it (a second
        type on a topic of the run): a node's error, never the trusted side's.
        """
        if len(self.taps) + len(self.publishers) >= MAX_TOPICS:
            raise self.failure(f'uses {topic} beyond the cap of {MAX_TOPICS} topics per process')
        try:
            return create()
        except Exception as error:  # noqa: B902 rclpy's RCLError: a second type
            raise self.failure(f'uses {topic} as {name} '
                               f'({topic_type_hint(error) or error})') from None

    def taken(self, topics: Iterable[str] | None = None) -> list[Message]:
        """Take the messages published here for the process since the last exchange."""
        taken = []
        for topic, tap in self.taps.items():
            if topics is not None and topic not in topics:
                continue
            while (got := tap.handle.take_message(tap.msg_type, True)) is not None:
                data, info = got
                message = Message(topic, type_name(tap.msg_type), data)
                taken.append((info['source_timestamp'], message))
        taken.sort(key=lambda item: item[0])
        return [message for _, message in taken]

    def republish(self, messages: Sequence[Message]) -> None:
        """
        Publish here what the process's nodes published, each checked; fail if one is bad.

        Checked: its type is the one the topic is published as here, and its bytes deserialize
        as that type. What is published is the message rclpy read from them, never the bytes
        (bytes after a message of an unbounded type would go on to the bag).
        """
        from rclpy.serialization import deserialize_message
        for message in messages:
            if message.topic in OWN_TOPICS:
                continue
            known = self.publishers.get(message.topic)
            if known is None:
                msg_type = allowed_class(message.type_name)
                if msg_type is None:
                    continue  # a type of no package the run knows: it stays in its process
                known = self.publishers[message.topic] = (self.created(
                    message.topic, message.type_name,
                    lambda: self.node.create_publisher(msg_type, message.topic, 1000)),
                    msg_type)
            publisher, msg_type = known
            if type_name(msg_type) != message.type_name:
                raise self.failure(f'sent {message.topic} as {message.type_name}, a type it '
                                   'did not publish it as')
            refusal = message_refusal(message.topic, message.type_name, message.data)
            try:
                msg = None if refusal else deserialize_message(message.data, msg_type)
            except Exception as error:  # noqa: B902 whatever rclpy raises on bad bytes
                raise self.failure(f'sent bytes that are not a {message.type_name} on '
                                   f'{message.topic} ({type(error).__name__})') from None
            refusal = refusal or message_refusal(message.topic, message.type_name,
                                                 message.data, msg)
            if refusal:
                raise self.failure(refusal)
            publisher.publish(msg)
        self.taken({m.topic for m in messages})  # not back to where they came from
