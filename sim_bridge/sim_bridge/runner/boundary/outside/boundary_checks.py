"""
The trusted side's bounds on what a node process says: its graph, and each message it sends.

What a node process says it is (its graph: nodes, their topics and parameters) makes the
trusted side create publishers and subscriptions; what it publishes is republished and
recorded. Each is bounded here, before anything is created or recorded: a graph or a message
over a cap is refused with one line naming the node (or topic) and the cap, as a
:class:`Refused`; the boundary fails that run with it (sim_bridge.runner.boundary.outside.link).

Caps (a lab's nodes use a handful of topics and parameters, messages of a few kB):

* MAX_NODES nodes in a process, MAX_TOPICS_PER_NODE topics (published and subscribed) per node,
  MAX_TOPICS topics the trusted side publishes or taps for one process, MAX_PARAMETERS per node;
  names (node, namespace, parameter) of MAX_NAME_CHARS at most;
* a message of MAX_MESSAGE_BYTES (its CDR bytes) at most, no string in it longer than
  MAX_STRING_BYTES and no array of more than MAX_ARRAY_ITEMS items.
"""

import math
from typing import Any

from sim_bridge.runner.boundary.wire.frames import valid_topic, valid_type

#: The message packages whose types may cross the boundary: the ones a lab's nodes use.
INTERFACE_PACKAGES = frozenset((
    'std_msgs', 'geometry_msgs', 'sensor_msgs', 'nav_msgs', 'tf2_msgs', 'rosgraph_msgs',
    'builtin_interfaces', 'visualization_msgs', 'rcl_interfaces', 'diagnostic_msgs'))
#: Most nodes a process may describe.
MAX_NODES = 100
#: Most topics one node may publish and subscribe to (together).
MAX_TOPICS_PER_NODE = 100
#: Most topics the trusted side publishes or subscribes to for one node process.
MAX_TOPICS = 200
#: Most parameters one node may declare.
MAX_PARAMETERS = 1000
#: Most characters of a node's name, namespace or parameter name.
MAX_NAME_CHARS = 256
#: Most bytes of one message (CDR); of one string in it; most items of one array in it.
MAX_MESSAGE_BYTES = 4 * 2 ** 20
MAX_STRING_BYTES = 64 * 2 ** 10
MAX_ARRAY_ITEMS = 2 ** 20


class Refused(ValueError):
    """A graph or message over a cap; the text says which node or topic, and the cap."""


def allowed_class(type_name: str) -> type | None:
    """Return the message class of ``type_name`` when its package may cross, else None."""
    from importlib import import_module
    package, _, kind = type_name.partition('/msg/')
    if package not in INTERFACE_PACKAGES:
        return None
    try:
        found = getattr(import_module(f'{package}.msg'), kind, None)
    except ImportError:
        return None
    return found if isinstance(found, type) and hasattr(found, 'get_fields_and_field_types') \
        else None


def _name(value: Any, what: str, node: str) -> str:
    """Return ``value`` as a name of at most MAX_NAME_CHARS; Refused if it is longer."""
    text = str(value)
    if len(text) > MAX_NAME_CHARS:
        raise Refused(f"node '{node[:80]}' has a {what} of {len(text)} characters: over the "
                      f'cap of {MAX_NAME_CHARS}')
    return text


def checked_node(entry: dict) -> dict:
    """
    Return one node of a process's graph, each field checked and bounded.

    Refused when a field is over its cap; TypeError, KeyError, ValueError or AttributeError
    when it is not a node's description.
    """
    name = _name(entry['name'], 'name', str(entry['name']))
    topics = {kind: [(t, n) for t, n in entry[kind] if valid_topic(t) and valid_type(n)]
              for kind in ('publishes', 'subscribes')}
    count = len(topics['publishes']) + len(topics['subscribes'])
    if count > MAX_TOPICS_PER_NODE:
        raise Refused(f"node '{name}' publishes or subscribes to {count} topics: over the cap "
                      f'of {MAX_TOPICS_PER_NODE} topics per node')
    parameters = list(entry['parameters'])
    values = dict(entry.get('values', {}))
    if max(len(parameters), len(values)) > MAX_PARAMETERS:
        raise Refused(f"node '{name}' declares {max(len(parameters), len(values))} "
                      f'parameters: over the cap of {MAX_PARAMETERS} parameters per node')
    return {
        'name': name, 'namespace': _name(entry['namespace'], 'namespace', name), **topics,
        'parameters': [_name(each, 'parameter name', name) for each in parameters],
        'values': {_name(each, 'parameter name', name): float(value)
                   for each, value in values.items()
                   if type(value) in (int, float) and math.isfinite(value)}}


def checked_graph(graph: Any) -> list[dict]:
    """
    Return a process's graph (a list of nodes, see :func:`checked_node`) if within the caps.

    Refused when it is over one (nodes, topics in all); TypeError and the like when malformed.
    """
    if not isinstance(graph, list):
        raise TypeError('a graph is a list')
    if len(graph) > MAX_NODES:
        raise Refused(f'its graph lists {len(graph)} nodes: over the cap of {MAX_NODES} nodes')
    nodes, topics = [], set()
    for entry in graph:
        nodes.append(checked_node(entry))
        topics.update(topic for kind in ('publishes', 'subscribes')
                      for topic, _ in nodes[-1][kind])
        if len(topics) > MAX_TOPICS:
            raise Refused(f"node '{nodes[-1]['name']}' brings its process's topics to "
                          f'{len(topics)}: over the cap of {MAX_TOPICS} topics per process')
    return nodes


def message_refusal(topic: str, type_name: str, data: bytes, msg: Any = None) -> str | None:
    """
    Return why a message is over a cap (its size, a string or an array in it), or None.

    ``data`` is its CDR bytes, ``msg`` the message rclpy read from them (needed only when
    ``data`` is longer than MAX_STRING_BYTES: no string or array can be over its cap before).
    """
    if len(data) > MAX_MESSAGE_BYTES:
        return (f'sent a {type_name} of {len(data)} bytes on {topic}: over the cap of '
                f'{MAX_MESSAGE_BYTES} bytes per message')
    if len(data) <= MAX_STRING_BYTES or msg is None:
        return None
    found = oversized_field(msg)
    if found is None:
        return None
    field, size, unit, cap = found
    return (f'sent a {type_name} on {topic} whose {field} holds {size} {unit}: over the cap '
            f'of {cap} {unit}')


def oversized_field(msg: Any, path: str = '') -> tuple[str, int, str, int] | None:
    """Return (field path, size, unit, cap) of the first string or array over its cap."""
    for field in msg.get_fields_and_field_types():
        value = getattr(msg, field)
        where = f'{path}{field}'
        if isinstance(value, str):
            if len(value) > MAX_STRING_BYTES:
                return where, len(value), 'characters', MAX_STRING_BYTES
        elif hasattr(value, 'get_fields_and_field_types'):
            found = oversized_field(value, f'{where}.')
            if found is not None:
                return found
        elif hasattr(value, '__len__'):
            if len(value) > MAX_ARRAY_ITEMS:
                return where, len(value), 'items', MAX_ARRAY_ITEMS
            for index, item in enumerate(value if isinstance(value, list) else ()):
                found = (oversized_field(item, f'{where}[{index}].')
                         if hasattr(item, 'get_fields_and_field_types') else
                         (f'{where}[{index}]', len(item), 'characters', MAX_STRING_BYTES)
                         if isinstance(item, str) and len(item) > MAX_STRING_BYTES else None)
                if found is not None:
                    return found
    return None
