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
trailing bytes to zero. It reads lengths only; it never decodes or re-encodes a value.
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
Walker = Callable[[bytearray, int], int]


def _align(data: bytearray, position: int, size: int) -> int:
    padding = -(position - ENCAPSULATION_HEADER_BYTES) % size
    if padding:
        data[position:position + padding] = bytes(padding)
    return position + padding


def _string(data: bytearray, position: int) -> int:
    position = _align(data, position, 4)
    return position + 4 + _UINT32.unpack_from(data, position)[0]


class PaddingZeroer:
    """Zero the padding of CDR messages of any installed message type."""

    def __init__(self) -> None:
        self.walkers: dict[type, Walker] = {}

    def __call__(self, type_name: str, data: bytes) -> bytes:
        """Return ``data`` (CDR bytes of a ``type_name`` message) with its padding zeroed."""
        buffer = bytearray(data)
        end = self.walker(message_class(type_name))(buffer, ENCAPSULATION_HEADER_BYTES)
        if end > len(buffer):
            raise ValueError(f'{type_name}: {len(data)} bytes are too few for its fields')
        buffer[end:] = bytes(len(buffer) - end)
        return bytes(buffer)

    def walker(self, cls: type) -> Walker:
        """Return (and keep) the walker of messages of the rclpy class ``cls``."""
        if cls not in self.walkers:
            steps = [self.field(slot_type) for slot_type in cls.SLOT_TYPES]

            def walk(data: bytearray, position: int) -> int:
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

        def walk(data: bytearray, position: int) -> int:
            count = fixed
            if count is None:
                position = _align(data, position, 4)
                count = _UINT32.unpack_from(data, position)[0]
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
