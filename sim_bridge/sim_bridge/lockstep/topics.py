"""
The topic graph: which subscriptions each publisher reaches, by name, type and QoS.

Matching follows the DDS/rmw rules Jazzy applies (``rmw_qos_profile_check_compatible``):

* a best-effort publisher does not reach a reliable subscription;
* a volatile publisher does not reach a transient-local subscription;
* a transient-local publisher keeps its last ``depth`` messages (KEEP_LAST) and hands them to
  transient-local subscriptions that join later.

Each incompatible pair is reported once on both sides with the warnings rclpy's default QoS
event callbacks log. A topic carries one message type: an endpoint asking for another type
raises :class:`TopicTypeError` (DDS would silently never connect them).
"""

from collections import deque

from sim_bridge.lockstep.errors import TopicTypeError
from sim_bridge.lockstep.messages import msgtype_of
from sim_bridge.lockstep.rclpy.qos import incompatible_policy, is_transient_local, queue_depth


class Topic:
    """The endpoints on one fully qualified topic name."""

    def __init__(self, name: str):
        self.name = name
        self.publishers: list = []
        self.subscriptions: list = []
        self.reported: set = set()

    def msgtype(self):
        """Return the message type its endpoints use, or None when it has none."""
        for endpoint in self.publishers + self.subscriptions:
            return msgtype_of(endpoint.msg_type)
        return None


class Graph:
    """All topics of a runtime; keeps every publisher's list of reachable subscriptions."""

    def __init__(self):
        self.topics: dict = {}

    def _topic(self, endpoint, role: str) -> Topic:
        topic = self.topics.setdefault(endpoint.topic_name, Topic(endpoint.topic_name))
        carried = topic.msgtype()
        wanted = msgtype_of(endpoint.msg_type)
        if carried is not None and carried != wanted:
            users = sorted({e._lockstep_node_name for e in topic.publishers + topic.subscriptions})
            raise TopicTypeError(
                f"node '{endpoint._lockstep_node_name}' created a {role} on {topic.name} with "
                f'type {wanted}, but {topic.name} already carries {carried} (used by node(s) '
                f"{', '.join(users)}); ROS 2 would never connect them")
        return topic

    def add_publisher(self, publisher) -> None:
        """Register a publisher; history is kept when its durability is transient local."""
        topic = self._topic(publisher, 'publisher')
        qos = publisher.qos_profile
        publisher._lockstep_history = deque(maxlen=queue_depth(qos)) \
            if is_transient_local(qos) else None
        topic.publishers.append(publisher)
        self._rematch(topic)

    def add_subscription(self, subscription) -> None:
        """Register a subscription and hand it the history of transient-local publishers."""
        topic = self._topic(subscription, 'subscription')
        topic.subscriptions.append(subscription)
        self._rematch(topic)
        if not is_transient_local(subscription.qos_profile):
            return
        for publisher in topic.publishers:
            if publisher._lockstep_history and subscription in publisher._lockstep_recipients:
                for wire in publisher._lockstep_history:
                    subscription._lockstep_receive(publisher._lockstep_copy(wire))

    def remove(self, endpoint) -> None:
        """Unregister a publisher or subscription (destroyed)."""
        topic = self.topics.get(endpoint.topic_name)
        if topic is None:
            return
        for endpoints in (topic.publishers, topic.subscriptions):
            if endpoint in endpoints:
                endpoints.remove(endpoint)
        self._rematch(topic)

    def count(self, topic_name: str, role: str) -> int:
        """Return the number of publishers or subscriptions on ``topic_name``."""
        topic = self.topics.get(topic_name)
        return 0 if topic is None else len(getattr(topic, role))

    def _rematch(self, topic: Topic) -> None:
        for publisher in topic.publishers:
            recipients = []
            for subscription in topic.subscriptions:
                policy = incompatible_policy(publisher.qos_profile, subscription.qos_profile)
                if policy is None:
                    recipients.append(subscription)
                elif (publisher, subscription) not in topic.reported:
                    topic.reported.add((publisher, subscription))
                    self._warn_incompatible(topic, publisher, subscription, policy)
            publisher._lockstep_recipients = recipients

    @staticmethod
    def _warn_incompatible(topic: Topic, publisher, subscription, policy: str) -> None:
        subscription._lockstep_logger.warning(
            f"New publisher discovered on topic '{topic.name}', offering incompatible QoS. "
            f'No messages will be received from it. Last incompatible policy: {policy}')
        publisher._lockstep_logger.warning(
            f"New subscription discovered on topic '{topic.name}', requesting incompatible "
            f'QoS. No messages will be sent to it. Last incompatible policy: {policy}')
