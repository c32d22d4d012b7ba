"""
Node, namespace and topic names as rcl validates, expands and remaps them.

* ``scan`` in namespace ``/`` → ``/scan``; in ``/robot1`` → ``/robot1/scan``;
* ``~/status`` is private: ``/robot1/node_name/status``; ``{node}`` and ``{ns}`` substitute;
* remap rules ``from:=to`` match the expanded name; ``__ns`` and ``__node`` rename the node
  (handled by the node).

Invalid names raise rclpy's InvalidNodeNameException / InvalidNamespaceException /
InvalidTopicNameException.
"""

from typing import Optional

from sim_bridge.lockstep.rclpy.exceptions import (
    InvalidNamespaceException, InvalidNodeNameException, InvalidTopicNameException)


def _alnum(char: str) -> bool:
    return char.isascii() and (char.isalnum() or char == '_')


def validate_node_name(name: str) -> None:
    """Raise InvalidNodeNameException unless ``name`` is a valid node name."""
    if not name:
        raise InvalidNodeNameException(name, 'node name must not be empty', 0)
    for index, char in enumerate(name):
        if not _alnum(char):
            raise InvalidNodeNameException(
                name, "node name must not contain characters other than alphanumerics or '_'",
                index)
    if name[0].isdigit():
        raise InvalidNodeNameException(name, 'node name must not start with a number', 0)


def _validate_path(exception: type, kind: str, name: str, extra: str) -> None:
    for index, char in enumerate(name):
        if not (_alnum(char) or char == '/' or char in extra):
            raise exception(name, f'{kind} must not contain characters other than '
                            f"alphanumerics, '_', '/'{', ' if extra else ''}{extra}", index)
    if '//' in name:
        raise exception(name, f'{kind} must not contain repeated forward slashes',
                        name.index('//'))
    if len(name) > 1 and name.endswith('/'):
        raise exception(name, f'{kind} must not end with a forward slash', len(name) - 1)
    offset = 0
    for token in name.split('/'):
        if token[:1].isdigit():
            raise exception(name, f'{kind} must not have a token that starts with a number',
                            offset)
        offset += len(token) + 1


def normalize_namespace(namespace: Optional[str]) -> str:
    """Return the absolute namespace rcl makes of ``namespace`` ('' → '/', 'ns' → '/ns')."""
    namespace = namespace or '/'
    namespace = namespace if namespace.startswith('/') else '/' + namespace
    _validate_path(InvalidNamespaceException, 'namespace', namespace, '')
    return namespace


def expand_topic_name(topic: str, node_name: str, namespace: str) -> str:
    """Expand ``topic`` for a node the way rcl_expand_topic_name does."""
    if not topic:
        raise InvalidTopicNameException(topic, 'topic name must not be empty', 0)
    _validate_path(InvalidTopicNameException, 'topic name', topic, '~{}')
    if '~' in topic[1:] or topic[:2] not in ('~', '~/') and topic.startswith('~'):
        raise InvalidTopicNameException(topic, "'~' must be alone or followed by '/'",
                                        topic.index('~'))
    if topic.startswith('~'):
        topic = namespace.rstrip('/') + '/' + node_name + topic[1:]
    topic = topic.replace('{node}', node_name).replace('{namespace}', namespace) \
        .replace('{ns}', namespace)
    if not topic.startswith('/'):
        topic = namespace.rstrip('/') + '/' + topic
    topic = topic.replace('//', '/')
    if '{' in topic or '}' in topic:
        raise InvalidTopicNameException(topic, 'unknown substitution', topic.index('{'))
    return topic


def remap_topic(topic: str, rules: list, node_name: str, namespace: str) -> str:
    """Apply the first remap rule ``(node key, from, to)`` whose ``from`` expands to ``topic``."""
    for _, source, target in rules:
        if not source.startswith('__') and \
                expand_topic_name(source, node_name, namespace) == topic:
            return expand_topic_name(target, node_name, namespace)
    return topic
