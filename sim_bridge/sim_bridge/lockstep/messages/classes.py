"""
Build message classes that behave like rosidl_generator_py's, from a :class:`MessageSpec`.

Behaviour mirrored from the Jazzy generator (rosidl_python's ``_msg.py.em`` after
ros2/rosidl_python#194, which hid the field assertions behind ``ROS_PYTHON_CHECK_FIELDS``):

* ``__slots__`` of ``_<field>`` plus ``_check_fields``; a property per field; an unknown
  attribute raises AttributeError.
* Field checks run only when ``ROS_PYTHON_CHECK_FIELDS=1`` or ``check_fields=True`` is passed
  to the constructor: then a wrong value (and an unknown constructor keyword) raises
  AssertionError with rosidl's message. Otherwise assignment stores anything, an unknown
  keyword is ignored, and a wrong type is only caught at publish, where the C converter aborts
  (:mod:`codegen` builds the equivalent check).
* float32/float64/integer ``[]`` sequences are ``array.array`` and fixed-size numeric arrays are
  numpy arrays; assignment always converts (``array.array(code, value)`` /
  ``numpy.array(value, dtype)``), so lists, tuples and numpy arrays are accepted.
* Every instance gets its own default sub-messages and containers.
"""

from array import array
from collections import UserList, UserString
from collections.abc import Sequence, Set
from operator import attrgetter
import os
import re

import numpy

from sim_bridge.lockstep.messages import codegen
from sim_bridge.lockstep.messages.fields import Field, MessageSpec

# rosidl reads the variable once, at import of each generated module.
CHECK_FIELDS = os.getenv('ROS_PYTHON_CHECK_FIELDS', default='') == '1'

_FLOAT32_LIMIT = 3.402823466e+38
_FLOAT64_LIMIT = 1.7976931348623157e+308


class LockstepMessage:
    """Base of every generated message class (rosidl's classes share no base; we need one)."""

    __slots__ = ()
    _lockstep_spec: MessageSpec

    def __repr__(self) -> str:
        typename = self.__class__.__module__.split('.')[:-1] + [self.__class__.__name__]
        args = []
        for field in self._lockstep_spec.fields:
            value = getattr(self, field.name)
            text = repr(value)
            if field.kind == 'sequence' and field.numeric_container:
                # rosidl strips "array('f', " ... ")" so sequences read like lists.
                text = '[]' if len(value) == 0 else text[len("array('X', "):-1]
            args.append(f'{field.name}={text}')
        return f"{'.'.join(typename)}({', '.join(args)})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, self.__class__):
            return False
        for field in self._lockstep_spec.fields:
            mine, theirs = getattr(self, field.name), getattr(other, field.name)
            if isinstance(mine, numpy.ndarray) or isinstance(theirs, numpy.ndarray):
                if not numpy.array_equal(mine, theirs):
                    return False
            elif mine != theirs:
                return False
        return True

    @classmethod
    def get_fields_and_field_types(cls) -> dict:
        """Return ``{field name: IDL type text}`` as rosidl does, e.g. ``'sequence<float>'``."""
        return {field.name: field.idl_type() for field in cls._lockstep_spec.fields}


def _float_limit(field: Field) -> float:
    return _FLOAT32_LIMIT if field.primitive.ros == 'float32' else _FLOAT64_LIMIT


def _assert_scalar(field: Field, value) -> None:
    name, primitive = field.name, field.primitive
    python = primitive.python
    if python is bytes:
        assert isinstance(value, bytes) and len(value) == 1, \
            f"The '{name}' field must be of type 'bytes' or 'ByteString' with length 1"
        return
    assert isinstance(value, python), f"The '{name}' field must be of type '{python.__name__}'"
    if python is float:
        limit = _float_limit(field)
        word = 'float' if primitive.ros == 'float32' else 'double'
        assert not (value < -limit or value > limit) or numpy.isinf(value), \
            f"The '{name}' field must be a {word} in [{-limit}, {limit}]"
    elif python is int:
        kind = 'an integer' if primitive.low < 0 else 'an unsigned integer'
        assert primitive.low <= value <= primitive.high, \
            f"The '{name}' field must be {kind} in [{primitive.low}, {primitive.high}]"
    elif python is str and field.string_bound:
        assert len(value) <= field.string_bound, \
            f"The '{name}' field must be string value not longer than {field.string_bound}"


def _is_sequence(value) -> bool:
    """Apply rosidl's container test: a Sequence, Set or UserList that is not a string."""
    return isinstance(value, (Sequence, Set, UserList)) and \
        not isinstance(value, (str, UserString))


def _assert_container(field: Field, value, message_class) -> None:
    name = field.name
    length = ''
    if field.kind == 'array':
        length = f' with length {field.size}'
    elif field.size:
        length = f' with length <= {field.size}'
    element = message_class if field.primitive is None else field.primitive.python
    ok = _is_sequence(value) and \
        (field.kind != 'array' or len(value) == field.size) and \
        (field.kind != 'sequence' or not field.size or len(value) <= field.size) and \
        all(isinstance(item, element) for item in value)
    assert ok, (f"The '{name}' field must be a set or sequence{length} "
                f"and each value of type '{element.__name__}'")


def _assert_numeric_container(field: Field, value) -> bool:
    """Check a value for a numeric array/sequence; True when it can be stored as it is."""
    name = field.name
    if field.kind == 'array' and isinstance(value, numpy.ndarray):
        assert value.dtype == field.primitive.dtype, \
            f"The '{name}' numpy.ndarray() must have the dtype of 'numpy.{field.primitive.dtype}'"
        assert value.size == field.size, \
            f"The '{name}' numpy.ndarray() must have a size of {field.size}"
        return True
    if field.kind == 'sequence' and isinstance(value, array):
        assert value.typecode == field.primitive.typecode, \
            f"The '{name}' array.array() must have the type code of " \
            f"'{field.primitive.typecode}'"
        return True
    _assert_container(field, value, None)
    return False


def _numeric_setter(field: Field, slot_set):
    typecode = field.primitive.typecode
    dtype = field.primitive.dtype
    is_array = field.kind == 'array'

    def setter(self, value):
        if self._check_fields and _assert_numeric_container(field, value):
            slot_set(self, value)
        elif is_array:
            slot_set(self, numpy.array(value, dtype=dtype))
        else:
            slot_set(self, codegen.to_array(typecode, value))
    return setter


def _plain_setter(field: Field, slot_set, resolve):
    if field.kind == 'scalar':
        def check(value):
            _assert_scalar(field, value)
    elif field.kind == 'message':
        def check(value):
            message_class = resolve(field.msgtype)
            assert isinstance(value, message_class), \
                f"The '{field.name}' field must be a sub message of type " \
                f"'{message_class.__name__}'"
    else:
        def check(value):
            message_class = resolve(field.msgtype) if field.primitive is None else None
            _assert_container(field, value, message_class)

    def setter(self, value):
        if self._check_fields:
            check(value)
        slot_set(self, value)
    return setter


def _default_value(field: Field, resolve):
    """Return a fresh default value for ``field`` (for the keyword-argument constructor)."""
    if field.kind == 'scalar':
        return field.default
    if field.kind == 'message':
        return resolve(field.msgtype)()
    if field.numeric_container:
        if field.kind == 'array':
            return numpy.zeros(field.size, dtype=field.primitive.dtype)
        return array(field.primitive.typecode)
    if field.kind == 'sequence':
        return []
    if field.primitive is None:
        return [resolve(field.msgtype)() for _ in range(field.size)]
    return [field.primitive.default] * field.size


def _kwargs_initializer(spec: MessageSpec, resolve):
    slots = {f'_{field.name}' for field in spec.fields} | {'_check_fields'}

    def init_from_kwargs(self, kwargs):
        check = kwargs['check_fields'] if 'check_fields' in kwargs else CHECK_FIELDS
        self._check_fields = check
        if check:
            assert all('_' + key in slots for key in kwargs), \
                'Invalid arguments passed to constructor: %s' % \
                ', '.join(sorted(key for key in kwargs if '_' + key not in slots))
        for field in spec.fields:
            if field.name not in kwargs:
                setattr(self, field.name, _default_value(field, resolve))
                continue
            setattr(self, field.name, kwargs[field.name])
            if field.numeric_container and field.kind == 'array':
                # rosidl asserts the shape here even when field checks are off.
                value = getattr(self, field.name)
                assert value.shape == (field.size,)
    return init_from_kwargs


def build_class(spec: MessageSpec, resolve) -> type:
    """Create the Python class for ``spec``; ``resolve(msgtype)`` returns nested classes."""
    namespace = {
        '__slots__': [f'_{field.name}' for field in spec.fields] + ['_check_fields'],
        '__module__': f'{spec.package}.msg._{_snake_case(spec.name)}',
        '__doc__': f"Message class '{spec.name}'.",
        '_lockstep_spec': spec,
        **spec.constants,
    }
    cls = type(spec.name, (LockstepMessage,), namespace)
    for field in spec.fields:
        slot_set = cls.__dict__[f'_{field.name}'].__set__
        setter = _numeric_setter(field, slot_set) if field.numeric_container \
            else _plain_setter(field, slot_set, resolve)
        setattr(cls, field.name, property(attrgetter(f'_{field.name}'), setter,
                                          doc=f"Message field '{field.name}'."))
    shared = {'CLS': cls, 'CHECK_FIELDS': CHECK_FIELDS, 'new': object.__new__,
              'init_from_kwargs': _kwargs_initializer(spec, resolve)}
    cls.__init__ = codegen.compile_function(codegen.init_source(spec, resolve), shared)
    cls._lockstep_check = staticmethod(
        codegen.compile_function(codegen.check_source(spec, resolve), shared))
    cls._lockstep_copy = staticmethod(
        codegen.compile_function(codegen.copy_source(spec, resolve), shared))
    return cls


def _snake_case(name: str) -> str:
    """Convert names as rosidl does: LaserScan → laser_scan, TFMessage → tf_message."""
    name = re.sub('(.)([A-Z][a-z]+)', r'\1_\2', name)
    return re.sub('([a-z0-9])([A-Z])', r'\1_\2', name).lower()
