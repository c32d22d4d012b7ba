"""
The parameter half of rclpy's Node, following Jazzy's node.py step for step.

* ``declare_parameter(name, value)`` types the parameter by its default (``Parameter.Type`` as
  the value declares the type without a value); an override (``--ros-args -p``, a params file,
  ``parameter_overrides``) replaces the value and must have that type: an int override for a
  double parameter raises InvalidParameterTypeException, exactly as Jazzy's rclpy does.
* ``set_parameters`` returns one SetParametersResult per parameter; a wrong type fails with
  "Wrong parameter type, expected 'Type.DOUBLE' got 'Type.INTEGER'"; on-set callbacks can
  reject; ranges and read-only descriptors are enforced.
* Reading an undeclared parameter raises ParameterNotDeclaredException (unless undeclared
  parameters are allowed).
"""

import math
from typing import Any, Callable, Dict, List, Optional
import warnings

from sim_bridge.lockstep.messages import message_class
from sim_bridge.lockstep.rclpy.exceptions import (
    InvalidParameterException, InvalidParameterTypeException, InvalidParameterValueException,
    ParameterAlreadyDeclaredException, ParameterImmutableException, ParameterNotDeclaredException,
    ParameterUninitializedException)
from sim_bridge.lockstep.rclpy.parameter import Parameter, PARAMETER_SEPARATOR_STRING

__lockstep__ = True


def _descriptor(**fields):
    return message_class('rcl_interfaces/msg/ParameterDescriptor')(**fields)


def _result(successful: bool, reason: str = ''):
    return message_class('rcl_interfaces/msg/SetParametersResult')(
        successful=successful, reason=reason)


class NodeParameters:
    """Parameter storage and the declare/get/set API of rclpy.node.Node."""

    PARAM_REL_TOL = 1e-6

    def _init_parameters(self, overrides: Dict[str, Parameter], allow_undeclared: bool) -> None:
        self._parameters: Dict[str, Parameter] = {}
        self._descriptors: dict = {}
        self._parameter_overrides = overrides
        self._allow_undeclared_parameters = allow_undeclared
        self._pre_set_parameters_callbacks: List[Callable] = []
        self._on_set_parameters_callbacks: List[Callable] = []
        self._post_set_parameters_callbacks: List[Callable] = []

    # --- declaring ----------------------------------------------------------------------------

    def declare_parameter(self, name: str, value: Any = None, descriptor=None,
                          ignore_override: bool = False) -> Parameter:
        """Declare and initialise a parameter; return it with its effective value."""
        if value is None and descriptor is None:
            args = (name,)
        else:
            args = (name, value, _descriptor() if descriptor is None else descriptor)
        return self.declare_parameters('', [args], ignore_override)[0]

    def declare_parameters(self, namespace: str, parameters: list,
                           ignore_override: bool = False) -> List[Parameter]:
        """Declare ``namespace.name`` for each (name[, value[, descriptor]]) tuple."""
        parameter_list = []
        descriptors = {}
        for index, parameter_tuple in enumerate(parameters):
            if len(parameter_tuple) < 1 or len(parameter_tuple) > 3:
                raise TypeError(
                    f'Invalid parameter tuple length at index {index} in parameters list: '
                    f'{parameter_tuple}; expecting length between 1 and 3')
            name = parameter_tuple[0]
            if not isinstance(name, str):
                raise TypeError(f'First element {name} at index {index} in parameters list '
                                'is not a str.')
            if namespace:
                name = f'{namespace}.{name}'
            if not name:
                raise InvalidParameterException(name)
            second_arg = parameter_tuple[1] if len(parameter_tuple) > 1 else None
            descriptor = parameter_tuple[2] if len(parameter_tuple) > 2 else _descriptor()
            if not isinstance(descriptor, message_class('rcl_interfaces/msg/ParameterDescriptor')):
                raise TypeError(f'Third element {descriptor} at index {index} in parameters list '
                                'is not a ParameterDescriptor.')
            value = None
            if len(parameter_tuple) == 1:
                warnings.warn(
                    f"when declaring parameter named '{name}', declaring a parameter only "
                    'providing its name is deprecated. You have to either:\n'
                    '\t- Pass a name and a default value different to "PARAMETER NOT SET" '
                    '(and optionally a descriptor).\n'
                    '\t- Pass a name and a parameter type.\n'
                    '\t- Pass a name and a descriptor with `dynamic_typing=True')
                descriptor.dynamic_typing = True
            if isinstance(second_arg, Parameter.Type):
                if second_arg == Parameter.Type.NOT_SET:
                    raise ValueError(
                        f'Cannot declare parameter {{{name}}} as statically typed of type NOT_SET')
                if descriptor.dynamic_typing is True:
                    raise ValueError(
                        f'When declaring parameter {{{name}}} passing a descriptor with'
                        '`dynamic_typing=True` is not allowed when the parameter type is provided')
                descriptor.type = second_arg.value
            else:
                value = second_arg
                if not descriptor.dynamic_typing:
                    descriptor.type = Parameter.Type.from_parameter_value(value).value
                    if descriptor.type == Parameter.Type.NOT_SET.value:
                        raise ValueError('Cannot declare a statically typed parameter with '
                                         'default value of type PARAMETER_NOT_SET')
            if not ignore_override and name in self._parameter_overrides:
                value = self._parameter_overrides[name].value
            parameter_list.append(Parameter(name, value=value))
            descriptors[name] = descriptor

        already = [p.name for p in parameter_list if p.name in self._parameters]
        if already:
            raise ParameterAlreadyDeclaredException(already)
        for parameter in parameter_list:
            result = self._set_parameters_atomically_common(
                [parameter], descriptors, allow_not_set_type=True)
            if not result.successful:
                if result.reason.startswith('Wrong parameter type'):
                    raise InvalidParameterTypeException(
                        parameter, Parameter.Type(descriptors[parameter.name].type).name)
                raise InvalidParameterValueException(parameter.name, parameter.value,
                                                     result.reason)
        return [self._parameters[parameter.name] for parameter in parameter_list]

    def undeclare_parameter(self, name: str) -> None:
        """Undeclare a previously declared parameter."""
        if not self.has_parameter(name):
            raise ParameterNotDeclaredException(name)
        if self._descriptors[name].read_only:
            raise ParameterImmutableException(name)
        del self._parameters[name]
        del self._descriptors[name]

    # --- reading ------------------------------------------------------------------------------

    def has_parameter(self, name: str) -> bool:
        """Return True if parameter is declared; False otherwise."""
        return name in self._parameters

    def get_parameter(self, name: str) -> Parameter:
        """Get a declared parameter by name."""
        if self.has_parameter(name):
            parameter = self._parameters[name]
            if parameter.type_ != Parameter.Type.NOT_SET or \
                    self._descriptors[name].dynamic_typing:
                return parameter
            raise ParameterUninitializedException(name)
        if self._allow_undeclared_parameters:
            return Parameter(name, Parameter.Type.NOT_SET, None)
        raise ParameterNotDeclaredException(name)

    def get_parameters(self, names: List[str]) -> List[Parameter]:
        """Get a list of parameters."""
        if not all(isinstance(name, str) for name in names):
            raise TypeError('All names must be instances of type str')
        return [self.get_parameter(name) for name in names]

    def get_parameter_or(self, name: str, alternative_value: Optional[Parameter] = None):
        """Get a parameter, or ``alternative_value`` when it is undeclared or unset."""
        if alternative_value is None:
            alternative_value = Parameter(name, Parameter.Type.NOT_SET)
        if not self.has_parameter(name) or \
                self._parameters[name].type_ == Parameter.Type.NOT_SET:
            return alternative_value
        return self._parameters[name]

    def get_parameters_by_prefix(self, prefix: str) -> Dict[str, Parameter]:
        """Parameters under ``prefix.``, keyed by the rest of their name."""
        if prefix:
            prefix = prefix + PARAMETER_SEPARATOR_STRING
        return {name[len(prefix):]: parameter for name, parameter in self._parameters.items()
                if name.startswith(prefix)}

    def get_parameter_type(self, name: str) -> Parameter.Type:
        """Get a parameter's type."""
        if self.has_parameter(name):
            return self._parameters[name].type_
        if self._allow_undeclared_parameters:
            return Parameter.Type.NOT_SET
        raise ParameterNotDeclaredException(name)

    def describe_parameter(self, name: str):
        """Return the ParameterDescriptor of a parameter."""
        try:
            return self._descriptors[name]
        except KeyError:
            if self._allow_undeclared_parameters:
                return _descriptor()
            raise ParameterNotDeclaredException(name) from None

    def describe_parameters(self, names: List[str]) -> list:
        """Return the ParameterDescriptors of several parameters."""
        return [self.describe_parameter(name) for name in names]

    # --- setting ------------------------------------------------------------------------------

    def set_parameters(self, parameter_list: List[Parameter]) -> list:
        """Set parameters one by one; return one SetParametersResult each."""
        return [self._set_parameters_atomically([parameter]) for parameter in parameter_list]

    def set_parameters_atomically(self, parameter_list: List[Parameter]):
        """Set parameters all at once (all or none); return one SetParametersResult."""
        return self._set_parameters_atomically(parameter_list)

    def _set_parameters_atomically(self, parameter_list: List[Parameter]):
        if self._pre_set_parameters_callbacks:
            modified = []
            for callback in self._pre_set_parameters_callbacks:
                modified.extend(callback(parameter_list))
            parameter_list = modified
            if not parameter_list:
                return _result(False, 'parameter list cannot be empty, this might be due to '
                                      'pre_set_parameters_callback modifying the original '
                                      'parameters list.')
        if not all(isinstance(parameter, Parameter) for parameter in parameter_list):
            raise TypeError(f"parameter must be instance of type '{Parameter!r}'")
        undeclared = [p.name for p in parameter_list if p.name not in self._parameters]
        if undeclared and not self._allow_undeclared_parameters:
            raise ParameterNotDeclaredException(undeclared)
        return self._set_parameters_atomically_common(parameter_list)

    def _set_parameters_atomically_common(self, parameter_list, descriptors=None,
                                          allow_not_set_type: bool = False):
        if descriptors is not None:
            result = self._apply_descriptors(parameter_list, descriptors, False)
        else:
            result = self._apply_descriptors(parameter_list, self._descriptors, True)
        if not result.successful:
            return result
        for callback in self._on_set_parameters_callbacks:
            result = callback(parameter_list)
            if not result.successful:
                return result
        for parameter in parameter_list:
            if not allow_not_set_type and parameter.type_ == Parameter.Type.NOT_SET:
                self._parameters.pop(parameter.name, None)
                self._descriptors.pop(parameter.name, None)
                continue
            if descriptors is not None:
                self._descriptors[parameter.name] = descriptors[parameter.name]
            elif parameter.name not in self._descriptors:
                self._descriptors[parameter.name] = _descriptor(dynamic_typing=True)
            self._parameters[parameter.name] = parameter
        for callback in self._post_set_parameters_callbacks:
            callback(parameter_list)
        return _result(True)

    def _apply_descriptors(self, parameter_list, descriptors, check_read_only: bool):
        for parameter in parameter_list:
            if parameter.name in descriptors:
                result = self._apply_descriptor(parameter, descriptors[parameter.name],
                                                check_read_only)
                if not result.successful:
                    return result
        return _result(True)

    def _apply_descriptor(self, parameter: Parameter, descriptor, check_read_only: bool):
        descriptor.name = parameter.name
        if check_read_only and descriptor.read_only:
            return _result(False, f'Trying to set a read-only parameter: {parameter.name}.')
        if descriptor.dynamic_typing:
            descriptor.type = parameter.type_.value
        elif self.has_parameter(parameter.name) and parameter.type_ == Parameter.Type.NOT_SET:
            return _result(False, 'Static parameter cannot be undeclared')
        elif parameter.type_ != Parameter.Type.NOT_SET and \
                parameter.type_.value != descriptor.type:
            return _result(False, 'Wrong parameter type, expected '
                                  f"'{Parameter.Type(descriptor.type)}' got '{parameter.type_}'")
        if parameter.type_ == Parameter.Type.INTEGER and descriptor.integer_range:
            return self._apply_range(parameter, descriptor.integer_range[0], integer=True)
        if parameter.type_ == Parameter.Type.DOUBLE and descriptor.floating_point_range:
            return self._apply_range(parameter, descriptor.floating_point_range[0],
                                     integer=False)
        return _result(True)

    def _apply_range(self, parameter: Parameter, value_range, integer: bool):
        low = min(value_range.from_value, value_range.to_value)
        high = max(value_range.from_value, value_range.to_value)
        value = parameter.value
        if integer:
            at_edge = value in (low, high)
        else:
            at_edge = math.isclose(value, low, rel_tol=self.PARAM_REL_TOL) or \
                math.isclose(value, high, rel_tol=self.PARAM_REL_TOL)
        if at_edge:
            return _result(True)
        if not low < value < high:
            return _result(False, f'Parameter {parameter.name} out of range'
                                  f"{'.' if integer else ''} Min: {low}, Max: {high}, "
                                  f'value: {value}')
        step = value_range.step
        if integer and step != 0 and (value - low) % step != 0:
            return _result(False, f'The parameter value for {parameter.name} is not a valid '
                                  f'step. Min: {low}, max: {high}, value: {value}, step: {step}')
        if not integer and step != 0.0 and not math.isclose(
                low + round((value - low) / step) * step, value, rel_tol=self.PARAM_REL_TOL):
            return _result(False, f'The parameter value for {parameter.name} is not close '
                                  f'enough to a valid step. Min: {low}, max: {high}, value: '
                                  f'{value}, step: {step}')
        return _result(True)

    # --- callbacks ----------------------------------------------------------------------------

    def add_pre_set_parameters_callback(self, callback: Callable) -> None:
        """Add a callback that may modify the list of parameters before they are validated."""
        self._pre_set_parameters_callbacks.insert(0, callback)

    def add_on_set_parameters_callback(self, callback: Callable) -> None:
        """Add a callback that validates parameters (returns SetParametersResult)."""
        self._on_set_parameters_callbacks.insert(0, callback)

    def add_post_set_parameters_callback(self, callback: Callable) -> None:
        """Add a callback called after parameters were set."""
        self._post_set_parameters_callbacks.insert(0, callback)

    def remove_pre_set_parameters_callback(self, callback: Callable) -> None:
        """Remove a pre-set callback."""
        self._pre_set_parameters_callbacks.remove(callback)

    def remove_on_set_parameters_callback(self, callback: Callable) -> None:
        """Remove an on-set callback."""
        self._on_set_parameters_callbacks.remove(callback)

    def remove_post_set_parameters_callback(self, callback: Callable) -> None:
        """Remove a post-set callback."""
        self._post_set_parameters_callbacks.remove(callback)
