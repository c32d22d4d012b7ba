"""
rclpy.parameter for the lockstep runtime: Parameter and Parameter.Type, as in Jazzy.

A parameter's type is inferred from its value: bool → BOOL, int → INTEGER, float → DOUBLE,
str → STRING, and lists of one of those (or of bytes) → the matching ``*_ARRAY``. An empty list
is a BYTE_ARRAY, as in rclpy.
"""

from array import array
from enum import Enum
from typing import Any, Optional

from sim_bridge.lockstep.messages import message_class

__lockstep__ = True

PARAMETER_SEPARATOR_STRING = '.'

_ARRAY_TYPES = (list, tuple, array)


class Parameter:
    """A named, typed parameter value."""

    class Type(Enum):
        """Parameter types (rcl_interfaces/msg/ParameterType)."""

        NOT_SET = 0
        BOOL = 1
        INTEGER = 2
        DOUBLE = 3
        STRING = 4
        BYTE_ARRAY = 5
        BOOL_ARRAY = 6
        INTEGER_ARRAY = 7
        DOUBLE_ARRAY = 8
        STRING_ARRAY = 9

        @classmethod
        def from_parameter_value(cls, parameter_value: Any) -> 'Parameter.Type':
            """Get a Parameter.Type from a value; TypeError for values no type holds."""
            if parameter_value is None:
                return cls.NOT_SET
            if isinstance(parameter_value, bool):
                return cls.BOOL
            if isinstance(parameter_value, int):
                return cls.INTEGER
            if isinstance(parameter_value, float):
                return cls.DOUBLE
            if isinstance(parameter_value, str):
                return cls.STRING
            if isinstance(parameter_value, _ARRAY_TYPES):
                for element_type, kind in ((bytes, cls.BYTE_ARRAY), (bool, cls.BOOL_ARRAY),
                                           (int, cls.INTEGER_ARRAY), (float, cls.DOUBLE_ARRAY),
                                           (str, cls.STRING_ARRAY)):
                    if all(isinstance(value, element_type) for value in parameter_value):
                        return kind
                raise TypeError('The given value is not a list of one of the allowed types'
                                f" '{parameter_value}'.")
            raise TypeError(
                f"The given value is not one of the allowed types '{parameter_value}'.")

        def check(self, parameter_value: Any) -> bool:
            """Tell whether ``parameter_value`` can be a value of this type."""
            cls = type(self)
            if self == cls.NOT_SET:
                return parameter_value is None
            scalars = {cls.BOOL: bool, cls.INTEGER: int, cls.DOUBLE: float, cls.STRING: str}
            if self in scalars:
                return isinstance(parameter_value, scalars[self])
            elements = {cls.BYTE_ARRAY: bytes, cls.BOOL_ARRAY: bool, cls.INTEGER_ARRAY: int,
                        cls.DOUBLE_ARRAY: float, cls.STRING_ARRAY: str}[self]
            return isinstance(parameter_value, _ARRAY_TYPES) and \
                all(isinstance(value, elements) for value in parameter_value)

    @classmethod
    def from_parameter_msg(cls, param_msg) -> 'Parameter':
        """Create a Parameter from an rcl_interfaces/msg/Parameter."""
        value = parameter_value_to_python(param_msg.value)
        return cls(param_msg.name, cls.Type(param_msg.value.type), value)

    def __init__(self, name: str, type_: Optional['Parameter.Type'] = None, value: Any = None):
        if type_ is None:
            type_ = Parameter.Type.from_parameter_value(value)
        if not isinstance(type_, Parameter.Type):
            raise TypeError(f"type must be an instance of '{Parameter.Type!r}'")
        if not type_.check(value):
            raise ValueError(f"Type '{type_}' and value '{value}' do not agree")
        self._type_ = type_
        self._name = name
        self._value = value

    @property
    def name(self) -> str:
        """The parameter's fully qualified name."""
        return self._name

    @property
    def type_(self) -> 'Parameter.Type':
        """The parameter's type."""
        return self._type_

    @property
    def value(self) -> Any:
        """The parameter's value; None when NOT_SET."""
        return self._value

    def __repr__(self) -> str:
        return f'Parameter(name={self._name!r}, type_={self._type_}, value={self._value!r})'

    def get_descriptor(self):
        """Return an rcl_interfaces/msg/ParameterDescriptor with this name and type."""
        return message_class('rcl_interfaces/msg/ParameterDescriptor')(
            name=self.name, type=self.type_.value)

    def get_parameter_value(self):
        """Return the value as an rcl_interfaces/msg/ParameterValue."""
        parameter_value = message_class('rcl_interfaces/msg/ParameterValue')(
            type=self.type_.value)
        field = _VALUE_FIELDS.get(self.type_)
        if field is not None:
            setattr(parameter_value, field, self.value)
        return parameter_value

    def to_parameter_msg(self):
        """Return the parameter as an rcl_interfaces/msg/Parameter."""
        return message_class('rcl_interfaces/msg/Parameter')(
            name=self.name, value=self.get_parameter_value())


_VALUE_FIELDS = {
    Parameter.Type.BOOL: 'bool_value', Parameter.Type.INTEGER: 'integer_value',
    Parameter.Type.DOUBLE: 'double_value', Parameter.Type.STRING: 'string_value',
    Parameter.Type.BYTE_ARRAY: 'byte_array_value', Parameter.Type.BOOL_ARRAY: 'bool_array_value',
    Parameter.Type.INTEGER_ARRAY: 'integer_array_value',
    Parameter.Type.DOUBLE_ARRAY: 'double_array_value',
    Parameter.Type.STRING_ARRAY: 'string_array_value',
}


def parameter_value_to_python(parameter_value) -> Any:
    """Get the Python value held by an rcl_interfaces/msg/ParameterValue."""
    kind = Parameter.Type(parameter_value.type)
    if kind == Parameter.Type.NOT_SET:
        return None
    value = getattr(parameter_value, _VALUE_FIELDS[kind])
    return list(value) if kind.name.endswith('_ARRAY') else value
