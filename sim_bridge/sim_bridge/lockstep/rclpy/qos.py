"""
rclpy.qos for the lockstep runtime: QoSProfile, the policy enums and the preset profiles.

Same names, values and defaults as Jazzy's rclpy (a profile built from ``depth`` alone is
KEEP_LAST, RELIABLE, VOLATILE, like ``rmw_qos_profile_default``), including the legacy aliases
(``QoSReliabilityPolicy`` ...). The matching rules the topic graph applies live here too:
SYSTEM_DEFAULT reliability means reliable and SYSTEM_DEFAULT durability means volatile, as with
the default DDS vendors; deadline, lifespan and liveliness are accepted and not enforced.
"""

from enum import Enum, IntEnum
from typing import Optional, Tuple

from sim_bridge.lockstep.rclpy.duration import Duration

__lockstep__ = True


class QoSPolicyKind(IntEnum):
    """Kinds of QoS policy (rmw/incompatible_qos_events_statuses.h)."""

    INVALID = 1 << 0
    DURABILITY = 1 << 1
    DEADLINE = 1 << 2
    LIVELINESS = 1 << 3
    RELIABILITY = 1 << 4
    HISTORY = 1 << 5
    LIFESPAN = 1 << 6
    DEPTH = 1 << 7
    LIVELINESS_LEASE_DURATION = 1 << 8
    AVOID_ROS_NAMESPACE_CONVENTIONS = 1 << 9


def qos_policy_name_from_kind(policy_kind) -> str:
    """Get a QoS policy's name from its QoSPolicyKind."""
    return QoSPolicyKind(policy_kind).name


class InvalidQoSProfileException(Exception):
    """Raised when constructing a QoSProfile with invalid arguments."""

    def __init__(self, *args):
        Exception.__init__(self, 'Invalid QoSProfile', *args)


class _ShortKeys:
    """rclpy's short-key helpers of the QoS enumerations (policies and preset profiles)."""

    @classmethod
    def short_keys(cls):
        """Return a list of shortened typing-friendly enum values."""
        return [k.lower() for k in cls.__members__.keys() if not k.startswith('RMW')]

    @classmethod
    def get_from_short_key(cls, name):
        """Retrieve a member's value from a short name, case-insensitive."""
        return cls[name.upper()].value


class QoSPolicyEnum(_ShortKeys, IntEnum):
    """Base for QoS policy enumerations, with the short-key helpers rclpy has."""

    @property
    def short_key(self):
        """The lower-case name of this value."""
        return self.name.lower()


class HistoryPolicy(QoSPolicyEnum):
    """QoS history settings (rmw/types.h)."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class ReliabilityPolicy(QoSPolicyEnum):
    """QoS reliability settings (rmw/types.h)."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class DurabilityPolicy(QoSPolicyEnum):
    """QoS durability settings (rmw/types.h)."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class LivelinessPolicy(QoSPolicyEnum):
    """QoS liveliness settings (rmw/types.h)."""

    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3
    UNKNOWN = 4
    BEST_AVAILABLE = 5


# Aliases with the old names, kept by rclpy for backwards compatibility.
QoSHistoryPolicy = HistoryPolicy
QoSReliabilityPolicy = ReliabilityPolicy
QoSDurabilityPolicy = DurabilityPolicy
QoSLivelinessPolicy = LivelinessPolicy

_DEFAULTS = {
    'history': HistoryPolicy.KEEP_LAST, 'depth': 10,
    'reliability': ReliabilityPolicy.RELIABLE, 'durability': DurabilityPolicy.VOLATILE,
    'lifespan': Duration(), 'deadline': Duration(),
    'liveliness': LivelinessPolicy.SYSTEM_DEFAULT, 'liveliness_lease_duration': Duration(),
    'avoid_ros_namespace_conventions': False,
}


def _policy(name: str, policy: type, doc: str) -> property:
    """Return a property storing ``policy(value)`` (a policy enum, or ValueError) as ``_name``."""
    attribute = '_' + name
    return property(lambda self: getattr(self, attribute),
                    lambda self, value: setattr(self, attribute, policy(value)), doc=doc)


def _checked(name: str, kind: type, doc: str) -> property:
    """Return a property storing a value of type ``kind`` as ``_name``, asserting the type."""
    attribute = '_' + name

    def setter(self, value) -> None:
        assert isinstance(value, kind)
        setattr(self, attribute, value)

    return property(lambda self: getattr(self, attribute), setter, doc=doc)


class QoSProfile:
    """Define Quality of Service policies."""

    __slots__ = [f'_{name}' for name in _DEFAULTS]

    def __init__(self, **kwargs):
        assert all('_' + key in self.__slots__ for key in kwargs.keys()), \
            'Invalid arguments passed to constructor: %r' % kwargs.keys()
        if 'history' not in kwargs:
            if 'depth' not in kwargs:
                raise InvalidQoSProfileException('History and/or depth settings are required.')
            kwargs['history'] = HistoryPolicy.KEEP_LAST
        self.history = kwargs['history']
        if self.history == HistoryPolicy.KEEP_LAST and 'depth' not in kwargs:
            raise InvalidQoSProfileException('History set to KEEP_LAST without a depth setting.')
        for name, default in _DEFAULTS.items():
            if name != 'history':
                setattr(self, name, kwargs.get(name, default))

    history = _policy('history', HistoryPolicy, 'How samples are kept.')
    reliability = _policy('reliability', ReliabilityPolicy, 'Delivery guarantee.')
    durability = _policy('durability', DurabilityPolicy, 'Whether late joiners get history.')
    liveliness = _policy('liveliness', LivelinessPolicy, 'Accepted, not enforced.')
    depth = _checked('depth', int, 'Messages kept with KEEP_LAST history.')
    lifespan = _checked('lifespan', Duration, 'Accepted, not enforced.')
    deadline = _checked('deadline', Duration, 'Accepted, not enforced.')
    liveliness_lease_duration = _checked('liveliness_lease_duration', Duration,
                                         'Accepted, not enforced.')
    avoid_ros_namespace_conventions = _checked('avoid_ros_namespace_conventions', bool,
                                               'Accepted, not used.')

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, QoSProfile):
            return False
        return all(getattr(self, slot) == getattr(other, slot) for slot in self.__slots__)

    def __str__(self) -> str:
        return f'{type(self).__name__}(%s)' % ', '.join(
            f'{slot[1:]}={getattr(self, slot)}' for slot in self.__slots__)


def _profile(history, depth, reliability, durability) -> QoSProfile:
    return QoSProfile(history=history, depth=depth, reliability=reliability,
                      durability=durability)


qos_profile_unknown = _profile(HistoryPolicy.UNKNOWN, 0, ReliabilityPolicy.UNKNOWN,
                               DurabilityPolicy.UNKNOWN)
qos_profile_system_default = _profile(HistoryPolicy.SYSTEM_DEFAULT, 0,
                                      ReliabilityPolicy.SYSTEM_DEFAULT,
                                      DurabilityPolicy.SYSTEM_DEFAULT)
qos_profile_sensor_data = _profile(HistoryPolicy.KEEP_LAST, 5, ReliabilityPolicy.BEST_EFFORT,
                                   DurabilityPolicy.VOLATILE)
qos_profile_services_default = _profile(HistoryPolicy.KEEP_LAST, 10, ReliabilityPolicy.RELIABLE,
                                        DurabilityPolicy.VOLATILE)
qos_profile_parameters = _profile(HistoryPolicy.KEEP_LAST, 1000, ReliabilityPolicy.RELIABLE,
                                  DurabilityPolicy.VOLATILE)
qos_profile_parameter_events = _profile(HistoryPolicy.KEEP_LAST, 1000,
                                        ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
qos_profile_action_status_default = _profile(HistoryPolicy.KEEP_LAST, 1,
                                             ReliabilityPolicy.RELIABLE,
                                             DurabilityPolicy.TRANSIENT_LOCAL)


class QoSPresetProfiles(_ShortKeys, Enum):
    """The named preset profiles."""

    UNKNOWN = qos_profile_unknown
    SYSTEM_DEFAULT = qos_profile_system_default
    SENSOR_DATA = qos_profile_sensor_data
    SERVICES_DEFAULT = qos_profile_services_default
    PARAMETERS = qos_profile_parameters
    PARAMETER_EVENTS = qos_profile_parameter_events
    ACTION_STATUS_DEFAULT = qos_profile_action_status_default


class QoSCompatibility(IntEnum):
    """Result of qos_check_compatible."""

    OK = 0
    WARNING = 1
    ERROR = 2


def _reliable(profile: QoSProfile) -> bool:
    return profile.reliability != ReliabilityPolicy.BEST_EFFORT


def is_transient_local(profile: QoSProfile) -> bool:
    """Tell whether the profile asks for TRANSIENT_LOCAL durability."""
    return profile.durability == DurabilityPolicy.TRANSIENT_LOCAL


def keeps_all(profile: QoSProfile) -> bool:
    """Tell whether the history is KEEP_ALL (the depth is then not a limit)."""
    return profile.history == HistoryPolicy.KEEP_ALL


def queue_depth(profile: QoSProfile) -> Optional[int]:
    """Messages a KEEP_LAST queue holds (at least 1: depth 0 is 'system default'), or None."""
    return None if keeps_all(profile) else max(1, profile.depth)


def incompatible_policy(publisher: QoSProfile, subscription: QoSProfile) -> Optional[str]:
    """Name of the last policy that stops ``publisher`` reaching ``subscription``, or None."""
    failed = None
    if _reliable(subscription) and not _reliable(publisher):
        failed = 'RELIABILITY'
    if is_transient_local(subscription) and not is_transient_local(publisher):
        failed = 'DURABILITY'
    return failed


def qos_check_compatible(publisher_qos: QoSProfile,
                         subscription_qos: QoSProfile) -> Tuple[QoSCompatibility, str]:
    """Check if two QoS profiles are compatible, as ``rclpy.qos.qos_check_compatible``."""
    reasons = []
    if _reliable(subscription_qos) and not _reliable(publisher_qos):
        reasons.append('ERROR: Best effort publisher and reliable subscription;')
    if is_transient_local(subscription_qos) and not is_transient_local(publisher_qos):
        reasons.append('ERROR: Volatile publisher and transient local subscription;')
    if reasons:
        return QoSCompatibility.ERROR, ''.join(reasons)
    return QoSCompatibility.OK, ''
