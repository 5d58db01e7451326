"""One writer per store: an exclusive lock file that names its holder (pid and host).

The lock is a file created with O_EXCL. A lock whose holder process is gone (same host, pid not
alive) is stale and is taken over, so a crashed writer never blocks the store for good.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from pathlib import Path

from dancedata.errors import StoreError

LOCK_FILE = ".lock"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def read_holder(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None


def holder_is_stale(holder: dict | None) -> bool:
    """True when the holder ran on this host and its process no longer exists."""
    if holder is None:
        return True
    if holder.get("host") != socket.gethostname():
        return False
    pid = holder.get("pid")
    return not isinstance(pid, int) or not _pid_alive(pid)


class StoreLock:
    """Context manager holding ``STORE/.lock`` for the duration of one write."""

    def __init__(self, root: Path, *, wait: bool = False, timeout_s: float = 3600.0) -> None:
        self.path = Path(root) / LOCK_FILE
        self.wait = wait
        self.timeout_s = timeout_s
        self._held = False

    def acquire(self) -> None:
        deadline = time.monotonic() + self.timeout_s
        announced = False
        while True:
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = read_holder(self.path)
                if holder_is_stale(holder):
                    # Take over a dead holder's lock; remove-then-retry keeps O_EXCL the arbiter.
                    with contextlib.suppress(FileNotFoundError):
                        self.path.unlink()
                    continue
                who = f"pid {holder.get('pid')} on {holder.get('host')}" if holder else "?"
                if not self.wait:
                    raise StoreError(
                        f"store is locked by another writer ({who}); rerun with --wait to queue",
                        self.path.parent,
                    ) from None
                if time.monotonic() > deadline:
                    raise StoreError(
                        f"gave up waiting for the lock held by {who}", self.path
                    ) from None
                if not announced:
                    import sys

                    print(f"waiting for the store lock held by {who} ...", file=sys.stderr)
                    announced = True
                time.sleep(0.2)
                continue
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                json.dump(
                    {"pid": os.getpid(), "host": socket.gethostname(), "since": time.time()},
                    handle,
                )
            self._held = True
            return

    def release(self) -> None:
        if self._held:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()
            self._held = False

    def __enter__(self) -> StoreLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
