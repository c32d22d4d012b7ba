# noqa: A005 (rclpy has a module of this name; it is only aliased, never on sys.path)
"""
rclpy.logging for the lockstep runtime: named loggers with rcutils' severities and filters.

``node.get_logger().info('...')`` becomes a :class:`~sim_bridge.lockstep.runtime.LogRecord` at
the current sim time, handed to the runtime's log sink (stderr by default, as rcutils, in the
console format ``[INFO] [12.340000000] [scan_ahead]: ...``).

The filters are rclpy's, keyed by call site: ``once``, ``skip_first`` and
``throttle_duration_sec`` (throttled on sim time — the lockstep has no other clock; as with
rclpy's default system-clock throttle, the first call always logs). As in rclpy, a call site
remembers its first enabled call's severity, logger name and filters, and a later call that
changes any of them raises ValueError (``Logger severity cannot be changed between calls.``):
one line of code logging at several severities works here only if it works on the robot.
Levels are per logger name and inherited along the dotted hierarchy (default INFO,
``--log-level`` or ``set_level``).
"""

from enum import IntEnum
import sys

from sim_bridge.lockstep import loop
from sim_bridge.lockstep.loop import LogRecord

__lockstep__ = True

_FILTER_PARAMS = ('throttle_duration_sec', 'throttle_time_source_type', 'skip_first', 'once')


class LoggingSeverity(IntEnum):
    """Logging severities (rcutils)."""

    UNSET = 0
    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40
    FATAL = 50


class _CallSite:
    """
    One logging call site (rclpy keys it on the caller's code position).

    What its first call asked for (severity, logger name, filter parameters), which later calls
    must repeat, and the filters' state.
    """

    __slots__ = ('severity', 'name', 'filters', 'logged_once', 'first_skipped',
                 'last_logged_ns')

    def __init__(self, severity: 'LoggingSeverity', name: str, filters: dict):
        self.severity = severity
        self.name = name
        self.filters = filters
        self.logged_once = False
        self.first_skipped = False
        self.last_logged_ns = None

    def check_unchanged(self, severity: 'LoggingSeverity', name: str, filters: dict) -> None:
        """Raise ValueError as rclpy does when a call changes what the site's first asked for."""
        if severity != self.severity:
            raise ValueError('Logger severity cannot be changed between calls.')
        if name != self.name:
            raise ValueError('Logger name cannot be changed between calls.')
        if filters.keys() != self.filters.keys():
            raise ValueError('Requested logging filters cannot be changed between calls.')
        if filters != self.filters:
            raise ValueError('Logging filter parameters cannot be changed between calls.')


def _caller_position() -> tuple:
    frame = sys._getframe(1)
    while frame.f_code.co_filename == __file__:
        frame = frame.f_back
    return frame.f_code.co_filename, frame.f_lineno, frame.f_lasti


class RcutilsLogger:
    """A named logger (rclpy.impl.rcutils_logger.RcutilsLogger)."""

    def __init__(self, name: str = ''):
        self.name = name
        self.contexts: dict = {}

    def get_child(self, name: str) -> 'RcutilsLogger':
        """Logger ``<this name>.<name>``."""
        if not name:
            raise ValueError('Child logger name must not be empty.')
        return RcutilsLogger(name=f'{self.name}.{name}' if self.name else name)

    def set_level(self, level) -> None:
        """Set this logger's level (its children inherit it unless they have their own)."""
        loop.current().logger_levels[self.name] = LoggingSeverity(level)

    def get_effective_level(self) -> LoggingSeverity:
        """Return the level of the nearest ancestor (or this logger) that has one; default INFO."""
        levels = loop.current().logger_levels
        name = self.name
        while True:
            level = levels.get(name, LoggingSeverity.UNSET)
            if level != LoggingSeverity.UNSET:
                return LoggingSeverity(level)
            if not name:
                return LoggingSeverity.INFO
            name = name.rpartition('.')[0]

    def is_enabled_for(self, severity) -> bool:
        """Tell whether a message of ``severity`` would pass this logger's level."""
        return LoggingSeverity(severity) >= self.get_effective_level()

    def log(self, message, severity, **kwargs) -> bool:
        """Log ``message`` at ``severity``; False when the level or a filter suppressed it."""
        severity = LoggingSeverity(severity)
        name = kwargs.pop('name', self.name)
        unknown = set(kwargs) - set(_FILTER_PARAMS)
        if unknown:
            raise TypeError(f'parameter "{unknown.pop()}" is not one of the recognized logging '
                            f'options "{list(_FILTER_PARAMS)}"')
        if not isinstance(message, str):
            # rclpy hands the message to a C function taking a string.
            raise TypeError(f'rclpy_logging_rcutils_log(): incompatible function arguments: the '
                            f'message must be a str, got {type(message).__name__}')
        if not self.is_enabled_for(severity):
            return False
        filters = {key: value for key, value in kwargs.items() if value}
        position = _caller_position()
        site = self.contexts.get(position)
        if site is None:
            site = self.contexts[position] = _CallSite(severity, name, filters)
        else:
            site.check_unchanged(severity, name, filters)
        current = loop.current()
        if filters and not self._filters_pass(site, filters, current.now_ns):
            return False
        current.log(LogRecord(name, severity.name, current.now_ns, message))
        return True

    @staticmethod
    def _filters_pass(site: _CallSite, kwargs: dict, now_ns: int) -> bool:
        """Run rclpy's filters in its order (throttle, skip_first, once), updating state."""
        duration = kwargs.get('throttle_duration_sec')
        if duration:
            if site.last_logged_ns is not None and \
                    now_ns < site.last_logged_ns + duration * 1e9:
                return False
            site.last_logged_ns = now_ns
        if kwargs.get('skip_first') and not site.first_skipped:
            site.first_skipped = True
            return False
        if kwargs.get('once'):
            if site.logged_once:
                return False
            site.logged_once = True
        return True

    def debug(self, message, **kwargs) -> bool:
        """Log a message with DEBUG severity."""
        return self.log(message, LoggingSeverity.DEBUG, **kwargs)

    def info(self, message, **kwargs) -> bool:
        """Log a message with INFO severity."""
        return self.log(message, LoggingSeverity.INFO, **kwargs)

    def warning(self, message, **kwargs) -> bool:
        """Log a message with WARN severity."""
        return self.log(message, LoggingSeverity.WARN, **kwargs)

    def warn(self, message, **kwargs) -> bool:
        """Log a message with WARN severity (older spelling of :meth:`warning`)."""
        return self.log(message, LoggingSeverity.WARN, **kwargs)

    def error(self, message, **kwargs) -> bool:
        """Log a message with ERROR severity."""
        return self.log(message, LoggingSeverity.ERROR, **kwargs)

    def fatal(self, message, **kwargs) -> bool:
        """Log a message with FATAL severity."""
        return self.log(message, LoggingSeverity.FATAL, **kwargs)


def get_logger(name: str) -> RcutilsLogger:
    """Get the logger called ``name`` (must not be empty)."""
    if not name:
        raise ValueError('Logger name must not be empty.')
    return RcutilsLogger(name)


def set_logger_level(name: str, level) -> None:
    """Set the level of logger ``name``."""
    RcutilsLogger(name).set_level(level)


def get_logger_effective_level(name: str) -> LoggingSeverity:
    """Get the effective level of logger ``name``."""
    return RcutilsLogger(name).get_effective_level()


def initialize() -> None:
    """Nothing to initialise: records go to the runtime's log sink."""


def shutdown() -> None:
    """Nothing to shut down."""
