"""
Zero the alignment padding in CDR bytes, so the same message always has the same bytes.

Fast CDR (under rclpy's ``serialize_message`` and every DDS sample) skips the padding that
aligns a field to its size without writing it: those bytes are whatever the buffer held, and
differ from run to run. Readers ignore them, but a recording that should be byte-identical for
the same seed cannot keep them. :class:`PaddingZeroer` walks the bytes by the message's field
definitions (rosbags' type store, plain CDR as rmw_fastrtps writes it: each primitive aligned
to its size, at most 8, counted from after the 4-byte encapsulation header) and sets padding and
trailing bytes to zero. It reads lengths only; it never decodes or re-encodes a value.
"""

import struct
from typing import Callable

from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

#: Bytes of each primitive ROS type in CDR.
PRIMITIVE_SIZES = {
    'bool': 1, 'byte': 1, 'char': 1, 'int8': 1, 'uint8': 1, 'int16': 2, 'uint16': 2,
    'int32': 4, 'uint32': 4, 'float32': 4, 'int64': 8, 'uint64': 8, 'float64': 8,
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
    """Zero the padding of CDR messages of any type in a rosbags type store."""

    def __init__(self, typestore: Typestore) -> None:
        self.typestore = typestore
        self.walkers: dict[str, Walker] = {}

    def __call__(self, type_name: str, data: bytes) -> bytes:
        """Return ``data`` (CDR bytes of a ``type_name`` message) with its padding zeroed."""
        buffer = bytearray(data)
        end = self.walker(type_name)(buffer, ENCAPSULATION_HEADER_BYTES)
        if end > len(buffer):
            raise ValueError(f'{type_name}: {len(data)} bytes are too few for its fields')
        buffer[end:] = bytes(len(buffer) - end)
        return bytes(buffer)

    def walker(self, type_name: str) -> Walker:
        """Return (and keep) the walker of messages of ``type_name``."""
        if type_name not in self.walkers:
            _, fields = self.typestore.fielddefs[type_name]
            steps = [self.field(kind, detail) for _, (kind, detail) in fields]

            def walk(data: bytearray, position: int) -> int:
                for step in steps:
                    position = step(data, position)
                return position
            self.walkers[type_name] = walk
        return self.walkers[type_name]

    def field(self, kind: Nodetype, detail) -> Walker:
        """Return the walker of one member or element: rosbags' node type ``kind``, ``detail``."""
        if kind == Nodetype.NAME:
            return lambda data, position: self.walker(detail)(data, position)
        if kind == Nodetype.BASE:
            type_name = detail[0]
            if type_name == 'string':
                return _string
            size = PRIMITIVE_SIZES[type_name]
            return lambda data, position: _align(data, position, size) + size
        (element_kind, element_detail), length = detail
        primitive = element_kind == Nodetype.BASE and element_detail[0] != 'string'
        element = None if primitive else self.field(element_kind, element_detail)
        size = PRIMITIVE_SIZES[element_detail[0]] if primitive else 0

        def collection(data: bytearray, position: int) -> int:
            count = length
            if kind == Nodetype.SEQUENCE:
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
        return collection
