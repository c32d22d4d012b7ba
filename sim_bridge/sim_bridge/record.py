"""
Record a run's topics as a rosbag2 bag (MCAP storage) for ROS 2 tools, rosbags and Foxglove.

:class:`BagRecorder` takes messages as the lockstep runtime publishes them (its rclpy-faithful
message objects, or rosbags messages), serialises them to CDR by the field definitions of the
rosbags ROS2_JAZZY type store and appends them to ``<bag>/<bag name>.mcap`` with rosbags'
writer. ``metadata.yaml`` is written on close, with the offered QoS profiles ``ros2 bag record``
would store, so ``ros2 bag play`` re-publishes each topic with a compatible profile
(``/tf_static`` latched).

A 600 s run publishes some 130 000 messages, so the per-message path is kept short: a generated
function per type and topic (no conversion to rosbags objects first; the runtime's messages read
through their slots) appends the message's whole MCAP record, header and CDR bytes, straight to
the open chunk's buffer, and the chunk is written as it is when it closes. The bytes are those
of rosbags' serialiser and writer (the tests compare them).
"""

from collections.abc import Callable, Iterable, Mapping
import functools
from io import BytesIO
import os
from pathlib import Path
import shutil
import struct
import sys
from types import TracebackType
from typing import Any

import numpy as np
from rosbags.interfaces import (Connection, Nodetype, Qos, QosDurability, QosHistory,
                                QosLiveliness, QosReliability, QosTime)
from rosbags.rosbag2 import CompressionMode, StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import get_typestore, Stores
from rosbags.typesys.store import Typestore

from sim_bridge.lockstep.messages import LockstepMessage

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
    generated per type: runs of scalar fields, string lengths, sequence counts and the padding
    between them are packed by one precompiled ``struct`` format each (the first run with the
    encapsulation header, so a message of scalars only is one call), arrays copied as buffers,
    nested messages and sequence elements inlined. The bytes (a ``bytes`` or ``bytearray``)
    equal ``typestore.serialize_cdr`` of the same message (the tests compare them).

    For a recording, a function of the same code can instead append a whole MCAP message record
    (its header, then the CDR bytes) to a chunk's buffer: see :meth:`function`.
    """

    def __init__(self, typestore: Typestore) -> None:
        self.typestore = typestore
        self._functions: dict[tuple[str, bool, int | None], Callable] = {}
        self._by_class: dict[type, Callable[[Any], bytes | bytearray]] = {}

    def serialize(self, msg: Any, typename: str | None = None) -> bytes | bytearray:
        """Return the CDR bytes (with the 4-byte encapsulation header) of ``msg``."""
        if typename is not None:
            return self.function(typename, slots=isinstance(msg, LockstepMessage))(msg)
        function = self._by_class.get(type(msg))
        if function is None:
            function = self._by_class[type(msg)] = self.function(
                ros_type_name(msg), slots=isinstance(msg, LockstepMessage))
        return function(msg)

    def function(self, typename: str, *, slots: bool = False,
                 mcap_channel: int | None = None) -> Callable:
        """
        Return the function serialising a ``typename`` message to CDR bytes, header first.

        With ``slots`` it is for the lockstep runtime's messages: it reads their slots
        (``msg._x``, cheaper than the ``x`` property) and copies numeric arrays as the runtime
        keeps them (numpy arrays, ``array.array``) without conversion; a message holding
        anything else (say a rosbags sub-message) is serialised by the function reading public
        names instead.

        With ``mcap_channel`` (an MCAP channel id) the function is ``write(msg, out, t_ns)``
        instead: it appends to the bytearray ``out`` the MCAP message record of ``msg`` on that
        channel at log and publish time ``t_ns`` (ns), sequence 0, as rosbags' MCAP writer
        writes it (the record header, then the CDR bytes), and returns None. If it raises,
        ``out`` is left as it was.
        """
        key = (typename, slots, mcap_channel)
        if key not in self._functions:
            fallback = self.function(typename, mcap_channel=mcap_channel) if slots else None
            self._functions[key] = _CdrCodegen(self.typestore.fielddefs, slots,
                                               mcap_channel).build(typename, fallback)
        return self._functions[key]


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
    """
    Writes the Python source of one type's serialiser (see :class:`CdrSerializer`).

    Scalars wait in ``run`` as ``(struct code, alignment, value expression)`` until something
    of variable size (a string's bytes, an array) or a loop needs the output up to there; the
    run is then packed in one call. A string's terminating NUL and the padding before an array
    are entries of a run too (code ``'x'`` and ``''``, no value). ``offset`` is the output's
    offset modulo 8 (from the end of the encapsulation header) where the code can know it: a
    run starting there packs by one format, elsewhere by one of eight per start alignment,
    chosen by the output's length past ``base`` (the CDR payload's start in ``out``). The first
    run is packed with the encapsulation header and starts the output, so a message of scalars
    only is one ``pack`` call (returning ``bytes``).

    With an MCAP channel id the function appends to a shared bytearray ``out`` instead, the
    MCAP message record header packed with the first run; the record's length is then a
    constant when the first run is all the message (its size is fixed), else patched at the
    end.
    """

    def __init__(self, fielddefs: dict, slots: bool, mcap_channel: int | None = None) -> None:
        self.fielddefs = fielddefs
        self.prefix = '_' if slots else ''
        # The runtime's numeric arrays are in native byte order; CDR here is little-endian.
        self.raw_arrays = slots and sys.byteorder == 'little'
        self.namespace: dict[str, Any] = {
            'HEADER': CDR_LITTLE_ENDIAN_HEADER, 'PADDING': _PADDING,
            'numeric_bytes': _numeric_bytes, 'byte_value': _byte_value}
        self.mcap_channel = mcap_channel
        # Where the CDR payload starts in ``out``: a constant, or the local ``base``.
        self.base = '4' if mcap_channel is None else 'base'
        self.lines: list[str] = []
        self.run: list[tuple[str, int, str | None]] = []
        self.offset: int | None = 0
        # Once written: the line number of the first pack, its expression and its size (bytes).
        self.opening: tuple[int, str, int] | None = None

    def build(self, typename: str, fallback: Callable | None) -> Callable:
        if self.mcap_channel is None:
            function, arguments = 'serialize', 'msg'
            self.lines = ['def serialize(msg):']
        else:
            function, arguments = 'write', 'msg, out, t_ns'
            self.lines = ['def write(msg, out, t_ns):', '  start = len(out)',
                          f'  base = start + {_MCAP_MESSAGE_OVERHEAD + 4}']
            self.namespace.update(OPCODE=_MCAP_MESSAGE_OPCODE, CHANNEL=self.mcap_channel,
                                  pack_length=_pack_into_uint64)
        indent = '  '
        if fallback is not None or self.mcap_channel is not None:
            self.lines.append('  try:')
            indent = '    '
        self.message(typename, 'msg', indent)
        self.flush(indent)
        line, expression, size = self.opening
        fixed = line == len(self.lines) - 1  # nothing after the first run
        if self.mcap_channel is not None:
            # The record length counts the bytes after the opcode and the length itself.
            self.namespace['LENGTH'] = size - 9 if fixed else 0
            if not fixed:
                self.lines.append(f'{indent}pack_length(out, start + 1, len(out) - start - 9)')
        elif fixed:  # return the first run's bytes
            self.lines[line] = f'{indent}return {expression}'
        else:
            self.lines.append(f'{indent}return out')
        if fallback is not None:
            # An AttributeError or TypeError: not the runtime's own objects all the way down.
            self.namespace['fallback'] = fallback
            self.lines.append('  except (AttributeError, TypeError):')
            if self.mcap_channel is not None:
                self.lines.append('    del out[start:]')
            self.lines.append(f'    return fallback({arguments})')
        if self.mcap_channel is not None:  # leave no partial record in the shared buffer
            self.lines += ['  except BaseException:', '    del out[start:]', '    raise']
        exec(compile('\n'.join(self.lines), f'<cdr {typename}>', 'exec'), self.namespace)
        return self.namespace[function]

    def name(self, value: Any) -> str:
        key = f'c{len(self.namespace)}'
        self.namespace[key] = value
        return key

    def local(self, letter: str) -> str:
        """Return a new local variable name (numbered by the line that will assign it)."""
        return f'{letter}{len(self.lines)}'

    def flush(self, indent: str) -> None:
        """Emit one pack of the pending run (the first, with the header, starts the output)."""
        if not self.run:
            if self.opening is None:  # an array of strings first, say: a loop follows
                self.start_output('', '', indent)
            return
        layouts = []
        for start in range(8):
            position, layout = start, '<'
            for code, alignment, _ in self.run:
                padding = -position % alignment
                layout += f'{padding}x' * bool(padding) + code
                position += padding + struct.calcsize('<' + code)
            layouts.append(layout)
        values = ', '.join(value for _, _, value in self.run if value is not None)
        self.run = []
        starts = range(8) if self.offset is None else [self.offset]
        ends = {(start + struct.calcsize(layouts[start])) % 8 for start in starts}
        self.offset = ends.pop() if len(ends) == 1 else None
        if self.opening is None:  # the first run, at offset 0: the header is packed before it
            self.start_output(layouts[0][1:], values, indent)
            return
        if len({layouts[start] for start in starts}) == 1:
            choice = self.name(self.packer(layouts[starts[0]], values))
        else:
            choice = f'{self.name(tuple(self.packer(layout, values) for layout in layouts))}' \
                f'[(len(out) - {self.base}) & 7]'
        self.lines.append(f'{indent}out += {choice}' + f'({values})' * bool(values))

    def start_output(self, layout: str, values: str, indent: str) -> None:
        """
        Emit the first pack: the encapsulation header, then the run of ``layout`` (struct codes).

        Without an MCAP channel it creates ``out``; with one, it appends the MCAP message
        record header and all that to ``out``.
        """
        if self.mcap_channel is None:
            lead, lead_values = '<4s', 'HEADER'
        else:  # opcode, record length, channel id, sequence, log time, publish time (ns)
            lead, lead_values = '<BQHIQQ4s', 'OPCODE, LENGTH, CHANNEL, 0, t_ns, t_ns, HEADER'
        packer = struct.Struct(lead + layout)
        expression = f'{self.name(packer.pack)}({lead_values}' + f', {values}' * bool(values) + ')'
        self.opening = (len(self.lines), expression, packer.size)
        if self.mcap_channel is None:
            self.lines.append(f'{indent}out = bytearray({expression})')
        else:
            self.lines.append(f'{indent}out += {expression}')

    @staticmethod
    def packer(layout: str, values: str) -> Callable | bytes:
        """Return the pack function of ``layout``, or its bytes (all padding) without values."""
        return struct.Struct(layout).pack if values else bytes(struct.calcsize(layout))

    def message(self, typename: str, expression: str, indent: str) -> None:
        if typename not in self.fielddefs:
            raise TypeError(f"message type '{typename}' is not in the rosbags type store")
        for field_name, desc in self.fielddefs[typename][1]:
            if field_name == EMPTY_MESSAGE_PLACEHOLDER:
                self.run.append(('x', 1, None))  # a uint8 0
            else:
                self.field(desc, f'{expression}.{self.prefix}{field_name}', field_name, indent)

    def field(self, desc: tuple, expression: str, field_name: str, indent: str) -> None:
        kind, detail = desc
        if kind == Nodetype.NAME:
            # A local per sub-message: each attribute is read once (rosidl's are properties).
            local = self.local('m')
            self.lines.append(f'{indent}{local} = {expression}')
            self.message(detail, local, indent)
        elif kind == Nodetype.BASE and detail[0] == 'string':
            self.string(expression, indent)
        elif kind == Nodetype.BASE:
            value = f'byte_value({expression})' if detail[0] == 'byte' else expression
            self.run.append((_SCALAR_FORMATS[detail[0]], _scalar_size(detail[0]), value))
        else:
            self.collection(kind, detail, expression, field_name, indent)

    def string(self, expression: str, indent: str) -> None:
        text = self.local('t')
        self.lines.append(f'{indent}{text} = {expression}.encode()')
        self.run.append(('I', 4, f'len({text}) + 1'))
        self.flush(indent)
        self.lines.append(f'{indent}out += {text}')
        self.run.append(('x', 1, None))
        self.offset = None

    def collection(self, kind: Nodetype, detail: tuple, expression: str, field_name: str,
                   indent: str) -> None:
        element, length = detail
        items = self.local('s')
        self.lines.append(f'{indent}{items} = {expression}')
        if kind == Nodetype.SEQUENCE:
            self.run.append(('I', 4, f'len({items})'))
        else:
            self.lines += [f'{indent}if len({items}) != {length}:',
                           f"{indent}  raise ValueError('{field_name}: "
                           f"expected {length} items, got %d' % len({items}))"]
        if element[0] == Nodetype.BASE and element[1][0] != 'string':
            self.numeric(kind, element[1][0], length, items, indent)
            return
        self.flush(indent)
        item = self.local('e')
        self.lines.append(f'{indent}for {item} in {items}:')
        self.offset = None  # where the previous item ended
        if element[0] == Nodetype.NAME:
            self.message(element[1], item, indent + '  ')
        else:
            self.string(item, indent + '  ')
        self.flush(indent + '  ')
        self.offset = None

    def numeric(self, kind: Nodetype, type_name: str, length: int, items: str,
                indent: str) -> None:
        """Emit the copy of an array or sequence of numbers (bools and bytes included)."""
        size = _scalar_size(type_name)
        if self.raw_arrays and type_name not in ('bool', 'byte'):
            # The runtime keeps these as numpy arrays / array.array of the field's type.
            data = f'{items}.tobytes()' if kind == Nodetype.ARRAY else items
        else:
            dtype = self.name(np.dtype(_NUMPY_TYPES[type_name]).newbyteorder('<'))
            data = f'numeric_bytes({items}, {dtype})'
        if kind == Nodetype.ARRAY:
            self.run.append(('', size, None))
            self.flush(indent)
            self.lines.append(f'{indent}out += {data}')
            self.offset = None if self.offset is None else (self.offset + length * size) % 8
        elif size > 4:
            # After the count the output is 4-aligned; wider items pad, but only if there are any.
            self.flush(indent)
            self.lines += [f'{indent}if len({items}):',
                           f'{indent}  out += PADDING[({self.base} - len(out)) & {size - 1}]',
                           f'{indent}  out += {data}']
            self.offset = None
        else:
            self.flush(indent)
            self.lines.append(f'{indent}out += {data}')
            self.offset = None


def _remove_old_bag(path: Path) -> None:
    """Delete a previous bag folder at ``path``; refuse anything else that is there."""
    if not path.is_dir() or any(
            item.is_dir() or not (item.name == 'metadata.yaml' or item.suffix == '.mcap')
            for item in path.iterdir()):
        raise FileExistsError(f'{path} exists and is not a rosbag2 bag; not overwriting it')
    shutil.rmtree(path)


# An MCAP message record up to its data: opcode, length, channel id, sequence, log, publish time.
_pack_message_header = struct.Struct('<BQHIQQ').pack
_MCAP_MESSAGE_OPCODE = 0x05
_MCAP_MESSAGE_OVERHEAD = 31  # bytes of a message record beyond the message data
_MCAP_CHUNK_SIZE = 1 << 20  # McapWriter closes a chunk after the message that passes this
_MCAP_EMPTY_CHUNK_TIMES = (2 ** 63 - 1, 0)  # McapWriter's times of a chunk without messages
# Chunk record up to its data: opcode, length, start, end, uncompressed size, CRC (0: none).
_pack_chunk_head = struct.Struct('<BQQQQI').pack
# Message index record up to its entries: opcode, length, channel id, entry bytes.
_pack_message_index_head = struct.Struct('<BQHI').pack
_pack_uint32 = struct.Struct('<I').pack
_pack_uint64 = struct.Struct('<Q').pack
_pack_into_uint64 = struct.Struct('<Q').pack_into


class _LeanMcapWriter(McapWriter):
    """
    rosbags' MCAP storage, writing each message's record straight into the open chunk's buffer.

    :meth:`message_writer` gives a function per channel that appends a message's whole record
    (header and CDR bytes, see :meth:`CdrSerializer.function`) to ``records`` and notes its
    message index entry; the chunk is written once its records pass 1 MiB, as McapWriter does.
    Schema and channel records, which rosbags writes into its own pending chunk, are moved to
    ``records`` in their place between the messages. The file is byte for byte McapWriter's
    (the tests compare them).
    """

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        super().__init__(path, compression)
        self.records = bytearray()  # the open chunk's records, uncompressed
        # The open chunk's message index entries per channel id: time (ns), offset (bytes in
        # the chunk's records) for each message in turn.
        self._entries: dict[int, list[int]] = {}
        self._indexed: list[int] = []  # the open chunk's channel ids, by their first message

    def add_msgtype(self, connection: Connection) -> None:
        super().add_msgtype(connection)
        self._take_records()

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        super().add_connection(connection, offered_qos_profiles)
        self._take_records()
        self._entries[connection.id] = []

    def _take_records(self) -> None:
        """Move what rosbags wrote into its pending chunk to the open chunk's records."""
        self.records += self.chunk.bio.getvalue()
        self.chunk.bio = BytesIO()

    def message_writer(self, connection: Connection,
                       write_record: Callable[[Any, bytearray, int], None],
                       ) -> Callable[[Any, int], None]:
        """
        Return ``write(msg, t_ns)``, which adds a message at ``t_ns`` (ns) on ``connection``.

        ``write_record(msg, records, t_ns)`` appends the message's MCAP record to ``records``
        (as :meth:`CdrSerializer.function` with the connection's id as MCAP channel does), or
        raises and leaves them as they were. The chunk closes after the message that takes it
        over 1 MiB.
        """
        records, indexed, close_chunk = self.records, self._indexed, self.close_chunk
        channel = connection.id
        entries = self._entries[channel]
        add_entry = entries.extend

        def write(msg: Any, t_ns: int) -> None:
            start = len(records)
            write_record(msg, records, t_ns)
            if not entries:
                indexed.append(channel)
            add_entry((t_ns, start))
            if len(records) > _MCAP_CHUNK_SIZE:
                close_chunk()

        return write

    def write(self, connection: Connection, timestamp: int, data: bytes | bytearray) -> None:
        """Add a message of CDR bytes ``data`` at ``timestamp`` (ns): McapWriter's interface."""
        def write_record(_: None, records: bytearray, t_ns: int) -> None:
            records += _pack_message_header(_MCAP_MESSAGE_OPCODE,
                                            _MCAP_MESSAGE_OVERHEAD - 9 + len(data),
                                            connection.id, 0, t_ns, t_ns)
            records += data

        self.message_writer(connection, write_record)(None, timestamp)

    def message_counts(self) -> dict[int, int]:
        """Return the number of messages written per channel id, the open chunk's included."""
        counts = dict(self.channel_stats)
        for channel, entries in self._entries.items():
            counts[channel] += len(entries) // 2
        return counts

    def close_pending_chunk(self) -> None:
        """Close the open chunk if it holds anything."""
        if self.records:
            self.close_chunk()

    def close_chunk(self) -> None:
        """Write the open chunk and its message index; keep its chunk index for the summary."""
        records, indexed = self.records, self._indexed
        if indexed:
            times = [self._entries[channel][0::2] for channel in indexed]
            start, end = min(map(min, times)), max(map(max, times))
        else:
            start, end = _MCAP_EMPTY_CHUNK_TIMES
        self.message_start_time = min(self.message_start_time, start)
        self.message_end_time = max(self.message_end_time, end)
        compressed = self.compressor(records)
        compression = self.compression.encode()
        chunk_start = self.bio.tell()
        self.bio.write(_pack_chunk_head(
            0x06, 40 + len(compression) + len(compressed), start, end, len(records), 0))
        self.bio.write(_pack_uint32(len(compression)) + compression)
        self.bio.write(_pack_uint64(len(compressed)))
        self.bio.write(compressed)
        chunk_end = self.bio.tell()

        # The message index: each channel's (time, offset) entries in message order, channels in
        # the order of their first message in the chunk (McapWriter's order of index records).
        index = BytesIO()
        index.write(struct.pack('<QQQQI', start, end, chunk_start, chunk_end - chunk_start,
                                10 * len(indexed)))
        for channel in indexed:
            entries = self._entries[channel]
            index.write(struct.pack('<HQ', channel, self.bio.tell()))
            self.bio.write(_pack_message_index_head(0x07, 6 + 8 * len(entries), channel,
                                                    8 * len(entries)))
            self.bio.write(np.array(entries, '<u8').tobytes())
            self.channel_stats[channel] += len(entries) // 2
            entries.clear()
        index.write(_pack_uint64(self.bio.tell() - chunk_end))
        index.write(_pack_uint32(len(compression)) + compression)
        index.write(struct.pack('<QQ', len(compressed), len(records)))
        self.chunks.append(index)
        indexed.clear()
        records.clear()

    def close(self, version: int, metadata: str) -> None:
        self.close_pending_chunk()
        super().close(version, metadata)


class _BagWriter(Writer):
    """
    rosbags' bag writer with the lean MCAP storage, to which the recorder hands its messages.

    The recorder only writes to connections it created and never compresses, the two things
    ``Writer.write`` checks on every message, so it skips ``Writer.write``; on close the writer
    takes the message counts and time range for ``metadata.yaml`` from the storage instead.
    """

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _LeanMcapWriter}

    def close(self) -> None:
        storage = self.storage
        storage.close_pending_chunk()
        self.counts.update(storage.message_counts())
        self.min_timestamp = storage.message_start_time
        self.max_timestamp = storage.message_end_time
        super().close()


@functools.cache
def _jazzy_serializer() -> CdrSerializer:
    """Return the serialiser of the ROS2_JAZZY type store that recorders share."""
    return CdrSerializer(get_typestore(Stores.ROS2_JAZZY))


class BagRecorder:
    """
    Write messages of the chosen topics into a new rosbag2 bag with MCAP storage.

    ``path`` is the bag folder; the MCAP file inside is ``<folder name>.mcap``. Connections are
    created on each topic's first message of a type. Use it as a context manager: the bag is
    closed (index and metadata written, so it stays readable) even when the run fails half-way.
    """

    def __init__(self, path: str | os.PathLike, topics: Iterable[str] = DEFAULT_TOPICS, *,
                 overwrite: bool = False, qos: Mapping[str, Qos] | None = None,
                 typestore: Typestore | None = None) -> None:
        self.path = Path(path)
        self.topics = frozenset(_absolute(topic) for topic in topics)
        self.qos = dict(DEFAULT_QOS if qos is None else qos)
        self.serializer = _jazzy_serializer() if typestore is None else CdrSerializer(typestore)
        self.typestore = self.serializer.typestore
        if overwrite and self.path.exists():
            _remove_old_bag(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = _BagWriter(self.path, version=BAG_VERSION,
                                  storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._storage = self._writer.storage
        self._writer_connections = self._writer.connections  # still readable once closed
        self._connections: dict[tuple[str, str], Connection] = {}  # by topic and type name
        # What write does per topic (as published) and message class: the storage's writer
        # ``(msg, t_ns)`` of the topic's connection, or a no-op for topics not recorded.
        self._routes: dict[tuple[str, type], Callable[[Any, int], None]] = {}

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
        if t_ns.__class__ is not int or t_ns < 0:
            raise ValueError(f'bag {self.path}: a message time must be a non-negative int '
                             f'(ns), got {t_ns!r} on {topic}')
        route = self._routes.get((topic, type(msg)))
        if route is None:
            route = self._route(topic, msg)
        route(msg, t_ns)

    @property
    def counts(self) -> dict[str, int]:
        """Return the number of messages recorded per topic."""
        per_channel = self._storage.message_counts()
        counts: dict[str, int] = {}
        for connection in self._writer_connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + \
                per_channel[connection.id]
        return counts

    def _route(self, topic: str, msg: Any) -> Callable[[Any, int], None]:
        """Return (and keep) what ``write`` does with messages like ``msg`` on ``topic``."""
        if self._writer is None:
            raise RuntimeError(f'bag {self.path} is closed')
        name = _absolute(topic)
        route = _skip
        if name in self.topics:
            typename = ros_type_name(msg)
            connection = self._connection(name, typename)
            route = self._storage.message_writer(connection, self.serializer.function(
                typename, slots=isinstance(msg, LockstepMessage), mcap_channel=connection.id))
        self._routes[(topic, type(msg))] = route
        return route

    def _connection(self, topic: str, typename: str) -> Connection:
        key = (topic, typename)
        if key not in self._connections:
            self._connections[key] = self._writer.add_connection(
                topic, typename, typestore=self.typestore,
                offered_qos_profiles=[self.qos.get(topic, offered_qos())])
        return self._connections[key]

    def close(self) -> None:
        """Finish the bag: write the MCAP index and ``metadata.yaml``. Safe to call twice."""
        writer, self._writer = self._writer, None
        if writer is not None:
            self._routes.clear()  # so that write finds the bag closed
            writer.close()

    def __enter__(self) -> 'BagRecorder':
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()


def _skip(msg: Any, t_ns: int) -> None:
    """Record nothing: what :meth:`BagRecorder.write` does on a topic not recorded."""


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic
