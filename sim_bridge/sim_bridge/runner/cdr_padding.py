"""
Zero the alignment padding in CDR bytes, so the same message always has the same bytes.

Fast CDR (under rclpy's ``serialize_message`` and every DDS sample) skips the padding that
aligns a field to its size without writing it: those bytes are whatever the buffer held, and
differ from run to run. Readers ignore them, but a recording that should be byte-identical for
the same seed cannot keep them, and no public writer zeroes them (rosbag2 stores the bytes as
DDS delivered them). :class:`PaddingZeroer` walks the bytes by the message's field definitions
as rosidl generated them (``SLOT_TYPES`` of the rclpy class, rosidl_parser's types: any
installed message type), plain CDR as rmw_fastrtps writes it: each primitive aligned to its
size, at most 8, counted from after the 4-byte encapsulation header; and sets padding and
trailing bytes to zero. It reads lengths only; it never decodes or re-encodes a value. Where
the padding of a type's message was is kept (:class:`Layout`): the next message of that type
with the same size and the same lengths (its strings' and sequences') has it in the same
places, so a run's thousands of /odom and /clock messages are walked once.
"""

import struct
from typing import Callable

from rosidl_parser import definition
from sim_bridge.common.message_types import message_class

#: Bytes of each primitive type of rosidl (IDL names) in CDR.
PRIMITIVE_SIZES = {
    'boolean': 1, 'octet': 1, 'char': 1, 'int8': 1, 'uint8': 1, 'int16': 2, 'uint16': 2,
    'int32': 4, 'uint32': 4, 'float': 4, 'int64': 8, 'uint64': 8, 'double': 8,
}
ENCAPSULATION_HEADER_BYTES = 4
_UINT32 = struct.Struct('<I')

#: Zero padding in ``data`` from offset ``position``; return the offset after the value.
Walker = Callable[['_Bytes', int], int]


class _Bytes(bytearray):
    """A message's bytes as they are walked: the padding found and the lengths read."""

    def __init__(self, data: bytes) -> None:
        super().__init__(data)
        self.padding: list[tuple[int, int]] = []  # (start, end) offsets
        self.lengths: list[int] = []  # offsets of the uint32 lengths the walk read


class Layout:
    """
    Where a message's padding is (``padding``: start and end offsets; ``end``: its last byte).

    It holds for any message of its type ``size`` bytes long with the same uint32 at each
    offset of ``lengths`` (offset -> the 4 bytes): a walk depends on nothing else.
    """

    def __init__(self, walked: _Bytes, end: int) -> None:
        self.size = len(walked)
        self.lengths = [(offset, bytes(walked[offset:offset + 4])) for offset in walked.lengths]
        self.padding = walked.padding
        self.end = end

    def fits(self, data: bytes) -> bool:
        """Tell whether ``data`` has this layout."""
        return len(data) == self.size and all(
            data[offset:offset + 4] == length for offset, length in self.lengths)

    def zeroed(self, data: bytes) -> bytes:
        """Return ``data`` (of this layout) with its padding and trailing bytes zeroed."""
        buffer = bytearray(data)
        for start, end in self.padding:
            buffer[start:end] = bytes(end - start)
        buffer[self.end:] = bytes(self.size - self.end)
        return bytes(buffer)


def _align(data: _Bytes, position: int, size: int) -> int:
    padding = -(position - ENCAPSULATION_HEADER_BYTES) % size
    if padding:
        data[position:position + padding] = bytes(padding)
        data.padding.append((position, position + padding))
    return position + padding


def _length(data: _Bytes, position: int) -> int:
    """Return the uint32 length at ``position`` (aligned), noted as read."""
    data.lengths.append(position)
    return _UINT32.unpack_from(data, position)[0]


def _string(data: _Bytes, position: int) -> int:
    position = _align(data, position, 4)
    return position + 4 + _length(data, position)


class PaddingZeroer:
    """Zero the padding of CDR messages of any installed message type."""

    def __init__(self) -> None:
        self.walkers: dict[type, Walker] = {}
        #: The layout of the last message walked, per type name.
        self.layouts: dict[str, Layout] = {}

    def __call__(self, type_name: str, data: bytes) -> bytes:
        """Return ``data`` (CDR bytes of a ``type_name`` message) with its padding zeroed."""
        layout = self.layouts.get(type_name)
        if layout is not None and layout.fits(data):
            return layout.zeroed(data)
        buffer = _Bytes(data)
        end = self.walker(message_class(type_name))(buffer, ENCAPSULATION_HEADER_BYTES)
        if end > len(buffer):
            raise ValueError(f'{type_name}: {len(data)} bytes are too few for its fields')
        buffer[end:] = bytes(len(buffer) - end)
        self.layouts[type_name] = Layout(buffer, end)
        return bytes(buffer)

    def walker(self, cls: type) -> Walker:
        """Return (and keep) the walker of messages of the rclpy class ``cls``."""
        if cls not in self.walkers:
            steps = [self.field(slot_type) for slot_type in cls.SLOT_TYPES]

            def walk(data: _Bytes, position: int) -> int:
                for step in steps:
                    position = step(data, position)
                return position
            self.walkers[cls] = walk
        return self.walkers[cls]

    def field(self, slot_type: definition.AbstractType) -> Walker:
        """Return the walker of one member or element of rosidl_parser's type ``slot_type``."""
        if isinstance(slot_type, definition.NamespacedType):
            cls = message_class('/'.join([*slot_type.namespaces, slot_type.name]))
            return lambda data, position: self.walker(cls)(data, position)
        if isinstance(slot_type, definition.AbstractString):
            return _string
        if isinstance(slot_type, definition.BasicType):
            size = PRIMITIVE_SIZES[slot_type.typename]
            return lambda data, position: _align(data, position, size) + size
        if not isinstance(slot_type, definition.AbstractNestedType):
            raise ValueError(f'{slot_type}: a field type the recording cannot lay out')
        return self.collection(slot_type)

    def collection(self, slot_type: definition.AbstractNestedType) -> Walker:
        """Return the walker of an array or a sequence (its length first) of elements."""
        element_type = slot_type.value_type
        primitive = isinstance(element_type, definition.BasicType)
        element = None if primitive else self.field(element_type)
        size = PRIMITIVE_SIZES[element_type.typename] if primitive else 0
        fixed = slot_type.size if isinstance(slot_type, definition.Array) else None

        def walk(data: _Bytes, position: int) -> int:
            count = fixed
            if count is None:
                position = _align(data, position, 4)
                count = _length(data, position)
                position += 4
            if primitive:
                return _align(data, position, size) + size * count if count else position
            if count > len(data) - position:  # each element takes a byte at least
                raise ValueError(f'a sequence of {count} elements at byte {position} of '
                                 f'{len(data)}: the bytes do not hold this type')
            for _ in range(count):
                position = element(data, position)
            return position
        return walk
