"""
Field specifications of ROS 2 Jazzy messages, read from the rosbags type store.

rosbags' ``ROS2_JAZZY`` store is the single source of truth for names, types, array sizes and
constants. It drops the default values written in ``.msg`` files; the only non-zero one among the
Jazzy interface packages is ``geometry_msgs/msg/Quaternion`` ``w`` (``float64 w 1``, see
common_interfaces' Quaternion.msg on the jazzy branch), kept in :data:`MSG_DEFAULTS`.

A :class:`Primitive` describes how rosidl_generator_py maps one ROS base type to Python: the
Python type, the ``array.array`` typecode / numpy dtype used for numeric arrays and sequences,
the integer bounds, the default value and the IDL name ``get_fields_and_field_types()`` shows.
"""

from dataclasses import dataclass
from typing import Any, Optional

import numpy
from rosbags.interfaces import Nodetype

# Empty messages carry this placeholder in C; rosidl's Python classes have no such field.
EMPTY_STRUCTURE_MEMBER = 'structure_needs_at_least_one_member'

MSG_DEFAULTS = {'geometry_msgs/msg/Quaternion': {'w': 1.0}}


@dataclass(frozen=True)
class Primitive:
    """How rosidl_generator_py represents one ROS 2 base type in Python."""

    ros: str
    idl: str
    python: type
    default: Any
    typecode: Optional[str] = None
    low: Optional[int] = None
    high: Optional[int] = None

    @property
    def numeric(self) -> bool:
        """True for types stored as array.array / numpy arrays when in sequences / arrays."""
        return self.typecode is not None

    @property
    def dtype(self) -> Optional[numpy.dtype]:
        """Numpy dtype of fixed-size arrays of this type (None when not numeric)."""
        return numpy.dtype(self.typecode) if self.numeric else None

    def describe(self) -> str:
        """Text naming the Python values the C converter accepts, e.g. ``float (float64)``."""
        if self.python is int:
            return f'int in [{self.low}, {self.high}] ({self.ros})'
        if self.python is bytes:
            return f'bytes of length 1 ({self.ros})'
        return f'{self.python.__name__} ({self.ros})'


def _integer(ros: str, idl: str, typecode: str, bits: int, signed: bool) -> Primitive:
    low, high = (-2 ** (bits - 1), 2 ** (bits - 1) - 1) if signed else (0, 2 ** bits - 1)
    return Primitive(ros, idl, int, 0, typecode, low, high)


PRIMITIVES = {
    'bool': Primitive('bool', 'boolean', bool, False),
    'byte': Primitive('byte', 'octet', bytes, b'\x00'),
    'char': _integer('char', 'uint8', 'B', 8, signed=False),
    'float32': Primitive('float32', 'float', float, 0.0, 'f'),
    'float64': Primitive('float64', 'double', float, 0.0, 'd'),
    'int8': _integer('int8', 'int8', 'b', 8, signed=True),
    'uint8': _integer('uint8', 'uint8', 'B', 8, signed=False),
    'int16': _integer('int16', 'int16', 'h', 16, signed=True),
    'uint16': _integer('uint16', 'uint16', 'H', 16, signed=False),
    'int32': _integer('int32', 'int32', 'i', 32, signed=True),
    'uint32': _integer('uint32', 'uint32', 'I', 32, signed=False),
    'int64': _integer('int64', 'int64', 'q', 64, signed=True),
    'uint64': _integer('uint64', 'uint64', 'Q', 64, signed=False),
    'string': Primitive('string', 'string', str, ''),
}


@dataclass(frozen=True)
class Field:
    """
    One message field: ``kind`` is 'scalar', 'message', 'array' (fixed size) or 'sequence'.

    Elements are either a ``primitive`` or messages of type ``msgtype``; ``size`` is the array
    length or the sequence bound (0: unbounded); ``string_bound`` bounds a string's length.
    """

    name: str
    kind: str
    primitive: Optional[Primitive] = None
    msgtype: Optional[str] = None
    size: int = 0
    string_bound: int = 0
    default: Any = None

    @property
    def numeric_container(self) -> bool:
        """True for arrays/sequences of numbers (numpy arrays / array.array in Python)."""
        return self.kind in ('array', 'sequence') and self.primitive is not None \
            and self.primitive.numeric

    def idl_type(self) -> str:
        """Return the type text rosidl's ``get_fields_and_field_types()`` reports."""
        if self.primitive is None:
            package, _, name = self.msgtype.split('/')
            element = f'{package}/{name}'
        elif self.primitive.ros == 'string' and self.string_bound:
            element = f'string<{self.string_bound}>'
        else:
            element = self.primitive.idl
        if self.kind == 'array':
            return f'{element}[{self.size}]'
        if self.kind == 'sequence':
            return f'sequence<{element}, {self.size}>' if self.size else f'sequence<{element}>'
        return element

    def ros_type(self) -> str:
        """Return the type as a .msg file writes it, e.g. ``float32[]``."""
        element = self.msgtype if self.primitive is None else self.primitive.ros
        if self.kind == 'array':
            return f'{element}[{self.size}]'
        if self.kind == 'sequence':
            return f'{element}[<={self.size}]' if self.size else f'{element}[]'
        return element


@dataclass(frozen=True)
class MessageSpec:
    """A message type: its name, fields and constants (name → Python value)."""

    msgtype: str
    fields: tuple
    constants: dict

    @property
    def package(self) -> str:
        """The interface package, e.g. ``sensor_msgs``."""
        return self.msgtype.split('/')[0]

    @property
    def name(self) -> str:
        """The class name, e.g. ``LaserScan``."""
        return self.msgtype.split('/')[-1]


def _element(definition) -> tuple[Optional[Primitive], Optional[str], int]:
    nodetype, detail = definition
    if nodetype == Nodetype.NAME:
        return None, detail, 0
    base, string_bound = detail
    return PRIMITIVES[base], None, string_bound


def _field(name: str, definition, default: Any) -> Field:
    nodetype, detail = definition
    if nodetype in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        element, size = detail
        primitive, msgtype, string_bound = _element(element)
        kind = 'array' if nodetype == Nodetype.ARRAY else 'sequence'
        return Field(name, kind, primitive, msgtype, size, string_bound)
    primitive, msgtype, string_bound = _element(definition)
    if primitive is None:
        return Field(name, 'message', msgtype=msgtype)
    value = primitive.default if default is None else primitive.python(default)
    return Field(name, 'scalar', primitive, string_bound=string_bound, default=value)


def _constant(ros_type: str, value: Any) -> Any:
    primitive = PRIMITIVES[ros_type]
    if primitive.python is bytes:
        return bytes([value])
    return primitive.python(value)


def message_spec(fielddefs: dict, msgtype: str) -> MessageSpec:
    """Build the :class:`MessageSpec` of ``msgtype`` from a rosbags ``typestore.fielddefs``."""
    constants, definitions = fielddefs[msgtype]
    defaults = MSG_DEFAULTS.get(msgtype, {})
    fields = tuple(_field(name, definition, defaults.get(name))
                   for name, definition in definitions
                   if not (len(definitions) == 1 and name == EMPTY_STRUCTURE_MEMBER))
    return MessageSpec(msgtype, fields,
                       {name: _constant(ros_type, value) for name, ros_type, value in constants})
