"""
rclpy.node for the lockstep runtime: Node, with Jazzy's constructor and entity API.

A node resolves its name, namespace, remappings and parameter overrides from the ROS arguments
of its context (``rclpy.init(args=...)``, unless ``use_global_arguments=False``), its own
``cli_args`` and ``parameter_overrides``, in that order of increasing precedence. It declares
``use_sim_time`` like rclpy's TimeSource. Its clock is ROS time, i.e. the runtime's sim time.
Services, clients, actions and rates are not part of the lockstep subset and raise.
"""

from typing import Any, Callable, Iterator, List, Optional

from sim_bridge.lockstep import loop, names, rosargs
from sim_bridge.lockstep.errors import LockstepError
from sim_bridge.lockstep.messages import LockstepMessage, message_class
from sim_bridge.lockstep.rclpy.clock import ROSClock
from sim_bridge.lockstep.rclpy.constants import S_TO_NS
from sim_bridge.lockstep.rclpy.exceptions import NotInitializedException
from sim_bridge.lockstep.rclpy.logging import get_logger
from sim_bridge.lockstep.rclpy.node_parameters import NodeParameters
from sim_bridge.lockstep.rclpy.parameter import Parameter
from sim_bridge.lockstep.rclpy.publisher import Publisher
from sim_bridge.lockstep.rclpy.qos import QoSProfile
from sim_bridge.lockstep.rclpy.subscription import Subscription
from sim_bridge.lockstep.rclpy.timer import Timer
from sim_bridge.lockstep.rclpy.utilities import get_default_context

__lockstep__ = True


class _CallbackGroup:
    """Callbacks run one at a time in the lockstep loop, whatever their group."""


def _check_is_valid_msg_type(msg_type) -> None:
    if not (isinstance(msg_type, type) and issubclass(msg_type, LockstepMessage)):
        raise RuntimeError(f'The message type provided is not valid ({msg_type}). This might be '
                           'a service or action, or a message class from another library')


def _validate_qos_or_depth_parameter(qos_or_depth) -> QoSProfile:
    if isinstance(qos_or_depth, QoSProfile):
        return qos_or_depth
    if isinstance(qos_or_depth, int):
        if qos_or_depth < 0:
            raise ValueError('history depth must be greater than or equal to zero')
        return QoSProfile(depth=qos_or_depth)
    raise TypeError(f'Expected QoSProfile or int, but received {type(qos_or_depth)!r}')


class Node(NodeParameters):
    """A node in the ROS graph."""

    def __init__(self, node_name: str, *, context=None, cli_args: Optional[List[str]] = None,
                 namespace: Optional[str] = None, use_global_arguments: bool = True,
                 enable_rosout: bool = True, start_parameter_services: bool = True,
                 parameter_overrides: Optional[List[Parameter]] = None,
                 allow_undeclared_parameters: bool = False,
                 automatically_declare_parameters_from_overrides: bool = False,
                 enable_logger_service: bool = False) -> None:
        self._runtime = loop.current()
        self._context = get_default_context() if context is None else context
        if not self._context.ok():
            raise NotInitializedException('cannot create node')
        arguments = [rosargs.parse(cli_args or [])]
        if use_global_arguments:
            arguments.append(self._context.ros_arguments)
        # Local rules come first: the first rule that matches wins, as in rcl.
        self._remaps = [rule for args in arguments for rule in args.remaps
                        if rosargs.node_key_matches(rule[0], node_name, '/' + node_name)]
        self._name, self._namespace = self._resolve_identity(node_name, namespace)
        self._logger = get_logger('.'.join(
            [token for token in self._namespace.split('/') if token] + [self._name]))
        self._publishers: List[Publisher] = []
        self._subscriptions: List[Subscription] = []
        self._timers: List[Timer] = []
        self._default_callback_group = _CallbackGroup()
        self._executor = None
        self._destroyed = False
        self._init_parameters(self._collect_overrides(reversed(arguments), parameter_overrides),
                              allow_undeclared_parameters)
        self._clock = ROSClock()
        if automatically_declare_parameters_from_overrides:
            descriptor = message_class('rcl_interfaces/msg/ParameterDescriptor')
            self.declare_parameters(
                '', [(name, parameter.value, descriptor())
                     for name, parameter in self._parameter_overrides.items()],
                ignore_override=True)
        if not self.has_parameter('use_sim_time'):
            self.declare_parameter('use_sim_time', False)
        self._context.track_node(self)
        self._runtime.nodes.append(self)

    def _resolve_identity(self, node_name: str, namespace: Optional[str]):
        """Apply ``__node``/``__ns`` remaps (first match wins) and validate the results."""
        names.validate_node_name(node_name)
        namespace = names.normalize_namespace(namespace)
        renames = {source: target for _, source, target in reversed(self._remaps)}
        node_name = renames.get('__node', renames.get('__name', node_name))
        names.validate_node_name(node_name)
        if '__ns' in renames:
            namespace = names.normalize_namespace(renames['__ns'])
        return node_name, namespace

    def _collect_overrides(self, arguments, parameter_overrides) -> dict:
        """Merge overrides: params files then ``-p``, wildcard keys before this node's own."""
        overrides = {}
        fqn = self.get_fully_qualified_name()
        for args in arguments:
            rules = [(key, name, value) for path in args.params_files
                     for key, values in rosargs.params_file(path).items()
                     for name, value in values.items()] + args.parameters
            rules = [rule for rule in rules if rosargs.node_key_matches(rule[0], self._name, fqn)]
            # As in rclcpp/rclpy, '/**' rules apply first and this node's own rules win.
            rules.sort(key=lambda rule: rule[0] is not None and '*' not in rule[0])
            overrides.update({name: Parameter(name, value=value) for _, name, value in rules})
        overrides.update({parameter.name: parameter for parameter in parameter_overrides or []})
        return overrides

    # --- identity -----------------------------------------------------------------------------

    @property
    def context(self):
        """The context the node was created with."""
        return self._context

    @property
    def executor(self):
        """The executor the node was added to, or None."""
        return self._executor

    @executor.setter
    def executor(self, new_executor) -> None:
        if self._executor is not None and self._executor is not new_executor:
            self._executor.remove_node(self)
        if new_executor is not None:
            new_executor.add_node(self)
        self._executor = new_executor

    @property
    def default_callback_group(self):
        """The default callback group (groups do not matter in the lockstep loop)."""
        return self._default_callback_group

    @property
    def publishers(self) -> Iterator[Publisher]:
        """Publishers created on this node."""
        yield from self._publishers

    @property
    def subscriptions(self) -> Iterator[Subscription]:
        """Subscriptions created on this node."""
        yield from self._subscriptions

    @property
    def timers(self) -> Iterator[Timer]:
        """Timers created on this node."""
        yield from self._timers

    def get_name(self) -> str:
        """Get the name of the node."""
        return self._name

    def get_namespace(self) -> str:
        """Get the namespace of the node."""
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        """Get the node's fully qualified name, e.g. ``/robot1/wall_follow``."""
        return self._namespace.rstrip('/') + '/' + self._name

    def get_clock(self) -> ROSClock:
        """Get the clock used by the node (sim time)."""
        return self._clock

    def get_logger(self):
        """Get the node's logger."""
        return self._logger

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        """Expand (and unless ``only_expand``, remap) a topic name for this node."""
        expanded = names.expand_topic_name(topic, self._name, self._namespace)
        if only_expand:
            return expanded
        return names.remap_topic(expanded, self._remaps, self._name, self._namespace)

    # --- entities -----------------------------------------------------------------------------

    def create_publisher(self, msg_type, topic: str, qos_profile, *, callback_group=None,
                         event_callbacks=None, qos_overriding_options=None,
                         publisher_class=Publisher) -> Publisher:
        """Create a publisher of ``msg_type`` on ``topic`` (an int QoS is a KEEP_LAST depth)."""
        qos_profile = _validate_qos_or_depth_parameter(qos_profile)
        _check_is_valid_msg_type(msg_type)
        publisher = Publisher(msg_type, self.resolve_topic_name(topic), qos_profile,
                              lockstep_node=self)
        self._runtime.graph.add_publisher(publisher)
        self._publishers.append(publisher)
        return publisher

    def create_subscription(self, msg_type, topic: str, callback: Callable[[Any], None],
                            qos_profile, *, callback_group=None, event_callbacks=None,
                            qos_overriding_options=None, raw: bool = False) -> Subscription:
        """Create a subscription calling ``callback(msg)`` for each message on ``topic``."""
        qos_profile = _validate_qos_or_depth_parameter(qos_profile)
        _check_is_valid_msg_type(msg_type)
        if raw:
            raise LockstepError('raw (serialized) subscriptions are not supported by the '
                                'lockstep runtime')
        subscription = Subscription(msg_type, self.resolve_topic_name(topic), callback,
                                    callback_group or self._default_callback_group,
                                    qos_profile, lockstep_node=self)
        self._subscriptions.append(subscription)
        self._runtime.graph.add_subscription(subscription)
        return subscription

    def create_timer(self, timer_period_sec: float, callback: Callable, callback_group=None,
                     clock=None, autostart: bool = True) -> Timer:
        """Create a timer firing every ``timer_period_sec`` seconds of sim time."""
        timer = Timer(callback, callback_group or self._default_callback_group,
                      int(float(timer_period_sec) * S_TO_NS), clock or self._clock,
                      context=self._context, autostart=autostart, lockstep_node=self)
        self._timers.append(timer)
        return timer

    def create_rate(self, frequency: float, clock=None):
        """Not supported: Rate.sleep() would block the single-threaded lockstep loop."""
        raise LockstepError('create_rate(): Rate.sleep() would block the lockstep loop; '
                            'use create_timer() instead')

    def create_client(self, srv_type, srv_name: str, **kwargs):
        """Not supported: the lockstep runtime has topics only."""
        raise LockstepError('services are not supported by the lockstep runtime')

    def create_service(self, srv_type, srv_name: str, callback, **kwargs):
        """Not supported: the lockstep runtime has topics only."""
        raise LockstepError('services are not supported by the lockstep runtime')

    def create_guard_condition(self, callback, callback_group=None):
        """Not supported: nothing else can wake the lockstep loop."""
        raise LockstepError('guard conditions are not supported by the lockstep runtime')

    def destroy_publisher(self, publisher: Publisher) -> bool:
        """Destroy a publisher created by this node."""
        if publisher not in self._publishers:
            return False
        self._publishers.remove(publisher)
        publisher.destroy()
        return True

    def destroy_subscription(self, subscription: Subscription) -> bool:
        """Destroy a subscription created by this node; undelivered messages are dropped."""
        if subscription not in self._subscriptions:
            return False
        self._subscriptions.remove(subscription)
        subscription.destroy()
        return True

    def destroy_timer(self, timer: Timer) -> bool:
        """Destroy a timer created by this node."""
        if timer not in self._timers:
            return False
        self._timers.remove(timer)
        timer.destroy()
        return True

    def destroy_node(self) -> None:
        """Destroy the node and everything it created."""
        for publisher in list(self._publishers):
            self.destroy_publisher(publisher)
        for subscription in list(self._subscriptions):
            self.destroy_subscription(subscription)
        for timer in list(self._timers):
            self.destroy_timer(timer)
        self._context.untrack_node(self)
        if self in self._runtime.nodes:
            self._runtime.nodes.remove(self)
        self._destroyed = True

    def _lockstep_stop(self) -> None:
        """Stop all callbacks (the context was shut down)."""
        for entity in self._timers + self._subscriptions + self._publishers:
            entity._lockstep_stop()

    # --- graph --------------------------------------------------------------------------------

    def count_publishers(self, topic_name: str) -> int:
        """Return the number of publishers on a topic."""
        return self._runtime.graph.count(self.resolve_topic_name(topic_name), 'publishers')

    def count_subscribers(self, topic_name: str) -> int:
        """Return the number of subscriptions on a topic."""
        return self._runtime.graph.count(self.resolve_topic_name(topic_name), 'subscriptions')

    def get_node_names(self) -> List[str]:
        """Return the names of the nodes alive in the runtime."""
        return [node.get_name() for node in self._runtime.nodes]

    def get_node_names_and_namespaces(self) -> list:
        """Return ``[(name, namespace)]`` of the nodes alive in the runtime."""
        return [(node.get_name(), node.get_namespace()) for node in self._runtime.nodes]

    def get_topic_names_and_types(self, no_demangle: bool = False) -> list:
        """``[(topic, [type])]`` for every topic with an endpoint."""
        graph = self._runtime.graph
        return sorted((name, [topic.msgtype()]) for name, topic in graph.topics.items()
                      if topic.msgtype() is not None)
