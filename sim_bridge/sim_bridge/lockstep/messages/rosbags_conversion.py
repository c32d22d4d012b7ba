"""
Convert runtime messages to rosbags message objects (for MCAP recording with rosbags).

rosbags keeps numeric, bool and byte arrays as numpy arrays, strings and sub-message sequences as
lists, ``byte``/``char`` scalars as ints, and gives empty messages their C placeholder field.
A converter is built once per (type store, message type) and reused.
"""

import numpy

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.messages.fields import EMPTY_STRUCTURE_MEMBER

_CONVERTERS: dict = {}


def msg_to_rosbags(msg, typestore):
    """Return the rosbags message (a dataclass of ``typestore``) equal to runtime ``msg``."""
    return _converter(typestore, msg._lockstep_spec.msgtype)(msg)


def _converter(typestore, msgtype: str):
    key = (id(typestore), msgtype)
    entry = _CONVERTERS.get(key)
    if entry is None or entry[0] is not typestore:
        entry = _CONVERTERS[key] = (typestore, _build(typestore, msgtype))
    return entry[1]


def _build(typestore, msgtype: str):
    target = typestore.types[msgtype]
    spec = message_class(msgtype)._lockstep_spec
    parts = [(field.name, _value_converter(typestore, field)) for field in spec.fields]
    extra = {EMPTY_STRUCTURE_MEMBER: 0} if not parts else {}

    def convert(msg):
        return target(**{name: convert_value(getattr(msg, name))
                         for name, convert_value in parts}, **extra)
    return convert


def _value_converter(typestore, field):
    if field.primitive is None:
        if field.kind == 'message':
            return _converter(typestore, field.msgtype)
        element = _converter(typestore, field.msgtype)
        return lambda values: [element(value) for value in values]
    ros = field.primitive.ros
    if field.kind == 'scalar':
        return (lambda value: value[0]) if ros == 'byte' else (lambda value: value)
    if ros == 'string':
        return list
    if ros == 'byte':
        return lambda values: numpy.frombuffer(b''.join(values), dtype=numpy.uint8).copy()
    dtype = numpy.dtype(bool) if ros == 'bool' else field.primitive.dtype
    return lambda values: numpy.array(values, dtype=dtype)
