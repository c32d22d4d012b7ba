"""
Straight-line Python source for the hot paths of each message class.

Three functions are generated per message type, the way rosidl_generator_py generates whole
classes from templates:

* ``__init__``, setting every slot directly (keyword arguments converted as the setters do);
* ``check(msg)``, the publish-time validation that mirrors the C converter
  (``convert_from_py``) rosidl generates: it returns ``None`` when the message would convert, or
  ``(field_path, expected, value)`` for the first field that would make Jazzy abort;
* ``copy(msg)``, the delivery copy: what a subscriber gets back from the C converter after
  serialisation (plain ``float``/``int`` values, float32 fields rounded to float32 precision,
  fresh containers and sub-messages).

Generated code is faster than walking the fields in a loop; the ``fields`` module says what to
generate, so nothing here is specific to one message.
"""

from array import array
import math
import struct

import numpy

from sim_bridge.lockstep.messages.fields import Field, MessageSpec


_FLOAT32 = struct.Struct('<f')


def _one_to_float32(value: float) -> float:
    try:
        return _FLOAT32.unpack(_FLOAT32.pack(value))[0]
    except OverflowError:
        # struct refuses what rounds past float32's range; C's (float) cast gives ±inf.
        return math.copysign(math.inf, value)


def float32_rounder(count: int):
    """Return ``f(*values) -> tuple`` rounding ``count`` floats to float32 like a C cast."""
    packer = struct.Struct(f'<{count}f')

    def to_float32(*values):
        try:
            return packer.unpack(packer.pack(*values))
        except OverflowError:
            return tuple(_one_to_float32(value) for value in values)
    return to_float32


def to_array(typecode: str, value) -> array:
    """Return ``array.array(typecode, value)``, without iterating numpy arrays of one kind."""
    if isinstance(value, numpy.ndarray) and value.ndim == 1:
        dtype = numpy.dtype(typecode)
        if value.dtype == dtype or (value.dtype.kind == 'f' and dtype.kind == 'f'):
            # Same values array.array would produce element by element (a C cast each).
            result = array(typecode)
            result.frombytes(value.astype(dtype, copy=False).tobytes())
            return result
    return array(typecode, value)


def to_fixed_array(value, dtype, size: int) -> numpy.ndarray:
    """Return ``numpy.array(value, dtype)``, asserting its shape as rosidl's constructor does."""
    result = numpy.array(value, dtype=dtype)
    assert result.shape == (size,)
    return result


def primitive_ok(primitive, value) -> bool:
    """Tell whether the C converter accepts ``value`` for a scalar of ``primitive``'s type."""
    python = primitive.python
    if python is float:
        return isinstance(value, float)
    if python is bool:
        return value is True or value is False
    if python is int:
        return isinstance(value, int) and primitive.low <= value <= primitive.high
    if python is bytes:
        return isinstance(value, bytes) and len(value) == 1
    return isinstance(value, str)


def _wrong_container(value, field: Field) -> bool:
    """Tell whether a list-backed array/sequence value has the wrong kind or length."""
    return not isinstance(value, (list, tuple)) or \
        (field.kind == 'array' and len(value) != field.size) or \
        (field.kind == 'sequence' and bool(field.size) and len(value) > field.size)


def check_items(value, name: str, field: Field):
    """Validate a list-backed array/sequence of primitives; the slow, rare path."""
    if _wrong_container(value, field):
        return name, container_text(field), value
    for index, item in enumerate(value):
        if not primitive_ok(field.primitive, item):
            return f'{name}[{index}]', field.primitive.describe(), item
    return None


def check_messages(value, name: str, field: Field, message_class):
    """Validate an array/sequence of sub-messages, naming the first bad element."""
    if _wrong_container(value, field):
        return name, container_text(field), value
    for index, item in enumerate(value):
        if item.__class__ is not message_class:
            return f'{name}[{index}]', field.msgtype, item
        problem = message_class._lockstep_check(item)
        if problem is not None:
            return f'{name}[{index}].{problem[0]}', problem[1], problem[2]
    return None


def container_text(field: Field) -> str:
    """Describe the Python container rosidl uses for an array/sequence field."""
    if field.numeric_container:
        if field.kind == 'array':
            return f'numpy.ndarray of {field.size} {field.primitive.dtype} ({field.ros_type()})'
        return f"array.array('{field.primitive.typecode}') ({field.ros_type()})"
    count = f'{field.size} ' if field.kind == 'array' else ''
    return f'list of {count}elements ({field.ros_type()})'


class _Source:
    """Accumulate the lines of one generated function and the globals it refers to."""

    def __init__(self, header: str):
        self.lines = [header]
        self.globals = {}

    def name(self, prefix: str, value) -> str:
        """Return a global name bound to ``value`` in the generated module."""
        key = f'{prefix}_{len(self.globals)}'
        self.globals[key] = value
        return key

    def add(self, line: str, indent: int = 1) -> None:
        self.lines.append('    ' * indent + line)

    def text(self) -> str:
        return '\n'.join(self.lines) + '\n'


def _default_expression(source: _Source, field: Field, resolve) -> str:
    if field.kind == 'scalar':
        return repr(field.default)
    if field.kind == 'message':
        return f'{source.name("cls", resolve(field.msgtype))}()'
    if field.numeric_container and field.kind == 'array':
        return f'zeros({field.size}, {source.name("dtype", field.primitive.dtype)})'
    if field.numeric_container:
        return f"array('{field.primitive.typecode}')"
    if field.kind == 'sequence':
        return '[]'
    if field.primitive is None:
        return f'[{source.name("cls", resolve(field.msgtype))}() for _ in range({field.size})]'
    return f'[{field.primitive.default!r}] * {field.size}'


def _keyword_expression(source: _Source, field: Field, default: str) -> str:
    """Expression for a field given as keyword argument, converted as its setter would."""
    given = f'kwargs[{field.name!r}]'
    if field.numeric_container and field.kind == 'array':
        dtype = source.name('dtype', field.primitive.dtype)
        given = f'to_fixed_array({given}, {dtype}, {field.size})'
    elif field.numeric_container:
        given = f"to_array('{field.primitive.typecode}', {given})"
    return f'{given} if {field.name!r} in kwargs else {default}'


def init_source(spec: MessageSpec, resolve) -> _Source:
    """
    Source of ``__init__``: defaults set directly; keyword arguments converted inline.

    With field checks on (``check_fields`` given or ROS_PYTHON_CHECK_FIELDS=1) keyword
    arguments go through ``init_from_kwargs`` and the checking setters instead.
    """
    source = _Source('def __init__(self, **kwargs):')
    defaults = [(field, _default_expression(source, field, resolve)) for field in spec.fields]
    source.add('if kwargs:')
    source.add("if CHECK_FIELDS or 'check_fields' in kwargs:", 2)
    source.add('init_from_kwargs(self, kwargs)', 3)
    source.add('return', 3)
    source.add('self._check_fields = False', 2)
    for field, default in defaults:
        source.add(f'self._{field.name} = {_keyword_expression(source, field, default)}', 2)
    source.add('return', 2)
    source.add('self._check_fields = CHECK_FIELDS')
    for field, default in defaults:
        source.add(f'self._{field.name} = {default}')
    return source


def check_source(spec: MessageSpec, resolve) -> _Source:
    """
    Source of ``check(m)``, mirroring the per-field asserts of rosidl's C converter.

    Nested messages are checked inline (one function per type, however deep it is).
    """
    source = _Source('def check(m):')
    _check_fields(source, spec, 'm', '', resolve)
    source.add('return None')
    return source


def _check_fields(source: _Source, spec: MessageSpec, message: str, path: str,
                  resolve) -> None:
    """Add the checks of every field of ``spec`` read from the variable ``message``."""
    for field in spec.fields:
        name = path + field.name
        source.add(f'v = {message}._{field.name}')
        if field.kind == 'message':
            message_class = resolve(field.msgtype)
            cls = source.name('cls', message_class)
            source.add(f'if v.__class__ is not {cls}:')
            source.add(f'return {name!r}, {field.msgtype!r}, v', 2)
            nested = f'm{len(source.lines)}'
            source.add(f'{nested} = v')
            _check_fields(source, message_class._lockstep_spec, nested, name + '.', resolve)
        elif field.kind == 'scalar':
            source.add(f'if {_scalar_failure(field)}:')
            source.add(f'return {name!r}, {field.primitive.describe()!r}, v', 2)
        elif field.numeric_container:
            expected = source.name('text', container_text(field))
            source.add(f'if {_container_failure(field, source)}:')
            source.add(f'return {name!r}, {expected}, v', 2)
        else:
            field_ref = source.name('field', field)
            if field.primitive is None:
                cls = source.name('cls', resolve(field.msgtype))
                source.add(f'r = check_messages(v, {name!r}, {field_ref}, {cls})')
            else:
                source.add(f'r = check_items(v, {name!r}, {field_ref})')
            source.add('if r is not None:')
            source.add('return r', 2)


def _scalar_failure(field: Field) -> str:
    primitive = field.primitive
    python = primitive.python
    if python is float:
        return 'not isinstance(v, float)'
    if python is bool:
        return 'v is not True and v is not False'
    if python is int:
        return f'not isinstance(v, int) or v < {primitive.low} or v > {primitive.high}'
    if python is bytes:
        return 'not isinstance(v, bytes) or len(v) != 1'
    return 'not isinstance(v, str)'


def _container_failure(field: Field, source: _Source) -> str:
    if field.kind == 'array':
        dtype = source.name('dtype', field.primitive.dtype)
        return (f'v.__class__ is not ndarray or v.dtype != {dtype} '
                f'or v.shape != ({field.size},)')
    bound = f' or len(v) > {field.size}' if field.size else ''
    return f"v.__class__ is not array or v.typecode != '{field.primitive.typecode}'{bound}"


def copy_source(spec: MessageSpec, resolve) -> _Source:
    """
    Source of ``copy(m)``: the message as a subscriber receives it after serialisation.

    The generated code refers to its own class as ``CLS``, which the caller provides.
    """
    source = _Source('def copy(m):')
    source.add('c = new(CLS)')
    source.add('c._check_fields = CHECK_FIELDS')
    float32_fields = [f.name for f in spec.fields
                      if f.kind == 'scalar' and f.primitive.ros == 'float32']
    if float32_fields:
        rounder = source.name('to_float32', float32_rounder(len(float32_fields)))
        targets = ''.join(f'c._{name}, ' for name in float32_fields)
        values = ', '.join(f'm._{name}' for name in float32_fields)
        source.add(f'{targets} = {rounder}({values})')
    for field in spec.fields:
        name = field.name
        if field.kind == 'scalar':
            if field.primitive.ros == 'float32':
                continue
            convert = {float: 'float', int: 'int', str: 'str'}.get(field.primitive.python)
            value = f'{convert}(m._{name})' if convert else f'm._{name}'
        elif field.kind == 'message':
            value = f'{source.name("cls", resolve(field.msgtype))}._lockstep_copy(m._{name})'
        elif field.numeric_container:
            value = f'm._{name}.copy()' if field.kind == 'array' else f'm._{name}[:]'
        elif field.primitive is None:
            cls = source.name('cls', resolve(field.msgtype))
            value = f'[{cls}._lockstep_copy(x) for x in m._{name}]'
        else:
            value = f'list(m._{name})'
        source.add(f'c._{name} = {value}')
    source.add('return c')
    return source


def compile_function(source: _Source, shared: dict):
    """Compile one generated function with ``shared`` plus the source's own globals."""
    namespace = {'array': array, 'ndarray': numpy.ndarray, 'zeros': numpy.zeros,
                 'to_array': to_array, 'to_fixed_array': to_fixed_array,
                 'check_items': check_items, 'check_messages': check_messages,
                 **shared, **source.globals}
    exec(compile(source.text(), '<lockstep message>', 'exec'), namespace)  # noqa: S102
    name = source.lines[0].split()[1].split('(')[0]
    return namespace[name]
