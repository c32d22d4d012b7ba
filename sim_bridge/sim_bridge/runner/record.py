"""
Record a run's topics as a rosbag2 bag (MCAP storage), as ROS 2 Jazzy's ``ros2 bag record``.

rosbag2 itself is not on PyPI, so the bag is written through the ``mcap`` package's public
``Writer``, with what Jazzy's rosbag2_storage_mcap puts in it. The halves are kept apart:

* the bytes are rclpy's: :meth:`BagRecorder.write` takes the CDR bytes of a message as
  ``rclpy.serialization.serialize_message`` returns them, or as a subscription created with
  ``raw=True`` delivers them, and stores them with only their alignment padding zeroed
  (Fast CDR leaves it unwritten, see sim_bridge.runner.cdr_padding): the same run gives the same
  bag, byte for byte. Nothing is decoded or re-serialised;
* the types are the installed packages' (sim_bridge.common.message_types): each MCAP schema is the
  type's ``.msg`` definition with its dependencies (encoding ``ros2msg``) and each channel and
  topic holds the RIHS01 hash of its type description, so any type rclpy can publish can be
  recorded;
* each topic's QoS is what its publishers offered, read from the ROS graph
  (``get_publishers_info_by_topic`` of :attr:`BagRecorder.graph`) when its first message is
  recorded, with Jazzy's "infinite" durations (9223372036 s 854775807 ns) and policy names
  (metadata version 9);
* the storage is mcap's: chunks of at most CHUNK_BYTES reach the file as they fill, and
  ``metadata.yaml`` is written when the bag opens (no messages yet) and again, complete, when it
  closes. A recording cut short (a crash, ``kill -9``) keeps what was written: its
  ``metadata.yaml`` names the file, and :func:`recover` (``python -m sim_bridge.commands.record
  recover BAG``) rewrites the MCAP's readable messages as a closed bag with its counts;
* a stepped run's bag (``sim_clock``, see :class:`BagRecorder`) holds the simulator's clock: a
  /clock message at every recorded message's time, so a node replaying it with
  ``use_sim_time`` never receives a message from its future.
"""

from collections.abc import Iterable
from dataclasses import dataclass
import os
from pathlib import Path
import shutil
import struct
from types import TracebackType
from typing import Any, Protocol

from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader
from mcap.writer import Writer
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sim_bridge.common.message_types import message_definition, type_hash, UnknownMessageType
from sim_bridge.runner.cdr_padding import PaddingZeroer
import yaml

#: Topics recorded when none are named: what the bridge and the nodes under test exchange,
#: and what the nodes wrote (/rosout).
DEFAULT_TOPICS = ('/scan', '/cmd_vel', '/odom', '/tf', '/tf_static', '/clock', '/rosout')
#: rosbag2 metadata version of ROS 2 Jazzy.
BAG_VERSION = 9
#: The ``ros_distro`` of the metadata: the messages are Jazzy's (rosbag2 writes $ROS_DISTRO).
ROS_DISTRO = 'jazzy'
#: The topic of the simulator's clock, kept in step with the recorded messages.
CLOCK_TOPIC = '/clock'
ROSOUT_TOPIC = '/rosout'
#: Bytes of messages an MCAP chunk holds before it is written to the file: what a recording
#: cut short can lose at most.
CHUNK_BYTES = 64 * 1024
METADATA_FILE = 'metadata.yaml'
_CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
_NANOSECONDS_PER_SECOND = 1_000_000_000


class BagFull(Exception):
    """A message that would take a bag past its cap (``max_bytes``); the text says so."""


class Graph(Protocol):
    """What the recorder asks of the ROS graph: an rclpy Node has it."""

    context: Any  # the node's rclpy Context (``ok()`` until ROS is shut down)

    def get_publishers_info_by_topic(self, topic_name: str) -> list:
        """Return the publishers' endpoint information (with their QoS) on ``topic_name``."""


def _duration(duration: Any) -> dict[str, int]:
    """Return an rclpy Duration as rosbag2 stores it: ``sec`` and ``nsec``."""
    sec, nsec = divmod(duration.nanoseconds, _NANOSECONDS_PER_SECOND)
    return {'sec': sec, 'nsec': nsec}


def rosout_qos() -> Any:
    """Return rcl's QoS of a node's /rosout publisher (rcl_qos_profile_rosout_default)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL, lifespan=Duration(seconds=10))


def offered_qos(profile: Any) -> dict[str, Any]:
    """Return an rclpy QoSProfile as rosbag2 (metadata version 9) stores an offered profile."""
    return {'history': profile.history.name.lower(), 'depth': profile.depth,
            'reliability': profile.reliability.name.lower(),
            'durability': profile.durability.name.lower(),
            'deadline': _duration(profile.deadline), 'lifespan': _duration(profile.lifespan),
            'liveliness': profile.liveliness.name.lower(),
            'liveliness_lease_duration': _duration(profile.liveliness_lease_duration),
            'avoid_ros_namespace_conventions': profile.avoid_ros_namespace_conventions}


def _yaml(data: Any) -> str:
    """Return ``data`` as block-style YAML in its own key order, as rosbag2 writes it."""
    return yaml.safe_dump(data, default_flow_style=False, sort_keys=False)


@dataclass
class _Topic:
    """One recorded topic and type: its MCAP channel, profiles and count."""

    name: str
    type_name: str
    channel_id: int
    offered_qos_profiles: list[dict[str, Any]]
    type_description_hash: str
    message_count: int = 0

    def metadata(self) -> dict[str, Any]:
        """Return the topic's entry of ``topics_with_message_count``."""
        return {'topic_metadata': {'name': self.name, 'type': self.type_name,
                                   'serialization_format': 'cdr',
                                   'offered_qos_profiles': self.offered_qos_profiles,
                                   'type_description_hash': self.type_description_hash},
                'message_count': self.message_count}


def _remove_old_bag(path: Path) -> None:
    """Delete a previous bag folder at ``path``; refuse anything else that is there."""
    if not path.is_dir() or any(
            item.is_dir() or not (item.name == METADATA_FILE or item.suffix == '.mcap')
            for item in path.iterdir()):
        raise FileExistsError(f'{path} exists and is not a rosbag2 bag; not overwriting it')
    shutil.rmtree(path)


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic


class BagRecorder:
    """
    Write the CDR bytes of messages on the chosen topics into a new rosbag2 bag (MCAP storage).

    ``path`` is the bag folder, created here; the MCAP file inside is ``<folder name>_0.mcap``,
    as rosbag2 names it. With ``overwrite`` a previous bag there (a folder of
    ``metadata.yaml`` and ``.mcap`` files only) is deleted first; anything else at ``path`` is
    an error. A topic's channel is created on its first message of a type; its offered QoS
    profiles are then read from ``graph`` (an rclpy Node of the run; without one, or without
    publishers, none are stored). Use it as a context manager: the bag is closed (index and
    metadata written) even when the run fails half-way.

    With ``sim_clock`` (and /clock among the topics) the bag keeps the simulator's clock in
    step with its messages: a /clock message at each time (ns) a message is recorded at, written
    before it, and one only. ``ros2 bag play`` publishes /clock as it was recorded, so a node
    replaying the bag with ``use_sim_time`` never gets a message stamped ahead of its clock,
    whichever topics the run's nodes listened to (a stepped run sends /clock only when a node
    hears it, see :meth:`sim_bridge.ros.bridge.SimBridge.step`). A /clock message given at a time
    that has one is not written again: the clock messages of a stepped run hold their time.

    With ``max_bytes``, the messages' bytes in the bag stay within it: a message that would
    pass it is not written and raises BagFull (the bag stays whole, and can be closed).
    """

    def __init__(self, path: str | os.PathLike, topics: Iterable[str] = DEFAULT_TOPICS, *,
                 overwrite: bool = False, sim_clock: bool = False,
                 graph: Graph | None = None, max_bytes: int | None = None) -> None:
        self.path = Path(path)
        self.max_bytes = max_bytes
        self._bytes = 0
        #: The recorded topics, absolute names.
        self.topics = frozenset(_absolute(topic) for topic in topics)
        self._offers: dict[str, list[dict[str, Any]]] = {}
        self.graph = graph
        if overwrite and self.path.exists():
            _remove_old_bag(self.path)
        self.path.mkdir(parents=True)
        self._zero_padding = PaddingZeroer()
        self._file = open(self.mcap_path, 'wb')
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES)
        self._writer.start(profile='ros2')
        self._schemas: dict[str, int] = {}
        # What write does per topic (as given) and type name: write to the topic, or nothing
        # (None) for a topic not recorded. Emptied on close.
        self._routes: dict[tuple[str, str], _Topic | None] = {}
        self._recorded: list[_Topic] = []
        self._times: list[int] = []  # the first and the last time recorded (ns)
        self._closed = False
        self._sim_clock = sim_clock and CLOCK_TOPIC in self.topics
        self._clock_ns = -1  # the time of the last /clock in the bag (ns)
        self._clock = Clock()  # filled in place for each /clock written
        self._write_metadata()

    @property
    def graph(self) -> Graph | None:
        """Return where the offered QoS of a topic's publishers is read (None: nowhere)."""
        return self._graph

    @graph.setter
    def graph(self, graph: Graph | None) -> None:
        """Read the offers from ``graph`` from now on, and keep those it has now (see _offered)."""
        self._graph = graph
        self._offers = {topic: self._offered(topic) for topic in self.topics}

    def _offered(self, topic: str) -> list[dict[str, Any]]:
        """
        Return the QoS profiles the publishers on ``topic`` offer, as the graph has them now.

        Once ROS is shut down (a node may end it), the offers kept when the graph was given.
        """
        if self._graph is None or not self._graph.context.ok():
            return self._offers.get(topic, [])
        offers = [offered_qos(info.qos_profile)
                  for info in self._graph.get_publishers_info_by_topic(topic)]
        if not offers and topic == ROSOUT_TOPIC:  # the nodes' rcl publishers, in their process
            offers = [offered_qos(rosout_qos())]
        return offers

    @property
    def mcap_path(self) -> Path:
        """Return the path of the MCAP file inside the bag folder."""
        return self.path / f'{self.path.name}_0.mcap'

    @property
    def closed(self) -> bool:
        """Return True once the bag is closed."""
        return self._closed

    @property
    def counts(self) -> dict[str, int]:
        """Return the number of messages recorded per topic (topics with a channel)."""
        counts: dict[str, int] = {}
        for topic in self._recorded:
            counts[topic.name] = counts.get(topic.name, 0) + topic.message_count
        return counts

    def write(self, topic: str, type_name: str, data: bytes, t_ns: int) -> None:
        """
        Record a message's CDR bytes ``data`` published on ``topic`` at time ``t_ns`` (ns).

        ``type_name`` is its ROS type (``sensor_msgs/msg/LaserScan``, see
        sim_bridge.common.message_types.message_type_name); ``data`` is what
        ``rclpy.serialization.serialize_message`` returns or a raw subscription delivers,
        encapsulation header first, and is stored with its padding zeroed. ``t_ns`` (an int,
        ns >= 0) is the bag's receive time for it, sim time in a stepped run. Messages on
        topics not recorded are ignored.
        """
        if t_ns.__class__ is not int or t_ns < 0:
            raise ValueError(f'bag {self.path}: a message time must be a non-negative int '
                             f'(ns), got {t_ns!r} on {topic}')
        try:
            recorded = self._routes[topic, type_name]
        except KeyError:
            recorded = self._route(topic, type_name)
        if recorded is None:
            return
        if self._sim_clock and t_ns > self._clock_ns:
            self._clock_ns = t_ns
            if recorded.name != CLOCK_TOPIC:
                self._write_clock(t_ns)
        elif self._sim_clock and recorded.name == CLOCK_TOPIC:
            return  # the bag has the clock at t_ns already
        self._add(recorded, t_ns, self._zero_padding(type_name, data))

    def _add(self, recorded: _Topic, t_ns: int, data: bytes) -> None:
        if self.max_bytes is not None:
            if self._bytes + len(data) > self.max_bytes:
                raise BagFull(f'its recording reached its cap of {self.max_bytes} bytes of '
                              'messages')
            self._bytes += len(data)
        self._writer.add_message(recorded.channel_id, log_time=t_ns, data=data,
                                 publish_time=t_ns, sequence=recorded.message_count)
        recorded.message_count += 1
        if not self._times:
            self._times = [t_ns, t_ns]
        self._times = [min(self._times[0], t_ns), max(self._times[1], t_ns)]

    def _write_clock(self, t_ns: int) -> None:
        """Write a rosgraph_msgs/msg/Clock holding ``t_ns`` (ns) on /clock at ``t_ns``."""
        stamp = self._clock.clock
        stamp.sec, stamp.nanosec = divmod(t_ns, _NANOSECONDS_PER_SECOND)
        recorded = self._routes.get((CLOCK_TOPIC, _CLOCK_TYPE)) or \
            self._route(CLOCK_TOPIC, _CLOCK_TYPE)
        self._add(recorded, t_ns,
                  self._zero_padding(_CLOCK_TYPE, serialize_message(self._clock)))

    def _route(self, topic: str, type_name: str) -> _Topic | None:
        """Return (and keep) the recorded topic of ``type_name`` on ``topic``, None if not."""
        if self._closed:
            raise RuntimeError(f'bag {self.path} is closed')
        name = _absolute(topic)
        recorded = None
        if name in self.topics:
            recorded = next((known for known in self._recorded
                             if known.name == name and known.type_name == type_name), None)
            recorded = recorded or self._add_topic(name, type_name)
        self._routes[topic, type_name] = recorded
        return recorded

    def copy(self, topic: str, type_name: str, offered_qos_profiles: list[dict[str, Any]],
             t_ns: int, data: bytes) -> None:
        """Write a message of another bag as it was, on a topic offered these profiles."""
        recorded = next((known for known in self._recorded
                         if known.name == topic and known.type_name == type_name), None)
        self._add(recorded or self._add_topic(topic, type_name, offered_qos_profiles), t_ns,
                  data)

    def _add_topic(self, topic: str, type_name: str,
                   profiles: list[dict[str, Any]] | None = None) -> _Topic:
        """
        Add the schema (if new) and the channel of ``type_name`` on absolute ``topic``.

        Its offered QoS ``profiles`` are read from the graph unless given.
        """
        try:
            digest = type_hash(type_name)
            if type_name not in self._schemas:
                definition = message_definition(type_name)
                self._schemas[type_name] = self._writer.register_schema(
                    type_name, 'ros2msg' if definition else 'unknown', definition.encode())
        except UnknownMessageType as error:
            raise ValueError(f'bag {self.path}: {type_name!r} on {topic} cannot be recorded: '
                             f'{error}') from None
        if profiles is None:
            profiles = self._offered(topic)
        channel_id = self._writer.register_channel(
            topic, 'cdr', self._schemas[type_name],
            {'offered_qos_profiles': _yaml(profiles) if profiles else '',
             'topic_type_hash': digest})
        self._recorded.append(_Topic(topic, type_name, channel_id, profiles, digest))
        return self._recorded[-1]

    def _metadata(self) -> dict[str, Any]:
        """Return ``rosbag2_bagfile_information`` as Jazzy's rosbag2 writes it."""
        start, end = self._times or [0, 0]
        count = sum(topic.message_count for topic in self._recorded)
        return {'version': BAG_VERSION, 'storage_identifier': 'mcap',
                'duration': {'nanoseconds': end - start},
                'starting_time': {'nanoseconds_since_epoch': start},
                'message_count': count,
                'topics_with_message_count': [topic.metadata() for topic in self._recorded],
                'compression_format': '', 'compression_mode': '',
                'relative_file_paths': [self.mcap_path.name],
                'files': [{'path': self.mcap_path.name,
                           'starting_time': {'nanoseconds_since_epoch': start},
                           'duration': {'nanoseconds': end - start},
                           'message_count': count}],
                'custom_data': None, 'ros_distro': ROS_DISTRO}

    def _write_metadata(self) -> None:
        (self.path / METADATA_FILE).write_text(
            _yaml({'rosbag2_bagfile_information': self._metadata()}), 'utf-8')

    def close(self) -> None:
        """Finish the bag: write the MCAP index and ``metadata.yaml``. Safe to call twice."""
        if not self._closed:
            self._closed = True
            self._routes.clear()  # so that write finds the bag closed
            self._graph = None  # the run's node is freed with the run, not with the bag
            try:
                self._writer.add_metadata('rosbag2', {
                    'serialized_metadata': _yaml(self._metadata()), 'ROS_DISTRO': ROS_DISTRO})
                self._writer.finish()
            finally:  # a full disk: the file is closed all the same
                self._file.close()
            self._write_metadata()

    def __enter__(self) -> 'BagRecorder':
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()


def recover(path: str | os.PathLike) -> dict[str, int]:
    """
    Close a bag whose recording was cut short: keep every message its MCAP file holds whole.

    The readable messages (those of the chunks that reached the file) are written again, as
    they were, into a closed bag of the same name, with the topics' QoS as the bag recorded
    them, the types' definitions and hashes of the installed packages (as when recording), and
    a complete ``metadata.yaml``. Returns the count per topic.
    """
    bag = Path(path)
    info = yaml.safe_load((bag / METADATA_FILE).read_text('utf-8'))
    cut = bag / info['rosbag2_bagfile_information']['relative_file_paths'][0]
    staging = bag.parent / f'.{bag.name}.recovering'
    shutil.rmtree(staging, ignore_errors=True)
    with open(cut, 'rb') as stream, BagRecorder(staging / bag.name) as recovered:
        for topic, type_name, profiles, t_ns, data in _readable_messages(stream):
            recovered.copy(topic, type_name, profiles, t_ns, data)
    shutil.rmtree(bag)
    (staging / bag.name).rename(bag)
    staging.rmdir()
    return recovered.counts


def _readable_messages(stream) -> Iterable[tuple[str, str, list, int, bytes]]:
    """Yield (topic, type, offered QoS profiles, time ns, bytes) of an MCAP's whole messages."""
    messages = NonSeekingReader(stream).iter_messages(log_time_order=False)  # as stored
    try:
        for schema, channel, message in messages:
            profiles = yaml.safe_load(channel.metadata.get('offered_qos_profiles') or '[]')
            yield channel.topic, schema.name, profiles, message.log_time, message.data
    except (EOFError, ValueError, struct.error, McapError):
        return  # the record cut short: the messages before it are what was written
