"""
What the grader keeps to itself: the lock on its ``--out`` and the key that signs its results.

One grader at a time writes a ``--out`` folder: :func:`lock_out` takes an ``fcntl`` lock on
``--out/.grader.lock`` for the grader's lifetime (the kernel lets it go when the grader ends,
however it ends) and refuses a second grader in one line naming the first one's process id.

A run's saved ``result.json`` lets a later invocation resume without running it again; it lies
below ``--out``, where a run's own process could have written. :class:`ResultSigner` signs each
saved result with an HMAC-SHA256 key kept in the grader's private state folder
(``$XDG_STATE_HOME/sim_bridge``, default ``~/.local/state/sim_bridge``; mode 0700, the key file
0600), outside ``--out`` and out of every run's reach: a result edited, or copied from another
run's folder, does not match its signature and is run again.
"""

import fcntl
import hashlib
import hmac
import json
import os
from pathlib import Path
import secrets
from typing import Any, Callable, IO

#: The lock file in ``--out``, holding the process id of the grader that writes it.
LOCK_NAME = '.grader.lock'
#: The key file in the grader's private state folder.
KEY_NAME = 'result-signing.key'
KEY_BYTES = 32


class OutInUse(Exception):
    """Another grader writes the same ``--out``; the message names it in one line."""


def lock_out(out: Path) -> IO[bytes]:
    """
    Make ``out`` and take its lock for this process's lifetime; return the open lock file.

    Keep the returned file open as long as the grading lasts. OutInUse when another grader
    holds the lock; OSError (a read-only or full disk) when ``out`` cannot be written.
    """
    out.mkdir(parents=True, exist_ok=True)
    lock = open(out / LOCK_NAME, 'a+b', buffering=0)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.seek(0)
        holder = lock.read(32).decode('ascii', errors='replace').strip() or 'unknown'
        lock.close()
        raise OutInUse(f'--out {out} is in use by another grader (pid {holder}): wait for it '
                       'to finish, or give another --out') from None
    try:
        lock.truncate(0)
        lock.write(f'{os.getpid()}\n'.encode())
        lock.flush()
    except OSError:  # a full disk: the lock holds without its pid
        pass
    return lock


def state_folder(environ: dict[str, str] | None = None) -> Path:
    """Return the grader's private state folder (not made): ``$XDG_STATE_HOME/sim_bridge``."""
    environ = os.environ if environ is None else environ
    home_state = os.path.join(os.path.expanduser('~'), '.local', 'state')
    base = environ.get('XDG_STATE_HOME') or home_state
    return Path(base) / 'sim_bridge'


def signing_key(folder: Path | None = None) -> bytes:
    """
    Return the grader's result-signing key, made (random, KEY_BYTES long) on first use.

    The folder is made mode 0700 and the key file 0600; a key file that others can read is
    replaced by a new key (results signed with the old one are then run again).
    """
    folder = folder or state_folder()
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    path = folder / KEY_NAME
    try:
        if path.stat().st_mode & 0o077 == 0:
            key = path.read_bytes()
            if len(key) == KEY_BYTES:
                return key
    except FileNotFoundError:
        pass
    key = secrets.token_bytes(KEY_BYTES)
    partial = path.with_name(f'{KEY_NAME}.{os.getpid()}.partial')
    descriptor = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, 'wb') as file:
        file.write(key)
    os.replace(partial, path)
    return key


class ResultSigner:
    """Sign and check saved run results with the grader's private key (see the module)."""

    def __init__(self, key: bytes) -> None:
        self.key = key

    @classmethod
    def of_grader(cls, note: Callable[[str], None] = print) -> 'ResultSigner':
        """
        Return the signer with the grader's key (:func:`signing_key`).

        When the key cannot be kept (a read-only home), a key of this invocation only signs:
        ``note`` says that its results will not be resumed.
        """
        try:
            return cls(signing_key())
        except OSError as error:
            note(f'cannot keep the result-signing key in {state_folder()} '
                 f'({error.strerror or error}): no result of this invocation will be resumed')
            return cls(secrets.token_bytes(KEY_BYTES))

    def signature(self, folder: Path, saved: dict[str, Any]) -> str:
        """
        Return the signature of ``saved`` (a result without its signature) in ``folder``.

        The run's folder is signed with it: a result copied into another run's folder does
        not match there.
        """
        text = json.dumps({'folder': os.path.abspath(folder), 'saved': saved},
                          sort_keys=True, allow_nan=False)
        return hmac.new(self.key, text.encode(), hashlib.sha256).hexdigest()

    def signs(self, folder: Path, saved: dict[str, Any], signature: Any) -> bool:
        """Tell whether ``signature`` is this grader's of ``saved`` in ``folder``."""
        if not isinstance(signature, str):
            return False
        try:
            expected = self.signature(folder, saved)
        except ValueError:  # not strict JSON: no result the grader wrote
            return False
        return hmac.compare_digest(expected, signature)
