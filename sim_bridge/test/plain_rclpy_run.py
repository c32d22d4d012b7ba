"""
Run a node file under plain rclpy at real time, as ``python3 FILE``; keep what it publishes.

``python plain_rclpy_run.py FILE OUT.json TOPIC TYPE`` runs FILE as its ``__main__`` (nothing of
rclpy or the standard library patched) while an observer node, made in the same context as soon
as FILE's ``rclpy.init()`` made it, takes what is published on TOPIC (a message type
``package/msg/Type``). OUT.json gets the CDR bytes (hex) of each message, in the order they were
published. The differential tests (test_agent_differential.py) compare this with a stepped run.
"""

from importlib import import_module
import json
from pathlib import Path
import runpy
import sys
import threading
import time

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy

#: Wall seconds between two looks for FILE's context, and between two takes.
POLL_S = 0.001


class Observer:
    """A raw subscription to TOPIC in the default context, made once FILE initialised it."""

    def __init__(self, topic: str, type_name: str):
        package, _, kind = type_name.split('/')
        self.msg_type = getattr(import_module(f'{package}.msg'), kind)
        self.topic = topic
        self.subscription = None
        self.taken: list[tuple[int, bytes]] = []
        self.lock = threading.Lock()

    def watch(self) -> None:
        """Wait for the default context, subscribe in it; take until it shuts down."""
        context = rclpy.utilities.get_default_context()
        while not context.ok():
            time.sleep(POLL_S)
        node = rclpy.create_node('_plain_rclpy_observer', enable_rosout=False,
                                 start_parameter_services=False)
        self.subscription = node.create_subscription(
            self.msg_type, self.topic, lambda _: None,
            QoSProfile(depth=10_000, reliability=ReliabilityPolicy.BEST_EFFORT), raw=True)
        context.on_shutdown(self.take)  # what came just before shutdown
        while context.ok():
            self.take()
            time.sleep(POLL_S)

    def take(self) -> None:
        """Take every message waiting, with its source timestamp."""
        with self.lock:
            while self.subscription is not None:
                try:
                    got = self.subscription.handle.take_message(self.msg_type, True)
                except Exception:  # noqa: B902 its context is gone: nothing more to take
                    return
                if got is None:
                    return
                data, info = got
                self.taken.append((info['source_timestamp'], data))


def main() -> None:
    """Run FILE (see the module's docstring)."""
    path, out, topic, type_name = sys.argv[1:5]
    observer = Observer(topic, type_name)
    threading.Thread(target=observer.watch, daemon=True).start()
    sys.argv = [path]
    sys.path.insert(0, str(Path(path).resolve().parent))
    try:
        runpy.run_path(path, run_name='__main__')
    finally:
        observer.take()
        Path(out).write_text(json.dumps([data.hex() for _, data in sorted(observer.taken)]))


if __name__ == '__main__':
    main()
