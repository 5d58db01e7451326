"""Per-track audio features cached by content, shared by every store, version and run.

featurize computes each audio family's arrays for a track once and keeps them here; a later run
(the same store re-featurized with other motion settings, a second store holding the same music,
a resumed run) loads them instead of recomputing. An entry is keyed by everything that decides
its numbers (:func:`cache_key`): the audio file's sha256, the family's name and config (for
OpenUnmix stems that includes each weight file's sha256), the FACT :class:`AudioFeatureConfig`
(frame rate, sample rate, hop, n_fft, ...), the track's BPM for families that use it (the
FACT beats), the dancedata version and the versions of the
libraries that compute it (librosa, numpy, scipy; torch, torchaudio and openunmix for OpenUnmix
stems). Change any of them and the key changes: a stale entry is never read, only left behind
for ``dancedata cache clear``.

Location: ``--cache-dir``, else ``$DANCEDATA_CACHE``, else ``$XDG_CACHE_HOME/dancedata/features``,
else ``~/.cache/dancedata/features``. Layout: ``ROOT/<key[:2]>/<key>.npz``, one file per
(track, family) holding the family's arrays plus a JSON header (``__meta__``: key, family,
music file, config, array shapes). Files are loaded with ``allow_pickle=False``.

Writes are atomic: each writer saves to its own temporary file in the entry's folder and renames
it onto the entry, so readers never see a partial file and parallel workers (or two featurize
runs) writing the same entry are safe — both write the same bytes and the last rename wins. A
file that does not load, or whose arrays do not match what the family declares, counts as a miss
and is removed. Loading an entry updates its modification time, so ``clear --older-than DAYS``
removes entries unused for DAYS.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import time
import uuid
import zipfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import installed_version
from dancedata.store.checksums import canonical_json

ENV_VAR = "DANCEDATA_CACHE"
META_KEY = "__meta__"
SUFFIX = ".npz"
TEMP_PREFIX = ".tmp-"
# Temporary files older than this (seconds) belong to a writer that died; clear removes them.
STALE_TEMP_SECONDS = 600.0


def default_cache_dir() -> Path:
    """``$DANCEDATA_CACHE``, else ``$XDG_CACHE_HOME/dancedata/features``, else
    ``~/.cache/dancedata/features``."""
    explicit = os.environ.get(ENV_VAR)
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "dancedata" / "features"


def library_versions(names: Iterable[str]) -> dict[str, str]:
    """Installed version of each distribution (``"absent"`` when not installed); no imports."""
    return {name: installed_version(name) or "absent" for name in names}


def cache_key(
    audio_sha256: str,
    family: str,
    family_config: Mapping[str, Any],
    audio_config: Mapping[str, Any],
    dancedata_version: str,
    libraries: Mapping[str, str],
    track: Mapping[str, Any] | None = None,
) -> str:
    """Hex sha256 over everything that decides a family's arrays for one track; ``track`` holds
    what the family reads about the track besides its samples (e.g. its known BPM)."""
    payload = {
        "audio_sha256": audio_sha256,
        "track": dict(track or {}),
        "family": family,
        "family_config": family_config,
        "audio_config": audio_config,
        "dancedata_version": dancedata_version,
        "libraries": libraries,
    }
    return hashlib.sha256(canonical_json(payload).encode()).hexdigest()


@dataclass(frozen=True)
class CacheEntry:
    """One cached (track, family): its file, size in bytes, last use (epoch s) and header."""

    key: str
    path: Path
    bytes: int
    last_used: float
    meta: dict[str, Any]

    @property
    def family(self) -> str:
        return str(self.meta.get("family", "?"))

    @property
    def source(self) -> str:
        return str(self.meta.get("music_id") or self.meta.get("source") or "?")


@dataclass(frozen=True)
class ClearReport:
    entries: int
    bytes: int
    temp_files: int


class FeatureCache:
    """The cache folder at ``root`` (created on first write)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root).expanduser()

    def __repr__(self) -> str:
        return f"FeatureCache({str(self.root)!r})"

    def path(self, key: str) -> Path:
        return self.root / key[:2] / f"{key}{SUFFIX}"

    # -- reading ---------------------------------------------------------------------------
    def load(
        self, key: str, expected: Mapping[str, tuple[tuple[int, ...], Any]]
    ) -> dict[str, np.ndarray] | None:
        """The arrays of entry ``key``, or None (a miss). ``expected`` maps each array path to
        its (row shape, dtype); an entry lacking one or disagreeing is removed and missed."""
        path = self.path(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                meta = _read_meta(data)
                names = meta["arrays"]
                arrays = {p: np.array(data[names[p]]) for p in expected}
        except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile, EOFError):
            self._discard(path)
            return None
        if meta.get("key") != key or not _matches(arrays, expected):
            self._discard(path)
            return None
        with contextlib.suppress(OSError):
            os.utime(path)  # last use, for clear --older-than
        return arrays

    def entries(self) -> list[CacheEntry]:
        """Every entry, oldest use first (headers read; arrays not)."""
        out: list[CacheEntry] = []
        if not self.root.is_dir():
            return out
        for path in self.root.glob(f"??/*{SUFFIX}"):
            if path.name.startswith(TEMP_PREFIX):
                continue
            try:
                stat = path.stat()
                with np.load(path, allow_pickle=False) as data:
                    meta = _read_meta(data)
            except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError):
                meta = {"family": "unreadable"}
                try:
                    stat = path.stat()
                except OSError:
                    continue
            out.append(CacheEntry(path.stem, path, stat.st_size, stat.st_mtime, meta))
        return sorted(out, key=lambda e: e.last_used)

    # -- writing ---------------------------------------------------------------------------
    def save(self, key: str, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any]) -> bool:
        """Store ``arrays`` under ``key`` atomically; False (and nothing left behind) when the
        folder cannot be written, which never fails a featurize run."""
        path = self.path(key)
        names = {p: f"a{i}" for i, p in enumerate(arrays)}
        header = {**meta, "key": key, "arrays": names, "created_at": time.time()}
        payload = {names[p]: np.ascontiguousarray(a) for p, a in arrays.items()}
        payload[META_KEY] = np.frombuffer(json.dumps(header, default=str).encode(), np.uint8)
        temp = path.with_name(f"{TEMP_PREFIX}{key}-{os.getpid()}-{uuid.uuid4().hex[:8]}{SUFFIX}")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(temp, "wb") as handle:
                np.savez(handle, **payload)
            os.replace(temp, path)
        except OSError:
            with contextlib.suppress(OSError):
                temp.unlink()
            return False
        return True

    def clear(self, older_than_days: float | None = None) -> ClearReport:
        """Remove every entry (or those unused for more than ``older_than_days`` days), and
        temporary files left by writers that died."""
        now = time.time()
        removed = removed_bytes = temps = 0
        if not self.root.is_dir():
            return ClearReport(0, 0, 0)
        for path in self.root.glob("??/*"):
            try:
                stat = path.stat()
            except OSError:
                continue
            age = now - stat.st_mtime
            if path.name.startswith(TEMP_PREFIX):
                if age > STALE_TEMP_SECONDS and _unlink(path):
                    temps += 1
                continue
            if path.suffix != SUFFIX:
                continue
            if older_than_days is not None and age <= older_than_days * 86400.0:
                continue
            if _unlink(path):
                removed += 1
                removed_bytes += stat.st_size
        for folder in self.root.glob("??"):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when empty
        return ClearReport(removed, removed_bytes, temps)

    def _discard(self, path: Path) -> None:
        _unlink(path)


def _read_meta(data: Any) -> dict[str, Any]:
    raw = np.asarray(data[META_KEY])
    if raw.dtype != np.uint8:
        raise ValueError("cache header is not bytes")
    meta = json.loads(bytes(raw).decode())
    if not isinstance(meta, dict) or not isinstance(meta.get("arrays"), dict):
        raise ValueError("cache header lacks its array list")
    return meta


def _matches(
    arrays: Mapping[str, np.ndarray], expected: Mapping[str, tuple[tuple[int, ...], Any]]
) -> bool:
    for name, (row_shape, dtype) in expected.items():
        values = arrays[name]
        if values.ndim != 1 + len(row_shape) or tuple(values.shape[1:]) != tuple(row_shape):
            return False
        if values.dtype != np.dtype(dtype):
            return False
    return True


def _unlink(path: Path) -> bool:
    try:
        path.unlink()
    except OSError:
        return False
    return True


def format_bytes(n: int) -> str:
    """Human-readable size: 1.5 MB, 320 kB, 12 B (powers of 1000)."""
    value = float(n)
    for unit in ("B", "kB", "MB", "GB"):
        if value < 1000 or unit == "GB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1000
    return f"{value:.1f} GB"
