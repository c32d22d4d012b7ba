"""
Errors of the lockstep runtime itself, next to the rclpy exceptions it mirrors.

* :class:`MessageTypeError` — a publish Jazzy's C converter would abort on (an int in a float
  field, a numpy.float32, a wrong sub-message ...), naming node, topic, field and expected type.
* :class:`TopicTypeError` — two endpoints disagree on a topic's message type.
* :class:`NodeError` — an exception escaped a node's callback; ``run_until``/``spin`` raise it
  with the original as ``__cause__`` and ``.original``.
* :class:`StalledError` — ``spin`` was asked to run with nothing left that could ever happen.
* :class:`LockstepError` — base for misuse of the runtime (not installed, re-entrant spin ...).
"""

from typing import Any, Optional


class LockstepError(RuntimeError):
    """The lockstep runtime was used in a way it cannot honour."""


class StalledError(LockstepError):
    """spin() has no timer, no pending message and no horizon: it would wait forever."""


def describe_value(value: Any, limit: int = 60) -> str:
    """Name a value's type and show it briefly: ``int 0``, ``numpy.float32 1.5``."""
    kind = type(value)
    if hasattr(kind, '_lockstep_spec'):
        return kind._lockstep_spec.msgtype
    module = kind.__module__
    if module == 'builtins':
        name, text = kind.__qualname__, repr(value)
    else:
        # numpy 2 reprs scalars as np.float32(0.2); its str reads better next to the type.
        name, text = f'{module.split(".")[0]}.{kind.__name__}', str(value)
    if len(text) > limit:
        text = text[:limit - 3] + '...'
    return f'{name} {text}'


class MessageTypeError(TypeError):
    """A published message Jazzy's C converter would reject (the process would abort)."""

    def __init__(self, node_name: str, topic: str, field: Optional[str], expected: str,
                 value: Any):
        self.node_name = node_name
        self.topic = topic
        self.field = field
        self.expected = expected
        self.value = value
        if field is None:
            text = f'expected a {expected} message, got {describe_value(value)}'
        else:
            text = f"field '{field}' must be {expected}, got {describe_value(value)}"
        super().__init__(f"node '{node_name}' published {topic}: {text}")


class TopicTypeError(TypeError):
    """An endpoint asked for a topic under a message type other than the one it carries."""


class NodeError(Exception):
    """An exception raised by a node's timer or subscription callback."""

    def __init__(self, node_name: str, original: BaseException):
        self.node_name = node_name
        self.original = original
        if isinstance(original, MessageTypeError):
            text = str(original)
        else:
            text = f"node '{node_name}' raised {type(original).__name__}: {original}"
        super().__init__(text)
