"""
The agent's end of the pipes to the trusted side: one frame out, its answer in.

Before a frame goes out, what the nodes printed so far is flushed (Python's streams and C's
stdio), so that the trusted side reads their lines before the frame that follows them.
"""

import ctypes
import os
import sys
import threading
from typing import Any

from sim_bridge.runner.boundary.wire.frames import encode, FrameDecoder, TRUSTED_KINDS


class Link:
    """The agent's end of the pipes: frames out on ``out_fd``, in on ``in_fd``."""

    def __init__(self, in_fd: int, out_fd: int):
        self.in_fd = in_fd
        self.out_fd = out_fd
        self.decoder = FrameDecoder(TRUSTED_KINDS)
        self.frames = []
        self.libc = ctypes.CDLL(None)
        #: Held by the thread that sends a frame until it has its answer.
        self.lock = threading.RLock()

    def request(self, kind: str, messages=(), **fields: Any):
        """Send a frame (see :meth:`send`) and return the trusted side's answer."""
        with self.lock:
            self.send(kind, messages, **fields)
            return self.receive()

    def send(self, kind: str, messages=(), **fields: Any) -> None:
        """Write one frame, after what the nodes printed so far (flushed first)."""
        with self.lock:
            self._send(kind, messages, **fields)

    def _send(self, kind: str, messages=(), **fields: Any) -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, AttributeError):  # closed or replaced by a node
                pass
        self.libc.fflush(None)  # C's stdio: rcutils' logger, a library's printf
        data = encode(kind, messages, **fields)
        while data:
            data = data[os.write(self.out_fd, data):]

    def receive(self):
        """Return the next frame from the trusted side; end this process when it is gone."""
        while not self.frames:
            data = os.read(self.in_fd, 2 ** 20)
            if not data:
                os._exit(0)  # the trusted side ended the run
            self.frames += self.decoder.feed(data)
        return self.frames.pop(0)
