"""
ROS command-line arguments as rcl parses them, and rcl's YAML typing of parameter values.

``--ros-args`` opens a ROS section that runs to ``--`` or the end; inside it rcl knows
``-p/--param [node:]name:=value``, ``-r/--remap [node:]from:=to`` (``__ns``, ``__node``),
``--params-file FILE``, ``--log-level [logger:=]level``, and a few flags the runtime accepts
and ignores. Anything else in a ROS section is an unknown ROS argument (rclpy refuses to init).

Values are typed the way rcl_yaml_param_parser's ``get_value()`` does it: a plain (unquoted)
scalar is a bool if it is one of ``true/True/TRUE/yes/.../on`` (or the false words), an integer
if C's ``strtol(value, &end, 0)`` consumes it all (so ``010`` is 8 and ``0x1A`` is 26), a double
if ``strtod`` does (``1e3``, ``.5``, ``inf``, ``.nan``), else a string; quoted scalars are
strings; a flow sequence ``[1, 2]`` is an array whose items must all have one type.
"""

from dataclasses import dataclass, field
import math
import re
import sys
from typing import Any, Optional

import yaml

_TRUE_WORDS = {'Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON'}
_FALSE_WORDS = {'N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF'}
_YAML_SPECIAL_FLOATS = {'.nan': math.nan, '.NaN': math.nan, '.NAN': math.nan}
_YAML_SPECIAL_FLOATS.update({f'{sign}.{word}': (-math.inf if sign == '-' else math.inf)
                             for sign in ('', '+', '-') for word in ('inf', 'Inf', 'INF')})
_STRTOL = re.compile(r'[+-]?(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
_STRTOD_DECIMAL = re.compile(r'[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?')
_STRTOD_WORD = re.compile(r'[+-]?(inf|infinity|nan)', re.IGNORECASE)
_STRTOD_HEX = re.compile(r'[+-]?0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)([pP][+-]?\d+)?')

LOG_LEVELS = {'unset': 0, 'debug': 10, 'info': 20, 'warn': 30, 'error': 40, 'fatal': 50}
_FLAGS_WITH_VALUE = {'-p', '--param', '-r', '--remap', '--params-file', '--log-level',
                     '--log-config-file', '--log-file-name', '-e', '--enclave'}
_FLAGS = {f'--{state}-{what}-logs' for state in ('enable', 'disable')
          for what in ('rosout', 'stdout', 'external-lib')}


class UnknownROSArgsError(RuntimeError):
    """A ``--ros-args`` section holds arguments rcl does not know (rclpy refuses to init)."""


class InvalidROSArgsError(RuntimeError):
    """A ROS argument rcl knows but cannot parse (e.g. ``-p name`` without ``:=``)."""


@dataclass
class RosArguments:
    """What rcl extracted from one argument list."""

    parameters: list = field(default_factory=list)     # (node key or None, name, value)
    params_files: list = field(default_factory=list)   # paths, in order
    remaps: list = field(default_factory=list)         # (node key or None, from, to)
    log_levels: dict = field(default_factory=dict)     # logger name ('' = default) → severity


def _strtol(text: str) -> Optional[int]:
    """C ``strtol(text, &end, 0)`` when it consumes all of ``text``; None otherwise."""
    if not _STRTOL.fullmatch(text):
        return None
    digits = text.lstrip('+-')
    if digits[:2] in ('0x', '0X'):
        value = int(digits[2:], 16)
    elif digits.startswith('0'):
        value = int(digits, 8)
    else:
        value = int(digits)
    if text.startswith('-'):
        value = -value
    return value if -2 ** 63 <= value < 2 ** 63 else None   # ERANGE: not an int to rcl


def _strtod(text: str) -> Optional[float]:
    """C ``strtod`` when it consumes all of ``text`` without ERANGE; None otherwise."""
    if text in _YAML_SPECIAL_FLOATS:
        return _YAML_SPECIAL_FLOATS[text]
    if _STRTOD_WORD.fullmatch(text):
        return float(text)
    match = _STRTOD_HEX.fullmatch(text)
    try:
        if match:
            value = float.fromhex(text)
        else:
            match = _STRTOD_DECIMAL.fullmatch(text)
            if not match:
                return None
            value = float(text)
    except OverflowError:
        return None
    nonzero_mantissa = bool(match.group(1).strip('0.'))
    # strtod sets ERANGE on overflow and underflow; rcl then keeps the text as a string.
    if math.isinf(value) or 0.0 < abs(value) < sys.float_info.min or \
            (value == 0.0 and nonzero_mantissa):
        return None
    return value


def scalar_value(text: str, quoted: bool = False) -> Any:
    """Type one YAML scalar the way rcl does; ``quoted`` scalars are always strings."""
    if quoted:
        return text
    if text in _TRUE_WORDS:
        return True
    if text in _FALSE_WORDS:
        return False
    integer = _strtol(text)
    if integer is not None:
        return integer
    number = _strtod(text)
    return text if number is None else number


def _node_value(node: yaml.Node, where: str) -> Any:
    if isinstance(node, yaml.ScalarNode):
        if node.style is None and node.value == '':
            raise ValueError(f'no value for {where}')
        return scalar_value(node.value, quoted=node.style in ("'", '"'))
    if isinstance(node, yaml.SequenceNode):
        if not node.value:
            raise ValueError(f'{where}: rcl cannot give an empty array a type')
        items = [_node_value(item, where) for item in node.value]
        kinds = {type(item) for item in items}
        if len(kinds) != 1 or any(isinstance(item, list) for item in items):
            raise ValueError(f'{where}: sequence should be of same type, got {items}')
        return items
    raise ValueError(f'{where}: a parameter value must be a scalar or a sequence')


def yaml_value(text: str) -> Any:
    """Type the value of ``-p name:=value`` (YAML) with rcl's rules."""
    try:
        node = yaml.compose(text)
    except yaml.YAMLError as error:
        raise ValueError(f'invalid YAML value {text!r}: {error}') from None
    if node is None:
        raise ValueError(f'no value in {text!r}')
    return _node_value(node, repr(text))


def _split_rule(rule: str, what: str) -> tuple[Optional[str], str, str]:
    """Split ``[node:]name:=value``."""
    if ':=' not in rule:
        raise InvalidROSArgsError(f"Couldn't parse {what} rule: '{rule}'. Error: missing ':='")
    left, value = rule.split(':=', 1)
    node, _, name = left.rpartition(':')
    if not name:
        raise InvalidROSArgsError(f"Couldn't parse {what} rule: '{rule}'. Error: empty name")
    return node or None, name, value


def _apply(arguments: RosArguments, flag: str, value: str) -> None:
    if flag in ('-p', '--param'):
        node, name, text = _split_rule(value, 'parameter override')
        try:
            arguments.parameters.append((node, name, yaml_value(text)))
        except ValueError as error:
            raise InvalidROSArgsError(
                f"Couldn't parse parameter override rule: '{flag} {value}'. Error: {error}"
            ) from None
    elif flag in ('-r', '--remap'):
        node, source, target = _split_rule(value, 'remap')
        arguments.remaps.append((node, source, target))
    elif flag == '--params-file':
        arguments.params_files.append(value)
    elif flag == '--log-level':
        logger, _, level = value.rpartition(':=')
        if level.lower() not in LOG_LEVELS:
            raise InvalidROSArgsError(f"Couldn't parse log level: '{value}'")
        arguments.log_levels[logger] = LOG_LEVELS[level.lower()]


def parse(args: list) -> RosArguments:
    """Parse the ROS sections of ``args`` (a full argv: non-ROS arguments are skipped)."""
    arguments = RosArguments()
    unknown = []
    in_ros_section = False
    pending = None
    for arg in args:
        if pending is not None:
            _apply(arguments, pending, arg)
            pending = None
        elif arg == '--ros-args':
            in_ros_section = True
        elif not in_ros_section:
            continue
        elif arg == '--':
            in_ros_section = False
        elif arg in _FLAGS_WITH_VALUE:
            pending = arg
        elif arg not in _FLAGS:
            unknown.append(arg)
    if pending is not None:
        raise InvalidROSArgsError(f"Couldn't parse trailing {pending} flag: no value follows it")
    if unknown:
        raise UnknownROSArgsError(f'Found unknown ROS arguments: {unknown}')
    return arguments


def remove_ros_args(args: list) -> list:
    """Return ``args`` without ``--ros-args`` sections (rclpy.utilities.remove_ros_args)."""
    kept = []
    in_ros_section = False
    for arg in args:
        if arg == '--ros-args':
            in_ros_section = True
        elif in_ros_section and arg == '--':
            in_ros_section = False
        elif not in_ros_section:
            kept.append(arg)
    return kept


def node_key_matches(key: Optional[str], node_name: str, fully_qualified_name: str) -> bool:
    """Tell whether a rule's node key (``talker``, ``/ns/talker``, ``/**``) names this node."""
    if key is None:
        return True
    pattern = key if key.startswith('/') else '/' + key
    regex = re.escape(pattern).replace(r'\*\*', '.*').replace(r'\*', '[^/]*')
    return re.fullmatch(regex, fully_qualified_name) is not None or key == node_name


def _flatten(mapping: yaml.MappingNode, prefix: str, where: str) -> dict:
    values = {}
    for key_node, value_node in mapping.value:
        name = f'{prefix}{key_node.value}'
        if isinstance(value_node, yaml.MappingNode):
            values.update(_flatten(value_node, name + '.', where))
        else:
            values[name] = _node_value(value_node, f'{where}: {name}')
    return values


def params_file(path: str) -> dict:
    """Read a ROS 2 parameters file: ``{node key: {parameter name: value}}``."""
    with open(path, encoding='utf-8') as stream:
        root = yaml.compose(stream)
    result: dict = {}

    def walk(node: yaml.Node, keys: list):
        if not isinstance(node, yaml.MappingNode):
            raise ValueError(f'{path}: expected a mapping under {"/".join(keys) or "the root"}')
        for key_node, value_node in node.value:
            if key_node.value == 'ros__parameters':
                node_key = '/'.join(keys).replace('//', '/')
                result.setdefault(node_key, {}).update(_flatten(value_node, '', path))
            else:
                walk(value_node, keys + [key_node.value])
    if root is not None:
        walk(root, [])
    return result
