"""One writer per store: an exclusive lock file that names its holder.

``STORE/.lock`` is a small JSON file: ``pid``, ``host``, ``boot_id`` and ``start_ticks`` (which
run of the process, so a recycled pid is not mistaken for the holder), ``since``, ``command`` and
a random ``token``. It appears atomically, complete, through ``link(2)`` of a fully written
temporary file, so nobody ever reads a half-written lock.

A lock is *stale* when its holder ran on this host and is gone: the pid does not exist, the
machine has rebooted since (other ``boot_id``), or the pid now belongs to another process (other
``start_ticks``). A stale lock is taken over automatically, under a short ``flock`` on
``STORE/.lock.guard`` and only if the lock still holds the same token, so two writers breaking
the same stale lock cannot both win. A lock written on **another host** is never taken over:
this host cannot tell whether that writer still runs. ``dancedata unlock STORE --force`` (or
deleting ``STORE/.lock``) clears it once you know it is dead (:mod:`dancedata.store.unlock`,
on every backend).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import json
import os
import secrets
import socket
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError

LOCK_FILE = ".lock"
GUARD_FILE = ".lock.guard"
_POLL_S = 0.2
# link(2) failures that mean "this filesystem has no hard links" (then O_EXCL is used instead)
_NO_LINK_ERRNOS = {
    errno.EPERM,
    errno.EXDEV,
    errno.EMLINK,
    errno.ENOSYS,
    getattr(errno, "ENOTSUP", errno.EOPNOTSUPP),
    errno.EOPNOTSUPP,
}
_FRESH_S = 5.0


# -- who is this process -----------------------------------------------------------------------
def _read_text(path: str) -> str | None:
    try:
        with open(path, encoding="ascii", errors="replace") as handle:
            return handle.read()
    except OSError:
        return None


def boot_id() -> str | None:
    """This machine's boot id (Linux), or None where the platform has none."""
    text = _read_text("/proc/sys/kernel/random/boot_id")
    return text.strip() if text else None


def process_start_ticks(pid: int) -> int | None:
    """When process ``pid`` started, in clock ticks since boot (Linux /proc), or None."""
    text = _read_text(f"/proc/{pid}/stat")
    if not text or ")" not in text:
        return None
    fields = text.rsplit(")", 1)[1].split()
    try:
        return int(fields[19])  # field 22 of stat(5); fields[0] is field 3 (state)
    except (IndexError, ValueError):
        return None


def pid_alive(pid: int) -> bool:
    """True when a process with this pid exists (whoever owns it)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OverflowError:
        return False
    return True


def this_holder(command: str | None = None) -> dict[str, Any]:
    """The lock record of the calling process."""
    pid = os.getpid()
    return {
        "pid": pid,
        "host": socket.gethostname(),
        "boot_id": boot_id(),
        "start_ticks": process_start_ticks(pid),
        "since": time.time(),
        "command": command or " ".join(sys.argv[1:3]) or "python",
        "token": secrets.token_hex(8),
    }


# -- reading and judging a lock ----------------------------------------------------------------
def read_holder(path: Path) -> dict[str, Any] | None:
    """The lock record at ``path``; None when there is no lock file. Raises StoreError for a
    file that exists but is not a lock record (never written by dancedata: not auto-cleared)."""
    from dancedata.store.untrusted import LOCK_LIMIT, read_regular

    try:
        # a regular file of a lock record's size only: never through a link, from a FIFO or
        # from a device (a .lock linked to /dev/zero would be read forever)
        data = read_regular(path, LOCK_LIMIT)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise StoreError(
            f"unreadable lock file ({exc.strerror or exc}); remove it if no writer runs", path
        ) from None
    return parse_holder(data, path)


def parse_holder(data: bytes, where: str | Path) -> dict[str, Any]:
    """The lock record in ``data`` (the bytes of a lock file at ``where``, a path or a URL);
    StoreError naming ``where`` when they are not a dancedata lock record."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StoreError(
            f"unreadable lock file ({exc}); remove it if no writer runs", where
        ) from None
    try:
        holder = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        holder = None
    if not isinstance(holder, dict) or not isinstance(holder.get("pid"), int):
        raise StoreError(
            "lock file is not a dancedata lock record; if no writer runs, remove it "
            "(dancedata unlock STORE --force)",
            where,
        )
    return holder


def read_store_holder(backend: Any) -> dict[str, Any] | None:
    """The lock record of the store at ``backend`` (a :class:`~dancedata.store.backend.
    StoreBackend`, any kind), None when unlocked; StoreError naming the lock file when it is
    not a lock record or cannot be read."""
    from dancedata.store.untrusted import LOCK_LIMIT

    where = backend.where(LOCK_FILE)
    try:
        data = backend.read_small(LOCK_FILE, LOCK_LIMIT)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise StoreError(
            f"unreadable lock file ({exc.strerror or exc}); remove it if no writer runs", where
        ) from None
    return parse_holder(data, where)


@dataclass(frozen=True)
class LockState:
    """What a lock record means from this host: ``live``, ``stale`` or ``foreign``."""

    status: str
    reason: str


def judge_holder(holder: dict[str, Any]) -> LockState:
    """Whether the holder of a lock is alive (``live``), provably gone (``stale``) or on
    another host where we cannot tell (``foreign``)."""
    if holder.get("host") != socket.gethostname():
        return LockState("foreign", f"held from another host, {holder.get('host')!r}")
    pid = holder["pid"]
    recorded_boot = holder.get("boot_id")
    if recorded_boot and boot_id() and recorded_boot != boot_id():
        return LockState("stale", f"pid {pid} ran before this machine rebooted")
    if not pid_alive(pid):
        return LockState("stale", f"pid {pid} no longer exists")
    recorded_start = holder.get("start_ticks")
    current_start = process_start_ticks(pid)
    if recorded_start is not None and current_start is not None and recorded_start != current_start:
        return LockState("stale", f"pid {pid} now belongs to another process")
    return LockState("live", f"pid {pid} is running")


def holder_is_stale(holder: dict[str, Any] | None) -> bool:
    """True when the holder ran on this host and is provably gone (or there is no holder)."""
    return holder is None or judge_holder(holder).status == "stale"


def describe_holder(holder: dict[str, Any]) -> str:
    """``pid 123 on host vm (ingest aist, since 2024-05-01 12:00:00)``."""
    since = holder.get("since")
    when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(since)) if since else "?"
    command = holder.get("command") or "?"
    return f"pid {holder.get('pid')} on host {holder.get('host')} ({command}, since {when})"


# -- atomic create and guarded removal ---------------------------------------------------------
def _tmp_name(lock_name: str, record: dict[str, Any]) -> str:
    return f"{lock_name}.{record['host']}.{record['pid']}.{record['token']}.tmp"


def _remove_orphan_temps(root: Path) -> None:
    """Delete lock temporaries of writers of this host that died between writing and linking
    them (the name carries host and pid); others' are left alone."""
    host = socket.gethostname()
    for tmp in root.glob(f"{LOCK_FILE}.*.tmp"):
        parts = tmp.name[len(LOCK_FILE) + 1 : -len(".tmp")].rsplit(".", 2)
        if len(parts) != 3 or parts[0] != host or not parts[1].isdigit():
            continue
        if not pid_alive(int(parts[1])):
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()


def _create_exclusive(path: Path, record: dict[str, Any]) -> bool:
    """Make ``path`` hold ``record``, all at once, only if it does not exist. True on success."""
    tmp = path.with_name(_tmp_name(path.name, record))
    try:
        with open(tmp, "w", encoding="utf-8") as handle:
            json.dump(record, handle)
            handle.flush()
            os.fsync(handle.fileno())
    except BaseException:
        # full disk, read-only store, interrupt: leave no temporary behind, then report
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    try:
        os.link(tmp, path)
    except FileExistsError:
        return False
    except OSError as exc:
        if exc.errno not in _NO_LINK_ERRNOS:
            raise  # full, read-only, no permission: the fallback would fail the same way
        # Filesystems without hard links: O_EXCL create, then write (a reader may briefly see
        # an empty file, which read_holder reports rather than clears).
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                json.dump(record, handle)
        except BaseException:
            with contextlib.suppress(OSError):
                path.unlink()  # ours, half-written: never leave it to block other writers
            raise
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    return True


def _younger_than(path: Path, seconds: float) -> bool:
    try:
        return time.time() - path.stat().st_mtime < seconds
    except OSError:
        return True


@contextlib.contextmanager
def _guard(root: Path) -> Iterator[None]:
    """Serialise lock take-overs with ``flock`` on a file that is never deleted (released by the
    kernel if its holder dies, so it cannot go stale)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: best effort
        yield
        return
    fd = os.open(root / GUARD_FILE, os.O_CREAT | os.O_RDWR, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing releases the flock


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def remove_lock_if(
    root: Path, holder: dict[str, Any], before_delete: Callable[[], None] | None = None
) -> bool:
    """Delete ``root/.lock`` if it still carries ``holder``'s token. True if deleted.

    ``before_delete`` runs under the guard just before the file goes, so a message it prints
    ("took over a stale store lock") is in the log before the takeover, even if this process
    is killed right after it.
    """
    path = Path(root) / LOCK_FILE
    with _guard(Path(root)):
        try:
            current = read_holder(path)
        except StoreError:
            return False
        if current is None or current.get("token") != holder.get("token"):
            return False
        if before_delete is not None:
            before_delete()
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        return True


# -- the lock ----------------------------------------------------------------------------------
class StoreLock:
    """Context manager holding ``STORE/.lock`` for the duration of one write.

    ``wait=False`` fails at once with a message naming the holder; ``wait=True`` prints one
    "waiting for ..." line on stderr and polls until the lock is free (or ``timeout_s``).
    ``took_over`` records the stale lock this one replaced, if any.
    """

    def __init__(
        self,
        root: str | Path,
        *,
        wait: bool = False,
        timeout_s: float = 24 * 3600.0,
        command: str | None = None,
    ) -> None:
        self.root = Path(root)
        self.path = self.root / LOCK_FILE
        self.wait = wait
        self.timeout_s = timeout_s
        self.command = command
        self.record: dict[str, Any] | None = None
        self.took_over: list[dict[str, Any]] = []

    @property
    def held(self) -> bool:
        return self.record is not None

    def acquire(self) -> None:
        """Take the lock, taking over a stale one; wait or fail while another writer holds it."""
        if self.held:
            return
        deadline = time.monotonic() + self.timeout_s
        announced = False
        while True:
            record = this_holder(self.command)
            if _create_exclusive(self.path, record):
                self.record = record
                _remove_orphan_temps(self.root)
                return
            try:
                holder = read_holder(self.path)
            except StoreError:
                if _younger_than(self.path, _FRESH_S):
                    time.sleep(_POLL_S)  # being written by a writer without hard links
                    continue
                raise
            if holder is None:
                continue  # released between our attempt and our look
            state = judge_holder(holder)
            if state.status == "stale":
                notice = f"took over a stale store lock: {describe_holder(holder)}; {state.reason}"
                if remove_lock_if(self.root, holder, functools.partial(_say, notice)):
                    self.took_over.append(holder)
                continue
            message = self._busy_message(holder, state)
            if not self.wait:
                raise StoreError(message + "; rerun with --wait to queue", self.root)
            if time.monotonic() > deadline:
                raise StoreError(
                    f"gave up waiting after {self.timeout_s:.0f} s: {message}", self.root
                )
            if not announced:
                print(f"waiting for the store lock: {message} ...", file=sys.stderr, flush=True)
                announced = True
            time.sleep(_POLL_S)

    def _busy_message(self, holder: dict[str, Any], state: LockState) -> str:
        text = f"store is locked by another writer, {describe_holder(holder)}"
        if state.status == "foreign":
            text += (
                f"; it is {state.reason} and cannot be checked from here, so it is never taken "
                f"over automatically: if that writer is dead, run `dancedata unlock "
                f"{self.root} --force` (or delete {self.path})"
            )
        return text

    def release(self) -> None:
        """Give the lock back (only if it is still ours)."""
        if self.record is None:
            return
        with contextlib.suppress(StoreError):
            current = read_holder(self.path)
            if current is not None and current.get("token") == self.record["token"]:
                with contextlib.suppress(FileNotFoundError):
                    self.path.unlink()
        self.record = None

    def __enter__(self) -> StoreLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
