"""The thin store reader: a committed version read as sequences, with nothing derived.

Private: users meet :class:`dancedata.read.loader.DanceStore` (``dancedata.open_store``), which
is this class with the views as methods. :class:`_SequenceReader` gives the tables, each
sequence's slice of the stored arrays, its audio aligned frame by frame, the split memberships,
genres and the measures table. It computes nothing: the paper views (:mod:`dancedata.read.views`),
the measure windows (:mod:`dancedata.read.views.measures`) and the AIST++ cameras
(:mod:`dancedata.read.views.cameras`) are built on top of it.

Arrays are read whole into memory on first use and kept (a store's arrays are immutable), so
random access afterwards costs a numpy slice. For stores larger than memory, read slices through
:meth:`_SequenceReader.zarr` instead.
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.layout import warn_once
from dancedata.store.reader import _VersionReader
from dancedata.store.seq_ids import seq_id_problem

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr


def store_locator(path: str | Path) -> str:
    """``path`` as a string that names the same store after pickling: URLs (``s3://…``) kept
    verbatim, local paths as ``str(Path(path))``."""
    text = str(path)
    return text if isinstance(path, str) and "://" in text else str(Path(text))


def known_ids(wanted: str, ids: list[str], shown: int = 5) -> str:
    """What an unknown id error lists: the count, then the ids closest to ``wanted`` (difflib),
    or the first ``shown`` ids when none is close: ``4 sequences; closest: gBR_sBM_c01, ...``."""
    import difflib

    count = f"{len(ids)} sequence{'' if len(ids) == 1 else 's'}"
    if not ids:
        return "it has no sequences"
    close = difflib.get_close_matches(str(wanted), ids, n=3, cutoff=0.6)
    if close:
        return f"{count}; closest: {', '.join(close)}"
    return f"{count}: {', '.join(ids[:shown])}{', ...' if len(ids) > shown else ''}"


class _SequenceReader:
    """A committed version of a store, read as sequences (the generic core of
    :class:`dancedata.read.loader.DanceStore`, the public reader; views type against this
    core so that they need not import the loader)."""

    def __init__(
        self, path: str | Path | StoreBackend | _VersionReader, version: str | None = None
    ) -> None:
        """``path``: the store as a path or URL (resolved here, once), its handle (a
        :class:`~dancedata.store.backend.StoreBackend`), or a version already open (then
        ``version`` must be None or that version's name)."""
        if isinstance(path, _VersionReader):
            if version is not None and version != path.version:
                raise StoreError(f"version {version} asked of an open {path.version}", path.path)
            self._reader = path
        else:
            self._reader = _VersionReader(make_backend(path), version)
        self.backend: StoreBackend = self._reader.layout.backend
        """The store's handle: hand it down to whatever else reads or writes this store."""
        given = path if isinstance(path, str | Path) else None
        self.path = Path(given if given is not None else str(self.backend.where()))
        self.locator = store_locator(given) if given is not None else self.backend.locator()
        """The store as given, as a string that reopens it: a local folder or a URL such as
        ``s3://bucket/prefix`` (``Path`` would turn ``s3://`` into ``s3:/``)."""
        self.version = self._reader.version
        self._arrays: dict[str, np.ndarray] = {}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({str(self.path)!r}, version={self.version!r})"

    # -- tables --------------------------------------------------------------------------------
    @property
    def manifest(self) -> dict[str, Any]:
        return self._reader.manifest

    def table(self, name: str) -> pa.Table:
        """A parquet table as a pyarrow Table (``.to_pandas()`` if pandas is installed)."""
        return self._reader.table(name)

    @property
    def sequences(self) -> pa.Table:
        return self.table("sequences")

    @property
    def music(self) -> pa.Table:
        return self.table("music")

    @property
    def measures(self) -> pa.Table:
        return self.table("measures")

    @property
    def splits(self) -> pa.Table:
        return self.table("splits")

    @cached_property
    def _seq_rows(self) -> dict[str, dict[str, Any]]:
        """The sequences table by ``seq_id``; StoreError naming the table for an id outside the
        character set of :mod:`dancedata.store.seq_ids` (ids name files: never a path or a
        pattern)."""
        rows: dict[str, dict[str, Any]] = {}
        for row in self.sequences.to_pylist():
            problem = seq_id_problem(row.get("seq_id"))
            if problem is not None:
                raise StoreError(f"sequences table: {problem}", self.path)
            rows[row["seq_id"]] = row
        return rows

    @cached_property
    def _music_rows(self) -> dict[str, dict[str, Any]]:
        if not self._reader.has_table("music"):
            return {}
        return {row["music_id"]: row for row in self.music.to_pylist()}

    def sequence(self, seq_id: str) -> dict[str, Any]:
        """The sequences-table row of ``seq_id``."""
        try:
            return self._seq_rows[seq_id]
        except KeyError:
            raise StoreError(
                f"no sequence {seq_id!r} in version {self.version} "
                f"({known_ids(seq_id, list(self._seq_rows))})",
                self.path,
            ) from None

    def music_track(self, seq_id: str) -> dict[str, Any] | None:
        """The music-table row of ``seq_id``'s track (``path``, ``frame_start``/``frame_stop``
        in global ``audio/*`` rows, ...), a copy; None when the sequence names no music or its
        ``music_id`` is not in this version's music table (or there is no music table)."""
        music_id = self.sequence(seq_id).get("music_id")
        track = None if music_id is None else self._music_rows.get(music_id)
        return None if track is None else dict(track)

    def has_table(self, name: str) -> bool:
        """Whether this version has the parquet table ``name``."""
        return self._reader.has_table(name)

    def sources(self) -> list[str]:
        """The sorted ``source`` values of the sequences (e.g. ``["aist"]``)."""
        return sorted({str(r.get("source")) for r in self._seq_rows.values()})

    @property
    def has_music(self) -> bool:
        """Whether this version has any music track."""
        return bool(self._music_rows)

    def seq_ids(self, split: str | None = None, scheme: str = "crossmodal") -> list[str]:
        """Sequence ids in store order; with ``split``, those of that split of ``scheme``."""
        if split is None:
            return list(self._seq_rows)
        found = self.split_members(split, scheme)
        if not found:  # loud, not empty: a known split without sequences gets a warning
            warn_once(f"{self.path}: {self.empty_split_reason(split, scheme)}")
        return found

    def split_members(self, split: str, scheme: str) -> list[str]:
        """Sequence ids of ``split`` of ``scheme``; StoreError for an unknown scheme or split
        (a typo is never an empty list)."""
        rows = self.splits.to_pylist()
        chosen = {r["seq_id"] for r in rows if r["scheme"] == scheme and r["split"] == split}
        if not any(r["scheme"] == scheme for r in rows):
            schemes = sorted({r["scheme"] for r in rows})
            raise StoreError(f"no split scheme {scheme!r} in this store (have {schemes})")
        found = [s for s in self._seq_rows if s in chosen]
        names = sorted({r["split"] for r in rows if r["scheme"] == scheme})
        if not found and split not in names and split not in self._split_file_counts(scheme):
            raise StoreError(
                f"no split {split!r} in scheme {scheme!r} (splits: {', '.join(names)})", self.path
            )
        return found

    def empty_split_reason(self, split: str, scheme: str = "crossmodal") -> str:
        """Why the known ``split`` of ``scheme`` has no sequences: what its split file listed."""
        listed = self._split_file_counts(scheme)
        text = f"split {split!r} of scheme {scheme!r} has no sequences in version {self.version}"
        counts = listed.get(split)
        if isinstance(counts, dict) and "listed" in counts:
            text += (
                f" (its split file lists {counts['listed']}, {counts.get('ignored', 0)} of them "
                f"on the ignore list, {counts.get('in_store', 0)} in the store)"
            )
        return text

    def _split_file_counts(self, scheme: str) -> dict[str, Any]:
        """Per split of ``scheme``, the counts ingest recorded for its split file ({} if none)."""
        layout, seen = self._reader.layout, set()
        current: str | None = self.version
        while current and current not in seen:
            seen.add(current)
            try:
                manifest = layout.read_manifest(current)
            except StoreError:
                return {}
            files = (manifest.get("counts") or {}).get("splits")
            if isinstance(files, dict):
                schemes = files.get("schemes") or {}
                return schemes.get(scheme) or {} if isinstance(schemes, dict) else {}
            current = manifest.get("parent")
        return {}

    # -- arrays --------------------------------------------------------------------------------
    def zarr(self, name: str) -> zarr.Array:
        """The zarr array itself, for slicing without loading it whole."""
        return self._reader.array(name)

    def array_names(self) -> list[str]:
        return self._reader.array_names()

    def has_array(self, name: str) -> bool:
        """Whether this version has the array ``name`` (e.g. ``"motion/rotmat"``)."""
        return self._reader.has_array(name)

    def group_attrs(self, name: str) -> dict[str, Any]:
        """The attributes of group ``name`` (e.g. ``"motion"``: skeleton, up_axis, units)."""
        return self._reader.group_attrs(name)

    def whole_array(self, name: str) -> np.ndarray:
        """The whole array ``name`` over every sequence (rows are global frames), read once
        and cached: later calls return the same numpy array, not a copy."""
        if name not in self._arrays:
            self._arrays[name] = np.asarray(self._reader.array(name)[...])
        return self._arrays[name]

    def motion(self, seq_id: str, name: str) -> np.ndarray:
        """``motion/<name>`` frames of one sequence, e.g. ``motion(seq, "quat")``."""
        row = self.sequence(seq_id)
        return self.whole_array(f"motion/{name}")[row["frame_start"] : row["frame_stop"]]

    def audio_frames(self, seq_id: str) -> int:
        """How many of the sequence's frames have audio (≤ n_frames)."""
        row = self.sequence(seq_id)
        if row.get("music_missing") or row.get("music_id") not in self._music_rows:
            return 0
        track = self._music_rows[row["music_id"]]
        available = track["frame_stop"] - track["frame_start"] - int(row["audio_offset"])
        return max(0, min(int(row["n_frames"]), available))

    def audio(self, seq_id: str, name: str) -> np.ndarray:
        """``audio/<name>`` aligned to the sequence: row i meets motion frame i. Runs for
        :meth:`audio_frames` rows; audio past the end of the motion is cut off."""
        n = self.audio_frames(seq_id)
        if n == 0:
            raise StoreError(self.no_music_reason(seq_id), self.path)
        start = self.audio_start(seq_id)
        return self.whole_array(f"audio/{name}")[start : start + n]

    def audio_to_track_end(self, seq_id: str, name: str) -> np.ndarray:
        """``audio/<name>`` from the row that meets the sequence's first motion frame to the end
        of its track: :meth:`audio` plus the track's frames past the last motion frame (mint
        scores generated motion against the whole track's beats; docs/METRICS.md, bas_mint)."""
        if self.audio_frames(seq_id) == 0:
            raise StoreError(self.no_music_reason(seq_id), self.path)
        track = self._music_rows[self.sequence(seq_id)["music_id"]]
        return self.whole_array(f"audio/{name}")[self.audio_start(seq_id) : track["frame_stop"]]

    def audio_start(self, seq_id: str) -> int:
        """The global row of ``audio/*`` arrays that meets the sequence's first motion frame:
        its track's first frame plus its ``audio_offset`` (0 when the sequence has no audio)."""
        if self.audio_frames(seq_id) == 0:
            return 0
        row = self.sequence(seq_id)
        track = self._music_rows[row["music_id"]]
        return int(track["frame_start"]) + int(row["audio_offset"])

    def no_music_reason(self, seq_id: str) -> str:
        """Why ``seq_id`` has no audio frames, in the words of the sequences table."""
        row = self.sequence(seq_id)
        music_id = row.get("music_id")
        if not self._music_rows:
            return f"sequence {seq_id} has no audio: this store has no music"
        if music_id is None:
            return f"sequence {seq_id} has no music_id (its source named no music)"
        if row.get("music_missing"):
            return f"sequence {seq_id} has no audio: its music {music_id} was missing at ingest"
        if music_id not in self._music_rows:
            return f"sequence {seq_id}: its music {music_id} is not in the music table"
        return f"sequence {seq_id} has no audio frames after its audio_offset"

    def music_summary(self) -> str | None:
        """None when every sequence has music, else a phrase saying how many have none."""
        without = [s for s in self._seq_rows if self.audio_frames(s) == 0]
        if not without:
            return None
        if not self._music_rows:
            return f"this store has no music ({len(self._seq_rows)} sequences, 0 tracks)"
        return f"{len(without)} of {len(self._seq_rows)} sequences have no music"

    # -- stems --------------------------------------------------------------------------------
    def audio_or_hint(self, seq_id: str, name: str, hint: str) -> np.ndarray:
        """:meth:`audio`, or a StoreError saying how to get ``audio/<name>`` (``hint``) when
        this version lacks it."""
        if not self._reader.has_array(f"audio/{name}"):
            raise StoreError(f"version {self.version} has no audio/{name} ({hint})", self.path)
        return self.audio(seq_id, name)

    def stem_audio(self, seq_id: str, stem: str, feature: str = "onset_env") -> np.ndarray:
        """``audio/stems/<stem>/<feature>`` aligned to the sequence (see :meth:`audio`);
        ``stem`` in drums, bass, vocals, other; ``feature`` onset_env, mfcc or onset_peaks."""
        return self.audio_or_hint(
            seq_id, f"stems/{stem}/{feature}", "run `dancedata featurize` with a stem backend"
        )

    @property
    def stem_backend(self) -> dict[str, Any]:
        """Attrs of ``audio/stems``: ``backend`` and its full ``backend_config``."""
        return self.group_attrs("audio/stems")

    # -- genres and measures -------------------------------------------------------------------
    @cached_property
    def genres(self) -> list[str]:
        """Genres present in this version, sorted: the columns of :meth:`genre_onehot`."""
        return sorted({r["genre"] for r in self._seq_rows.values() if r.get("genre")})

    def genre_onehot(self, seq_id: str) -> np.ndarray:
        """(G,) float32 one-hot over :attr:`genres` (its width follows the genres kept)."""
        out = np.zeros(len(self.genres), dtype=np.float32)
        genre = self.sequence(seq_id).get("genre")
        if genre in self.genres:
            out[self.genres.index(genre)] = 1.0
        return out

    def measure_rows(
        self, split: str | None = None, scheme: str = "crossmodal"
    ) -> list[dict[str, Any]]:
        """Measures-table rows of the sequences in ``split`` (all when None)."""
        if not self._reader.has_table("measures"):
            raise StoreError("this version has no measures table (run `dancedata segment`)")
        wanted = set(self.seq_ids(split, scheme))
        return [r for r in self.measures.to_pylist() if r["seq_id"] in wanted]
