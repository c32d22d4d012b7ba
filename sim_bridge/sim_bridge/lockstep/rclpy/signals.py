"""
rclpy.signals for the lockstep runtime: the options exist, no handler is installed.

The lockstep loop runs in the caller's process and never waits on a signal, so installing or
uninstalling handlers changes nothing; the runtime's horizon ends a run, not Ctrl-C.
"""

from enum import IntEnum

__lockstep__ = True

_options = None


class SignalHandlerOptions(IntEnum):
    """Which signal handlers rclpy.init() installs."""

    NO = 0
    SIGINT = 1
    SIGTERM = 2
    ALL = 3

    def has_sigint(self) -> bool:
        """Return True if the instance is SIGINT or ALL."""
        return self in (SignalHandlerOptions.SIGINT, SignalHandlerOptions.ALL)

    def has_sigterm(self) -> bool:
        """Return True if the instance is SIGTERM or ALL."""
        return self in (SignalHandlerOptions.SIGTERM, SignalHandlerOptions.ALL)


def install_signal_handlers(options: SignalHandlerOptions = SignalHandlerOptions.ALL) -> None:
    """Remember ``options``; no handler is installed in the lockstep runtime."""
    global _options
    _options = SignalHandlerOptions(options)


def uninstall_signal_handlers() -> None:
    """Forget the remembered options."""
    global _options
    _options = None


def get_current_signal_handlers_options() -> SignalHandlerOptions:
    """Return the options given to the last install (NO when none)."""
    return SignalHandlerOptions.NO if _options is None else _options
