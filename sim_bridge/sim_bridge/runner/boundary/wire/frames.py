"""
The frames a run's trusted side and its node agent (boundary.inside.agent) exchange over a pipe.

Data only, never code: no pickle, no eval. A frame is an 8-byte prefix (the lengths of its
header and of its payload, big-endian), a header of UTF-8 JSON (an object with a ``kind`` and
small fields: numbers, strings, lists of them) and a payload, the CDR bytes of the ROS messages
the header lists as ``[topic, type name, size]``, one after the other::

    >II | {"kind": "idle", "wake_ns": 1200000000, "messages": [["/cmd_vel",
    "geometry_msgs/msg/Twist", 52]]} | <52 bytes of CDR>

The decoder (:class:`FrameDecoder`) is fed bytes as they come and bounds everything it reads:
header and payload sizes, the count of messages, topic and type names by regular expression.
Whatever it cannot read is a :class:`FrameError` with a one-line reason; the side that reads it
ends the exchange there (for the trusted side: that run fails, nothing else).
"""

from dataclasses import dataclass, field
import json
import re
import struct
from typing import Any, Iterable, NamedTuple

#: The prefix: header length, payload length (bytes).
PREFIX = struct.Struct('>II')
MAX_HEADER_BYTES = 2 ** 20
MAX_PAYLOAD_BYTES = 64 * 2 ** 20
MAX_MESSAGES = 10_000
#: A ROS topic's resolved name (absolute, '/'-separated tokens; no '~' or '{}' left).
TOPIC_NAME = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]*)+')
MAX_TOPIC_CHARS = 256
#: A message type as ROS names it: package/msg/Type.
TYPE_NAME = re.compile(r'[a-z][a-z0-9_]*/msg/[A-Z][A-Za-z0-9]*')


#: The frames a node process (sim_bridge.runner.boundary.inside.agent) sends, and those the
#: trusted side sends it.
AGENT_KINDS = ('hello', 'sync', 'idle', 'stuck', 'ended')
TRUSTED_KINDS = ('advance', 'ack', 'stop')


class FrameError(ValueError):
    """Bytes that are not a frame of this protocol; the text says why, in one line."""


class Message(NamedTuple):
    """One ROS message crossing the boundary: topic, type name and its CDR bytes."""

    topic: str
    type_name: str
    data: bytes


@dataclass
class Frame:
    """A decoded frame: its ``kind``, its other header ``fields`` and its ``messages``."""

    kind: str
    fields: dict = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)

    def integer(self, name: str, optional: bool = False, low: int = 0,
                high: int = 2 ** 63 - 1) -> int | None:
        """Return the field ``name`` as an int in [low, high]; FrameError if it is not one."""
        value = self.fields.get(name)
        if value is None and optional:
            return None
        if type(value) is not int or not low <= value <= high:
            raise FrameError(f'{self.kind} frame: {name} must be an integer in [{low}, {high}]')
        return value

    def text(self, name: str, max_chars: int = 256, default: str | None = None) -> str:
        """Return the field ``name`` as a string of at most ``max_chars``; FrameError if not."""
        value = self.fields.get(name, default)
        if not isinstance(value, str) or len(value) > max_chars:
            raise FrameError(f'{self.kind} frame: {name} must be a string of at most '
                             f'{max_chars} characters')
        return value


def valid_topic(topic: Any) -> bool:
    """Tell whether ``topic`` is a resolved ROS topic name of sane length."""
    return (isinstance(topic, str) and len(topic) <= MAX_TOPIC_CHARS
            and TOPIC_NAME.fullmatch(topic) is not None)


def valid_type(type_name: Any) -> bool:
    """Tell whether ``type_name`` reads as a ROS message type name (package/msg/Type)."""
    return (isinstance(type_name, str) and len(type_name) <= MAX_TOPIC_CHARS
            and TYPE_NAME.fullmatch(type_name) is not None)


def type_name(msg_type: type) -> str:
    """Return the ROS name of a message class: ``geometry_msgs/msg/Twist``."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def encode(kind: str, messages: Iterable[Message] = (), **fields: Any) -> bytes:
    """Return the bytes of a frame of ``kind`` with ``fields`` and ``messages``."""
    messages = list(messages)
    header = json.dumps({'kind': kind, **fields,
                         'messages': [[m.topic, m.type_name, len(m.data)] for m in messages]},
                        separators=(',', ':')).encode()
    payload = b''.join(m.data for m in messages)
    return PREFIX.pack(len(header), len(payload)) + header + payload


def _header(data: bytes) -> dict:
    try:
        header = json.loads(data.decode('utf-8'))
    except (UnicodeDecodeError, ValueError, RecursionError) as error:
        raise FrameError(f'frame header is not JSON ({type(error).__name__})') from None
    if not isinstance(header, dict) or not isinstance(header.get('kind'), str):
        raise FrameError('frame header is not an object with a kind')
    return header


def _messages(listed: Any, payload: bytes) -> list[Message]:
    if not isinstance(listed, list) or len(listed) > MAX_MESSAGES:
        raise FrameError(f'frame messages must be a list of at most {MAX_MESSAGES}')
    messages, offset = [], 0
    for entry in listed:
        if not (isinstance(entry, list) and len(entry) == 3):
            raise FrameError('a frame message must be [topic, type, size]')
        topic, type_name, size = entry
        if not valid_topic(topic):
            raise FrameError(f'bad topic name in frame: {str(topic)[:80]!r}')
        if not valid_type(type_name):
            raise FrameError(f'bad message type name in frame: {str(type_name)[:80]!r}')
        if type(size) is not int or size < 0 or offset + size > len(payload):
            raise FrameError(f'bad message size in frame for {topic}')
        messages.append(Message(topic, type_name, payload[offset:offset + size]))
        offset += size
    if offset != len(payload):
        raise FrameError('frame payload is longer than its messages')
    return messages


class FrameDecoder:
    """
    Cut the bytes of a stream into frames, whatever chunks they arrive in.

    ``kinds`` are the frame kinds this side accepts; any other is a FrameError.
    """

    def __init__(self, kinds: Iterable[str]):
        self.kinds = frozenset(kinds)
        self.buffer = bytearray()

    def feed(self, data: bytes) -> list[Frame]:
        """Add ``data``; return the frames it completes, in order; FrameError if malformed."""
        self.buffer += data
        frames = []
        while len(self.buffer) >= PREFIX.size:
            header_size, payload_size = PREFIX.unpack_from(self.buffer)
            if header_size > MAX_HEADER_BYTES or payload_size > MAX_PAYLOAD_BYTES:
                raise FrameError(f'frame of {header_size} + {payload_size} bytes: over the '
                                 f'limit of {MAX_HEADER_BYTES} + {MAX_PAYLOAD_BYTES}')
            end = PREFIX.size + header_size + payload_size
            if len(self.buffer) < end:
                break
            header = _header(bytes(self.buffer[PREFIX.size:PREFIX.size + header_size]))
            payload = bytes(self.buffer[PREFIX.size + header_size:end])
            del self.buffer[:end]
            kind = header.pop('kind')
            if kind not in self.kinds:
                raise FrameError(f'unexpected frame kind {kind[:40]!r}')
            messages = _messages(header.pop('messages', []), payload)
            frames.append(Frame(kind, header, messages))
        return frames

    @property
    def partial(self) -> bool:
        """Tell whether bytes of an unfinished frame are waiting."""
        return bool(self.buffer)
