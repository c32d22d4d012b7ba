"""The errors a run ends with, and the user's Ctrl-C told from a node's KeyboardInterrupt."""

import signal
import threading


class RunError(Exception):
    """
    A run that could not start: unknown world, bad target or parameter, bad output folder.

    ``traceback`` is the node's part of the traceback when its code failed (a node file that
    fails to import), else None.
    """

    def __init__(self, message: str, traceback: str | None = None):
        super().__init__(message)
        self.traceback = traceback


class RunStopped(BaseException):
    """
    Raised into a run by whoever supervises it (the grader's watchdog); the text says why.

    A BaseException, so that a node's ``except Exception`` does not swallow it: the run ends
    as a failed one with its outputs written, naming the node code that was running.
    """


class OutputsFull(RunStopped):
    """
    A run stopped by its own outputs: the disk is full, or its recording reached its cap.

    The text says which, in one line; the run fails with it, and no other run.
    """


class UserInterrupt:
    """
    While the block runs, Ctrl-C (SIGINT) is noted in ``pressed`` and raises KeyboardInterrupt.

    So that the runner tells the user's Ctrl-C from a node raising KeyboardInterrupt itself.
    Outside the main thread (where Python delivers signals) it only notes nothing.
    """

    def __init__(self) -> None:
        self.pressed = False
        self.previous = None

    def __enter__(self) -> 'UserInterrupt':
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self.on_sigint)
        return self

    def on_sigint(self, signum, frame) -> None:
        self.pressed = True
        raise KeyboardInterrupt

    def __exit__(self, *exc_info) -> None:
        if self.pressed and self.previous is not None:
            # The outputs are written now: an impatient second Ctrl-C must not cut them short.
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        else:
            self.restore()

    def restore(self) -> None:
        """Give Ctrl-C back its handler from before the block (once the outputs are written)."""
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
            self.previous = None
