"""
Record a run's topics as a rosbag2 bag (MCAP storage) for ROS 2 tools, rosbags and Foxglove.

rosbag2 itself is not on PyPI, so the bag is written by rosbags. The two halves are kept apart:

* the bytes are rclpy's: :meth:`BagRecorder.write` takes the CDR bytes of a message as
  ``rclpy.serialization.serialize_message`` returns them, or as a subscription created with
  ``raw=True`` delivers them, and stores them with only their alignment padding zeroed
  (Fast CDR leaves it unwritten, see sim_bridge.runner.cdr_padding): the same run gives the same
  bag, byte for byte. Nothing is decoded or re-serialised;
* the storage is rosbags': its ``rosbag2.Writer`` with the MCAP storage plugin writes the file,
  the index and ``metadata.yaml`` (rosbag2 metadata version 9, as Jazzy's ``ros2 bag record``).
  Each topic's connection carries the message definition and type hash of rosbags' ROS2_JAZZY
  type store, and the offered QoS profile ``ros2 bag record`` would store, so ``ros2 bag play``
  re-publishes each topic with a compatible profile (``/tf_static`` latched). Two things are
  written as Jazzy's rosbag2_storage_mcap writes them, where rosbags differs: each MCAP channel
  holds the type hash (``topic_type_hash``) beside its QoS, and the metadata name the
  distribution (``ros_distro: jazzy``), not the writing library;
* a stepped run's bag (``sim_clock``, see :class:`BagRecorder`) holds the simulator's clock: a
  /clock message at every recorded message's time, so a node replaying it with
  ``use_sim_time`` never receives a message from its future.

Reading a bag back (``rosbags.rosbag2.Reader`` and ``Typestore.deserialize_cdr``) is for
whoever needs the messages; the recorder never looks inside them.
"""

from collections.abc import Iterable
import functools
from io import BytesIO, StringIO
import os
from pathlib import Path
import shutil
from types import TracebackType
from typing import Any

from rclpy.serialization import serialize_message
from rosbags.interfaces import (
    Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import Channel, McapWriter, write_channel, write_string
from rosbags.typesys import get_typestore, Stores
from rosbags.typesys.store import Typestore
from rosgraph_msgs.msg import Clock
from ruamel.yaml import YAML
from sim_bridge.runner.cdr_padding import PaddingZeroer

#: Topics recorded when none are named: what the bridge and the nodes under test exchange,
#: and what the nodes wrote (/rosout).
DEFAULT_TOPICS = ('/scan', '/cmd_vel', '/odom', '/tf', '/tf_static', '/clock', '/rosout')
#: rosbag2 metadata version of ROS 2 Jazzy.
BAG_VERSION = 9
#: The ``ros_distro`` of the metadata: the messages are Jazzy's (rosbag2 writes $ROS_DISTRO).
ROS_DISTRO = 'jazzy'
#: The topic of the simulator's clock, kept in step with the recorded messages.
CLOCK_TOPIC = '/clock'
_CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
# What `ros2 bag record` stores for durations it cannot query from the publisher ("infinite").
_UNSET_DURATION = QosTime(2147483647, 4294967295)
# Interface kinds whose generated classes are messages on a topic (services' and actions'
# parts included: rosbag2 records action feedback and status topics under such names).
_INTERFACE_KINDS = ('msg', 'srv', 'action')


def offered_qos(*, reliable: bool = True, transient_local: bool = False) -> Qos:
    """Return an offered QoS profile as ``ros2 bag record`` stores it for a publisher."""
    return Qos(QosHistory.UNKNOWN, 0,
               QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
               _UNSET_DURATION, _UNSET_DURATION, QosLiveliness.AUTOMATIC, _UNSET_DURATION,
               avoid_ros_namespace_conventions=False)


#: Offered QoS per topic; topics not listed get a reliable, volatile profile. (A node's
#: /rosout publisher is transient local, as /tf_static's.)
DEFAULT_QOS = {'/tf_static': offered_qos(transient_local=True),
               '/rosout': offered_qos(transient_local=True)}


def message_type_name(msg_or_class: Any) -> str:
    """
    Return the ROS type name (``sensor_msgs/msg/LaserScan``) of an rclpy message or its class.

    rosidl generates each class in a module ``<package>.<kind>._<snake_name>`` (``kind`` being
    ``msg``, or ``srv`` / ``action`` for their parts) with a metaclass holding its type support.
    Raises TypeError for anything else.
    """
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    parts = cls.__module__.split('.')
    if len(parts) != 3 or parts[1] not in _INTERFACE_KINDS or not parts[2].startswith('_') \
            or not hasattr(type(cls), '_TYPE_SUPPORT'):
        raise TypeError(f'{cls.__module__}.{cls.__qualname__} is not a generated ROS 2 '
                        'message class')
    return f'{parts[0]}/{parts[1]}/{cls.__name__}'


def _remove_old_bag(path: Path) -> None:
    """Delete a previous bag folder at ``path``; refuse anything else that is there."""
    if not path.is_dir() or any(
            item.is_dir() or not (item.name == 'metadata.yaml' or item.suffix == '.mcap')
            for item in path.iterdir()):
        raise FileExistsError(f'{path} exists and is not a rosbag2 bag; not overwriting it')
    shutil.rmtree(path)


@functools.cache
def _jazzy_typestore() -> Typestore:
    """Return rosbags' ROS2_JAZZY type store, shared by the recorders (never changed)."""
    return get_typestore(Stores.ROS2_JAZZY)


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic


def _with_jazzy_distro(metadata: str, *, strip: bool) -> str:
    """Return rosbag2 metadata YAML (whole, or its inner mapping) naming Jazzy as its distro."""
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False  # as rosbags dumps it
    info = yaml.load(metadata)
    info.get('rosbag2_bagfile_information', info)['ros_distro'] = ROS_DISTRO
    text = StringIO()
    yaml.dump(info, text)
    return text.getvalue().strip() if strip else text.getvalue()


class _JazzyMcapWriter(McapWriter):
    """rosbags' MCAP storage, with channels and metadata as Jazzy's rosbag2_storage_mcap has."""

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        """Add a channel whose metadata holds the offered QoS and the type hash (RIHS01)."""
        # rosbags' own add_connection with one more key, which rosbag2_storage_mcap's
        # create_topic writes and its reader turns back into the topic's type_description_hash.
        metadata = BytesIO()
        for key, value in (('offered_qos_profiles', offered_qos_profiles),
                           ('topic_type_hash', connection.digest)):
            write_string(metadata, key)
            write_string(metadata, value)
        self.channels.append(Channel(connection.id, connection.msgtype, connection.topic,
                                     connection.ext.serialization_format, metadata.getvalue()))
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def close(self, version: int, metadata: str) -> None:
        """Write the index and the MCAP's copy of the metadata, with Jazzy's distro."""
        super().close(version, _with_jazzy_distro(metadata, strip=True))


class _JazzyWriter(Writer):
    """rosbags' rosbag2 writer, storing as :class:`_JazzyMcapWriter` and naming Jazzy."""

    STORAGE_PLUGINS = {StoragePlugin.MCAP: _JazzyMcapWriter}

    def close(self) -> None:
        """Close the storage and write ``metadata.yaml`` with ``ros_distro: jazzy``."""
        super().close()
        self.metapath.write_text(
            _with_jazzy_distro(self.metapath.read_text('utf8'), strip=False), 'utf8')


class BagRecorder:
    """
    Write the CDR bytes of messages on the chosen topics into a new rosbag2 bag (MCAP storage).

    ``path`` is the bag folder, created here; the MCAP file inside is ``<folder name>.mcap``.
    With ``overwrite`` a previous bag there (a folder of ``metadata.yaml`` and ``.mcap`` files
    only) is deleted first; anything else at ``path`` is an error. A connection is created on a
    topic's first message of a type. Use it as a context manager: the bag is closed (index and
    metadata written, so it stays readable) even when the run fails half-way.

    With ``sim_clock`` (and /clock among the topics) the bag keeps the simulator's clock in
    step with its messages: a /clock message at each time (ns) a message is recorded at, written
    before it, and one only. ``ros2 bag play`` publishes /clock as it was recorded, so a node
    replaying the bag with ``use_sim_time`` never gets a message stamped ahead of its clock,
    whichever topics the run's nodes listened to (a stepped run sends /clock only when a node
    hears it, see :meth:`sim_bridge.ros.bridge.SimBridge.step`). A /clock message given at a time
    that has one is not written again: the clock messages of a stepped run hold their time.
    """

    def __init__(self, path: str | os.PathLike, topics: Iterable[str] = DEFAULT_TOPICS, *,
                 overwrite: bool = False, sim_clock: bool = False) -> None:
        self.path = Path(path)
        #: The recorded topics, absolute names.
        self.topics = frozenset(_absolute(topic) for topic in topics)
        if overwrite and self.path.exists():
            _remove_old_bag(self.path)
        self._typestore = _jazzy_typestore()
        self._zero_padding = PaddingZeroer(self._typestore)
        self._writer = _JazzyWriter(self.path, version=BAG_VERSION,
                                    storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._write = self._writer.write
        # What write does per topic (as given) and type name: write to the connection, or
        # nothing (None) for a topic not recorded. Emptied on close.
        self._routes: dict[tuple[str, str], Connection | None] = {}
        self._closed = False
        self._sim_clock = sim_clock and CLOCK_TOPIC in self.topics
        self._clock_ns = -1  # the time of the last /clock in the bag (ns)
        self._clock = Clock()  # filled in place for each /clock written

    @property
    def mcap_path(self) -> Path:
        """Return the path of the MCAP file inside the bag folder."""
        return self.path / f'{self.path.name}.mcap'

    @property
    def closed(self) -> bool:
        """Return True once the bag is closed."""
        return self._closed

    @property
    def counts(self) -> dict[str, int]:
        """Return the number of messages recorded per topic (topics with a connection)."""
        counts: dict[str, int] = {}
        for connection in self._writer.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + \
                self._writer.counts[connection.id]
        return counts

    def write(self, topic: str, type_name: str, data: bytes, t_ns: int) -> None:
        """
        Record a message's CDR bytes ``data`` published on ``topic`` at time ``t_ns`` (ns).

        ``type_name`` is its ROS type (``sensor_msgs/msg/LaserScan``, see
        :func:`message_type_name`); ``data`` is what ``rclpy.serialization.serialize_message``
        returns or a raw subscription delivers, encapsulation header first, and is stored with
        its padding zeroed. ``t_ns`` (an int, ns >= 0) is the bag's receive time for it, sim
        time in a stepped run. Messages on topics not recorded are ignored.
        """
        if t_ns.__class__ is not int or t_ns < 0:
            raise ValueError(f'bag {self.path}: a message time must be a non-negative int '
                             f'(ns), got {t_ns!r} on {topic}')
        try:
            connection = self._routes[topic, type_name]
        except KeyError:
            connection = self._route(topic, type_name)
        if connection is None:
            return
        if self._sim_clock and t_ns > self._clock_ns:
            self._clock_ns = t_ns
            if connection.topic != CLOCK_TOPIC:
                self._write_clock(t_ns)
        elif self._sim_clock and connection.topic == CLOCK_TOPIC:
            return  # the bag has the clock at t_ns already
        self._write(connection, t_ns, self._zero_padding(type_name, data))

    def _write_clock(self, t_ns: int) -> None:
        """Write a rosgraph_msgs/msg/Clock holding ``t_ns`` (ns) on /clock at ``t_ns``."""
        stamp = self._clock.clock
        stamp.sec, stamp.nanosec = divmod(t_ns, 1_000_000_000)
        connection = self._routes.get((CLOCK_TOPIC, _CLOCK_TYPE)) or \
            self._route(CLOCK_TOPIC, _CLOCK_TYPE)
        self._write(connection, t_ns,
                    self._zero_padding(_CLOCK_TYPE, serialize_message(self._clock)))

    def _route(self, topic: str, type_name: str) -> Connection | None:
        """Return (and keep) the connection of ``type_name`` on ``topic``, None if not kept."""
        if self._closed:
            raise RuntimeError(f'bag {self.path} is closed')
        name = _absolute(topic)
        connection = None
        if name in self.topics:
            connection = self._connection(name, type_name)
        self._routes[topic, type_name] = connection
        return connection

    def _connection(self, topic: str, type_name: str) -> Connection:
        """Return the connection of ``type_name`` on absolute ``topic``, added if new."""
        for connection in self._writer.connections:
            if connection.topic == topic and connection.msgtype == type_name:
                return connection
        if type_name not in self._typestore.fielddefs:
            raise ValueError(f'bag {self.path}: {type_name!r} on {topic} is not a message type '
                             'of ROS 2 Jazzy known to rosbags (pkg/msg/Name)')
        return self._writer.add_connection(
            topic, type_name, typestore=self._typestore,
            offered_qos_profiles=[DEFAULT_QOS.get(topic, offered_qos())])

    def close(self) -> None:
        """Finish the bag: write the MCAP index and ``metadata.yaml``. Safe to call twice."""
        if not self._closed:
            self._closed = True
            self._routes.clear()  # so that write finds the bag closed
            self._writer.close()

    def __enter__(self) -> 'BagRecorder':
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
