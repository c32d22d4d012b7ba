"""
Record a run's topics as a rosbag2 bag (MCAP storage) for ROS 2 tools, rosbags and Foxglove.

:class:`BagRecorder` takes messages as the lockstep runtime publishes them (its rclpy-faithful
message objects, or rosbags messages), serialises them to CDR by the field definitions of the
rosbags ROS2_JAZZY type store and appends them to ``<bag>/<bag name>.mcap`` with rosbags'
writer. ``metadata.yaml`` is written on close, with the offered QoS profiles ``ros2 bag record``
would store, so ``ros2 bag play`` re-publishes each topic with a compatible profile
(``/tf_static`` latched).

A 600 s run publishes some 130 000 messages, so the per-message path is kept short: a generated
serialiser per type (no conversion to rosbags objects first) and a leaner message-record writer
than rosbags' own; both produce bytes identical to rosbags' (the tests compare them).
"""

from collections.abc import Callable, Iterable, Mapping
import os
from pathlib import Path
import shutil
import struct
from types import TracebackType
from typing import Any

import numpy as np
from rosbags.interfaces import (Nodetype, Qos, QosDurability, QosHistory, QosLiveliness,
                                QosReliability, QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import get_typestore, Stores
from rosbags.typesys.store import Typestore

#: Topics recorded when none are named: what the bridge and the nodes under test exchange.
DEFAULT_TOPICS = ('/scan', '/cmd_vel', '/odom', '/tf', '/tf_static', '/clock')
#: rosbag2 metadata version of ROS 2 Jazzy.
BAG_VERSION = 9
# What `ros2 bag record` stores for durations it cannot query from the publisher ("infinite").
_UNSET_DURATION = QosTime(2147483647, 4294967295)
_NUMPY_TYPES = {
    'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8, 'int8': np.int8, 'uint8': np.uint8,
    'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32, 'uint32': np.uint32,
    'int64': np.int64, 'uint64': np.uint64, 'float32': np.float32, 'float64': np.float64,
}

#: CDR encapsulation header: little-endian plain CDR, no options.
CDR_LITTLE_ENDIAN_HEADER = bytes((0, 1, 0, 0))
_SCALAR_FORMATS = {
    'bool': '?', 'byte': 'B', 'char': 'B', 'int8': 'b', 'uint8': 'B', 'int16': 'h',
    'uint16': 'H', 'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q', 'float32': 'f',
    'float64': 'd',
}
# The field rosidl and rosbags give a message without fields (a C struct needs one member).
EMPTY_MESSAGE_PLACEHOLDER = 'structure_needs_at_least_one_member'
_PADDING = tuple(bytes(count) for count in range(8))
_pack_uint32 = struct.Struct('<I').pack


def offered_qos(*, reliable: bool = True, transient_local: bool = False) -> Qos:
    """Return an offered QoS profile as ``ros2 bag record`` stores it for a publisher."""
    return Qos(QosHistory.UNKNOWN, 0,
               QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
               _UNSET_DURATION, _UNSET_DURATION, QosLiveliness.AUTOMATIC, _UNSET_DURATION,
               avoid_ros_namespace_conventions=False)


#: Offered QoS per topic; topics not listed get a reliable, volatile profile.
DEFAULT_QOS = {'/tf_static': offered_qos(transient_local=True)}


def ros_type_name(msg: Any) -> str:
    """
    Return the ROS type name (``sensor_msgs/msg/LaserScan``) of a message object.

    rosbags messages carry it as ``__msgtype__``; rosidl-generated classes (and the lockstep
    runtime's) live in a module ``<package>.msg._<snake_name>``.
    """
    cls = type(msg)
    name = getattr(cls, '__msgtype__', None)
    if isinstance(name, str):
        return name
    package, interface_kind = (cls.__module__.split('.') + ['', ''])[:2]
    if interface_kind != 'msg':
        raise TypeError(f'{cls.__module__}.{cls.__qualname__} is not a ROS message class')
    return f'{package}/msg/{cls.__name__}'


class CdrSerializer:
    """
    Serialise message objects to little-endian CDR, reading fields by the type store's names.

    Any object with the fields of its ROS type serialises (rosidl's classes, the lockstep
    runtime's, rosbags' own), so runtime messages need no conversion first. One function is
    generated per type: runs of scalar fields are packed by one precompiled ``struct`` format
    per start alignment, arrays copied as numpy buffers, nested messages inlined. The bytes
    equal ``typestore.serialize_cdr`` of the same message (the tests compare them).
    """

    def __init__(self, typestore: Typestore) -> None:
        self.typestore = typestore
        self._functions: dict[str, Callable[[Any, bytearray], None]] = {}

    def serialize(self, msg: Any, typename: str | None = None) -> bytearray:
        """Return the CDR bytes (with the 4-byte encapsulation header) of ``msg``."""
        out = bytearray(CDR_LITTLE_ENDIAN_HEADER)
        self.function(typename or ros_type_name(msg))(msg, out)
        return out

    def function(self, typename: str) -> Callable[[Any, bytearray], None]:
        """Return the function appending a ``typename`` message's CDR payload to a bytearray."""
        if typename not in self._functions:
            self._functions[typename] = _CdrCodegen(self).build(typename)
        return self._functions[typename]


def _scalar_size(type_name: str) -> int:
    return struct.calcsize(_SCALAR_FORMATS[type_name])


def _numeric_bytes(values: Any, dtype: np.dtype) -> bytes:
    """Return the little-endian bytes of a numeric array field's values."""
    if isinstance(values, (bytes, bytearray)):
        return bytes(values)
    if isinstance(values, list) and values and isinstance(values[0], bytes):
        return b''.join(values)  # rosidl keeps byte[] as a list of 1-byte bytes
    return np.asarray(values, dtype=dtype).tobytes()


def _byte_value(value: Any) -> int:
    """
    Return a ``byte`` field's value as an octet (0..255).

    rosidl keeps a byte as a 1-byte bytes object; rosbags as a signed int (-128..127).
    """
    return value[0] if isinstance(value, (bytes, bytearray)) else value & 0xFF


class _CdrCodegen:
    """Writes the Python source of one type's serialiser (see :class:`CdrSerializer`)."""

    def __init__(self, serializer: CdrSerializer) -> None:
        self.serializer = serializer
        self.fielddefs = serializer.typestore.fielddefs
        self.namespace: dict[str, Any] = {
            'PADDING': _PADDING, 'pack_uint32': _pack_uint32, 'numeric_bytes': _numeric_bytes,
            'byte_value': _byte_value}
        self.lines: list[str] = []
        self.scalars: list[tuple[str, str]] = []

    def build(self, typename: str) -> Callable[[Any, bytearray], None]:
        self.lines = ['def serialize(msg, out):']
        self.message(typename, 'msg', '  ')
        self.flush('  ')
        self.lines.append('  return out')
        exec(compile('\n'.join(self.lines), f'<cdr {typename}>', 'exec'), self.namespace)
        return self.namespace['serialize']

    def name(self, value: Any) -> str:
        key = f'c{len(self.namespace)}'
        self.namespace[key] = value
        return key

    def align(self, size: int, indent: str) -> None:
        # Offsets count from the end of the 4-byte encapsulation header.
        if size > 1:
            self.lines.append(f'{indent}out += PADDING[(4 - len(out)) & {size - 1}]')

    def flush(self, indent: str) -> None:
        """Emit one pack of the pending scalars, with the padding of each start alignment."""
        if not self.scalars:
            return
        formats = []
        for start in range(8):
            position, layout = start, '<'
            for type_name, _ in self.scalars:
                size = _scalar_size(type_name)
                padding = -position % size
                layout += f'{padding}x' * bool(padding) + _SCALAR_FORMATS[type_name]
                position += padding + size
            formats.append(struct.Struct(layout).pack)
        packs = self.name(tuple(formats))
        values = ', '.join(expression for _, expression in self.scalars)
        self.lines.append(f'{indent}out += {packs}[(len(out) - 4) & 7]({values})')
        self.scalars = []

    def message(self, typename: str, expression: str, indent: str) -> None:
        if typename not in self.fielddefs:
            raise TypeError(f"message type '{typename}' is not in the rosbags type store")
        for field_name, desc in self.fielddefs[typename][1]:
            if field_name == EMPTY_MESSAGE_PLACEHOLDER:
                self.scalars.append(('uint8', '0'))
            else:
                self.field(desc, f'{expression}.{field_name}', indent)

    def field(self, desc: tuple, expression: str, indent: str) -> None:
        kind, detail = desc
        if kind == Nodetype.NAME:
            # A local per sub-message: each attribute is read once (rosidl's are properties).
            local = f'm{len(self.lines)}'
            self.lines.append(f'{indent}{local} = {expression}')
            self.message(detail, local, indent)
        elif kind == Nodetype.BASE and detail[0] == 'byte':
            self.scalars.append((detail[0], f'byte_value({expression})'))
        elif kind == Nodetype.BASE and detail[0] != 'string':
            self.scalars.append((detail[0], expression))
        else:
            self.flush(indent)
            if kind == Nodetype.BASE:
                self.string(expression, indent)
            else:
                self.collection(kind, detail, expression, indent)

    def string(self, expression: str, indent: str) -> None:
        self.align(4, indent)
        self.lines += [f'{indent}text = {expression}.encode()',
                       f'{indent}out += pack_uint32(len(text) + 1)',
                       f"{indent}out += text + b'\\x00'"]

    def collection(self, kind: Nodetype, detail: tuple, expression: str, indent: str) -> None:
        element, length = detail
        self.lines.append(f'{indent}items = {expression}')
        if kind == Nodetype.SEQUENCE:
            self.align(4, indent)
            self.lines.append(f'{indent}out += pack_uint32(len(items))')
        else:
            self.lines += [f'{indent}if len(items) != {length}:',
                           f"{indent}  raise ValueError('{expression[4:]}: expected {length} "
                           "items, got %d' % len(items))"]
        if element[0] == Nodetype.BASE and element[1][0] != 'string':
            size = _scalar_size(element[1][0])
            dtype = self.name(np.dtype(_NUMPY_TYPES[element[1][0]]).newbyteorder('<'))
            self.lines.append(f'{indent}if len(items):')
            self.align(size, indent + '  ')
            self.lines.append(f'{indent}  out += numeric_bytes(items, {dtype})')
            return
        self.lines.append(f'{indent}for item in items:')
        if element[0] == Nodetype.NAME:
            nested = self.name(self.serializer.function(element[1]))
            self.lines.append(f'{indent}  {nested}(item, out)')
        else:
            self.string('item', indent + '  ')


def _remove_old_bag(path: Path) -> None:
    """Delete a previous bag folder at ``path``; refuse anything else that is there."""
    if not path.is_dir() or any(
            item.is_dir() or not (item.name == 'metadata.yaml' or item.suffix == '.mcap')
            for item in path.iterdir()):
        raise FileExistsError(f'{path} exists and is not a rosbag2 bag; not overwriting it')
    shutil.rmtree(path)


_MCAP_MESSAGE_HEADER = struct.Struct('<BQHIQQ')
_MCAP_MESSAGE_OPCODE = 0x05
_MCAP_MESSAGE_FIXED_SIZE = 22
_MCAP_CHUNK_SIZE = 1 << 20


class _LeanMcapWriter(McapWriter):
    """rosbags' MCAP storage with a message write that packs its record header in one call."""

    def write(self, connection: Any, timestamp: int, data: bytes | memoryview) -> None:
        # Comparisons rather than min()/max(): this runs for every message of a run.
        chunk = self.chunk
        if timestamp < chunk.message_start_time:
            chunk.message_start_time = timestamp
        if timestamp > chunk.message_end_time:
            chunk.message_end_time = timestamp
        if timestamp < self.message_start_time:
            self.message_start_time = timestamp
        if timestamp > self.message_end_time:
            self.message_end_time = timestamp
        self.channel_stats[connection.id] += 1
        bio = chunk.bio
        chunk.msgs[connection.id].append((timestamp, bio.tell()))
        bio.write(_MCAP_MESSAGE_HEADER.pack(
            _MCAP_MESSAGE_OPCODE, _MCAP_MESSAGE_FIXED_SIZE + len(data), connection.id, 0,
            timestamp, timestamp))
        bio.write(data)
        if bio.tell() > _MCAP_CHUNK_SIZE:
            self.close_chunk()


class _BagWriter(Writer):
    """
    rosbags' bag writer with the lean MCAP storage and no per-message connection lookup.

    The recorder only writes to connections it created and never compresses, the two things
    ``Writer.write`` checks on every message.
    """

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _LeanMcapWriter}

    def write(self, connection: Any, timestamp: int, data: bytes | memoryview) -> None:
        self.storage.write(connection, timestamp, data)
        self.counts[connection.id] += 1
        if timestamp < self.min_timestamp:
            self.min_timestamp = timestamp
        if timestamp > self.max_timestamp:
            self.max_timestamp = timestamp


class BagRecorder:
    """
    Write messages of the chosen topics into a new rosbag2 bag with MCAP storage.

    ``path`` is the bag folder; the MCAP file inside is ``<folder name>.mcap``. Connections are
    created on each topic's first message from the message's type. Use it as a context
    manager: the bag is closed (index and metadata written, so it stays readable) even when the
    run fails half-way.
    """

    def __init__(self, path: str | os.PathLike, topics: Iterable[str] = DEFAULT_TOPICS, *,
                 overwrite: bool = False, qos: Mapping[str, Qos] | None = None,
                 typestore: Typestore | None = None) -> None:
        self.path = Path(path)
        self.topics = frozenset(_absolute(topic) for topic in topics)
        self.qos = dict(DEFAULT_QOS if qos is None else qos)
        self.typestore = typestore or get_typestore(Stores.ROS2_JAZZY)
        self.serializer = CdrSerializer(self.typestore)
        if overwrite and self.path.exists():
            _remove_old_bag(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = _BagWriter(self.path, version=BAG_VERSION,
                                  storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections: dict[tuple[str, type], tuple[Any, Callable | None]] = {}
        # The writer's own tallies, still readable once it is closed.
        self._writer_connections = self._writer.connections
        self._writer_counts = self._writer.counts

    @property
    def mcap_path(self) -> Path:
        """Return the path of the MCAP file inside the bag folder."""
        return self.path / f'{self.path.name}.mcap'

    @property
    def closed(self) -> bool:
        """Return True once the bag is closed."""
        return self._writer is None

    def write(self, topic: str, msg: Any, t_ns: int) -> None:
        """
        Record ``msg`` published on ``topic`` at sim time ``t_ns`` (ns) if the topic is kept.

        Fits the lockstep runtime's tap signature ``fn(topic, msg, t_ns)``.
        """
        if self._writer is None:
            raise RuntimeError(f'bag {self.path} is closed')
        key = (topic, type(msg))
        entry = self._connections.get(key)
        if entry is None:
            if _absolute(topic) not in self.topics:
                self._connections[key] = entry = (None, None)
            else:
                entry = self._connections[key] = self._connect(_absolute(topic), msg)
        connection, serialize = entry
        if connection is None:
            return
        self._writer.write(connection, t_ns, serialize(msg, bytearray(CDR_LITTLE_ENDIAN_HEADER)))

    @property
    def counts(self) -> dict[str, int]:
        """Return the number of messages recorded per topic."""
        counts: dict[str, int] = {}
        for connection in self._writer_connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + \
                self._writer_counts[connection.id]
        return counts

    def _connect(self, topic: str, msg: Any) -> tuple[Any, Callable]:
        typename = ros_type_name(msg)
        connection = self._writer.add_connection(
            topic, typename, typestore=self.typestore,
            offered_qos_profiles=[self.qos.get(topic, offered_qos())])
        return connection, self.serializer.function(typename)

    def close(self) -> None:
        """Finish the bag: write the MCAP index and ``metadata.yaml``. Safe to call twice."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()

    def __enter__(self) -> 'BagRecorder':
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic
