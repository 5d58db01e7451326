"""Read a store back: tables, per-sequence arrays, aligned audio, the study views, measures.

    import dancedata
    store = dancedata.open_store("data/stores/aist-demo")
    store.motion("gBR_sBM_cAll_d01_mBR1_ch01", "rotmat")      # (F, 24, 3, 3)
    store.view("gBR_sBM_cAll_d01_mBR1_ch01", "fact_motion_225")  # (F, 225)
    for m in store.iter_measures(split="train"):               # crossmodal scheme by default
        m.motion, m.audio                                     # (frames, 225), (frames, 35)

Arrays are read whole into memory on first use and kept (a store's arrays are immutable), so
random access afterwards costs a numpy slice. For stores larger than memory, read slices through
:meth:`DanceStore.zarr` instead.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dancedata.errors import StoreError
from dancedata.store.layout import warn_once
from dancedata.store.reader import VersionReader

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr

    from dancedata.cameras import CameraSet
    from dancedata.windows import MeasureWindows

# Derived layouts (CONTRACT.md §3): name → ordered parts, each (kind, array, width or None).
VIEWS: dict[str, list[tuple[str, str]]] = {
    "fact_motion_225": [("zeros6", ""), ("motion", "trans"), ("motion", "rotmat")],
    "thesis_euler_75": [("motion", "trans"), ("motion", "euler")],
    "fact_audio_35": [
        ("audio", "onset_env"),
        ("audio", "mfcc"),
        ("audio", "chroma_cens"),
        ("audio", "onset_peaks"),
        ("audio", "beats"),
    ],
    "thesis_audio_22": [("audio", "mfcc"), ("audio", "onset_env"), ("audio", "onset_peaks")],
    # The thesis's 22-d M_full of each stem, stems in contract order: drums, bass, vocals, other.
    "thesis_stems_88": [
        ("audio", f"stems/{stem}/{feature}")
        for stem in ("drums", "bass", "vocals", "other")
        for feature in ("mfcc", "onset_env", "onset_peaks")
    ],
}
MOTION_VIEWS = ("fact_motion_225", "thesis_euler_75")
AUDIO_VIEWS = ("fact_audio_35", "thesis_audio_22", "thesis_stems_88")


@dataclass(frozen=True)
class MeasureWindow:
    """One measure of one sequence: frames [frame_start, frame_stop) of the sequence."""

    seq_id: str
    measure: int
    frame_start: int
    frame_stop: int
    motion: np.ndarray | None
    audio: np.ndarray | None
    genre_onehot: np.ndarray


class DanceStore:
    """A committed version of a store, opened for reading."""

    def __init__(self, path: str | Path, version: str | None = None) -> None:
        self.path = Path(path)
        self._reader = VersionReader(path, version)
        self.version = self._reader.version
        self._arrays: dict[str, np.ndarray] = {}

    def __repr__(self) -> str:
        return f"DanceStore({str(self.path)!r}, version={self.version!r})"

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
        return {row["seq_id"]: row for row in self.sequences.to_pylist()}

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
                f"no sequence {seq_id!r} in version {self.version}", self.path
            ) from None

    def seq_ids(self, split: str | None = None, scheme: str = "crossmodal") -> list[str]:
        """Sequence ids in store order; with ``split``, those of that split of ``scheme``."""
        if split is None:
            return list(self._seq_rows)
        found = self._split_members(split, scheme)
        if not found:  # loud, not empty: a known split without sequences gets a warning
            warn_once(f"{self.path}: {self.empty_split_reason(split, scheme)}")
        return found

    def _split_members(self, split: str, scheme: str) -> list[str]:
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
        layout, current, seen = self._reader.layout, self.version, set()
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

    def _full(self, name: str) -> np.ndarray:
        if name not in self._arrays:
            self._arrays[name] = np.asarray(self._reader.array(name)[...])
        return self._arrays[name]

    def motion(self, seq_id: str, name: str) -> np.ndarray:
        """``motion/<name>`` frames of one sequence, e.g. ``motion(seq, "quat")``."""
        row = self.sequence(seq_id)
        return self._full(f"motion/{name}")[row["frame_start"] : row["frame_stop"]]

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
        row = self.sequence(seq_id)
        n = self.audio_frames(seq_id)
        if n == 0:
            raise StoreError(self._no_music_reason(seq_id), self.path)
        track = self._music_rows[row["music_id"]]
        start = track["frame_start"] + int(row["audio_offset"])
        return self._full(f"audio/{name}")[start : start + n]

    def _no_music_reason(self, seq_id: str) -> str:
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

    def view(self, seq_id: str, name: str) -> np.ndarray:
        """A derived layout as float32 (frames, D): fact_motion_225, thesis_euler_75,
        fact_audio_35, thesis_audio_22 (CONTRACT.md §3) or thesis_stems_88 (the 22-d
        per stem: drums, bass, vocals, other; docs/STORE.md)."""
        if name not in VIEWS:
            raise StoreError(f"unknown view {name!r}; known: {sorted(VIEWS)}")
        self._require_view_arrays(name)
        parts: list[np.ndarray] = []
        n_frames = None
        for kind, array in VIEWS[name]:
            if kind == "zeros6":
                parts.append(None)  # type: ignore[arg-type]
                continue
            values = self.motion(seq_id, array) if kind == "motion" else self.audio(seq_id, array)
            values = values.reshape(values.shape[0], -1).astype(np.float32)
            parts.append(values)
            n_frames = values.shape[0] if n_frames is None else min(n_frames, values.shape[0])
        assert n_frames is not None
        filled = [np.zeros((n_frames, 6), np.float32) if p is None else p[:n_frames] for p in parts]
        return np.concatenate(filled, axis=1)

    def _require_view_arrays(self, name: str) -> None:
        """A clear error when a view's arrays are absent, saying whether featurize can help:
        rotation views need joint rotations, which poses from video (or any source with
        positions only) do not have."""
        missing = [
            f"{kind}/{array}"
            for kind, array in VIEWS[name]
            if kind != "zeros6" and not self._reader.has_array(f"{kind}/{array}")
        ]
        if not missing:
            return
        message = f"view {name!r} needs {', '.join(missing)}, which version {self.version} lacks"
        if name in MOTION_VIEWS and not self._reader.has_array("motion/axis_angle"):
            sources = sorted({str(r.get("source")) for r in self._seq_rows.values()})
            held = [n for n in self.array_names() if n.startswith("motion/")]
            message += (
                f": this store holds no joint rotations (sources: {', '.join(sources)}; motion "
                f"arrays: {', '.join(held) or 'none'}), so featurize cannot derive them; read "
                "the stored arrays with motion(seq_id, name) instead"
            )
        elif name not in MOTION_VIEWS and not self._music_rows:
            sources = sorted({str(r.get("source")) for r in self._seq_rows.values()})
            message += (
                f": this store has no music (sources: {', '.join(sources)}; 0 music tracks), so "
                "there are no audio features to compute; ingest the music with the motion "
                "(--music-dir, --music), or read motion only (audio=None)"
            )
        else:
            message += " (run `dancedata featurize`)"
        raise StoreError(message, self.path)

    # -- stems and NMFD ------------------------------------------------------------------------
    def _audio_or_hint(self, seq_id: str, name: str, hint: str) -> np.ndarray:
        if not self._reader.has_array(f"audio/{name}"):
            raise StoreError(f"version {self.version} has no audio/{name} ({hint})", self.path)
        return self.audio(seq_id, name)

    def stem_audio(self, seq_id: str, stem: str, feature: str = "onset_env") -> np.ndarray:
        """``audio/stems/<stem>/<feature>`` aligned to the sequence (see :meth:`audio`);
        ``stem`` in drums, bass, vocals, other; ``feature`` onset_env, mfcc or onset_peaks."""
        return self._audio_or_hint(
            seq_id, f"stems/{stem}/{feature}", "run `dancedata featurize` with a stem backend"
        )

    @property
    def stem_backend(self) -> dict[str, Any]:
        """Attrs of ``audio/stems``: ``backend`` and its full ``backend_config``."""
        return self._reader.group_attrs("audio/stems")

    def weighted_stem_onsets(
        self,
        seq_id: str,
        weights: dict[str, float] | None = None,
        normalize: bool = False,
    ) -> np.ndarray:
        """The thesis's weighted stem onset curve Σ_stem w_stem · onset_env_stem, (frames,)
        float32, from the stored per-stem onset envelopes (nothing extra is stored).
        ``weights`` maps stem → weight (default all 1; stems absent from it weigh 0 unless
        it is None); ``normalize`` divides each curve by its maximum over the sequence first."""
        from dancedata.compute.stem_features import DEFAULT_STEM_WEIGHTS, weighted_stem_onsets

        weights = DEFAULT_STEM_WEIGHTS if weights is None else weights
        unknown = sorted(set(weights) - set(DEFAULT_STEM_WEIGHTS))
        if unknown:
            raise StoreError(f"unknown stem(s) {unknown}; stems are {list(DEFAULT_STEM_WEIGHTS)}")
        onsets = {
            stem: self.stem_audio(seq_id, stem, "onset_env")
            for stem, weight in weights.items()
            if float(weight) != 0.0
        }
        if not onsets:
            return np.zeros(self.audio_frames(seq_id), dtype=np.float32)
        return weighted_stem_onsets(onsets, weights, normalize=normalize)

    def weighted_nmfd(
        self,
        seq_id: str,
        weights: dict[str, float] | None = None,
        normalize: bool = False,
    ) -> np.ndarray:
        """The thesis's weighted NMFD activation curve Σ_c w_c · activation_c over the kick,
        snare and hi-hat columns of ``audio/nmfd_drums``, (frames,) float32. ``weights`` maps
        component → weight (default all 1); ``normalize`` divides each column by its maximum
        over the sequence first."""
        from dancedata.compute.nmfd import weighted_nmfd_activation

        acts = self._audio_or_hint(
            seq_id, "nmfd_drums", "run `dancedata featurize` with the nmfd family"
        )
        return weighted_nmfd_activation(acts, weights, normalize=normalize)

    # -- cameras -------------------------------------------------------------------------------
    def cameras(self, seq_id: str) -> CameraSet:
        """The calibrated cameras of the sequence's AIST++ setting, in the view order of
        ``motion/keypoints2d``, with translation in metres (see :mod:`dancedata.cameras`)."""
        from dancedata.cameras import camera_set

        setting = self.sequence(seq_id).get("camera_setting")
        if not setting or not self._reader.has_table("cameras"):
            raise StoreError(f"sequence {seq_id} has no cameras in this store", self.path)
        return camera_set(self.table("cameras").to_pylist(), setting)

    def projection_matrices(self, seq_id: str) -> np.ndarray:
        """(9, 3, 4) float64 P = K [R | t] per view, for world points in metres (no lens
        distortion: use :meth:`cameras` with ``cv2.projectPoints`` to include it)."""
        return self.cameras(seq_id).projection

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

    def measure_windows(
        self,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
    ) -> MeasureWindows:
        """Fast random access to the measures of ``split`` as view windows (a data loader's
        sampler): ``windows[i]`` gives (motion, audio) in a few microseconds. The table and
        zarr lookups happen here, once; :class:`MeasureWindows` gets only arrays."""
        from dancedata.windows import MeasureWindows

        for view in (motion, audio):
            if view is not None and view not in VIEWS:
                raise StoreError(f"unknown view {view!r}; known: {sorted(VIEWS)}")
        rows = self.measure_rows(split, scheme)
        seq_start: dict[str, int] = {}
        audio_start: dict[str, int] = {}
        audio_frames: dict[str, int] = {}
        for seq_id in {r["seq_id"] for r in rows}:
            seq = self.sequence(seq_id)
            seq_start[seq_id] = int(seq["frame_start"])
            n_audio = self.audio_frames(seq_id) if audio else 0
            audio_frames[seq_id] = n_audio
            if n_audio:
                track = self._music_rows[seq["music_id"]]
                audio_start[seq_id] = int(track["frame_start"]) + int(seq["audio_offset"])
        if audio:  # measures not fully covered by audio are left out, as iter_measures does
            rows = [r for r in rows if r["frame_stop"] <= audio_frames[r["seq_id"]]]
        seq_ids = [r["seq_id"] for r in rows]
        starts = np.array([r["frame_start"] for r in rows], dtype=np.int64)
        motion_parts = self.view_parts(motion) if motion else None
        # Audio views are narrow (≤ 35 floats per frame): assemble the whole view once.
        audio_rows = None
        if audio:
            parts = self.view_parts(audio)
            audio_rows = np.concatenate([p for p in parts if p is not None], axis=1)
        audio_offsets = np.array([audio_start.get(s, 0) for s in seq_ids], dtype=np.int64)
        return MeasureWindows(
            seq_ids=seq_ids,
            measure=np.array([r["measure"] for r in rows], dtype=np.int64),
            length=np.array([r["frame_stop"] for r in rows], dtype=np.int64) - starts,
            motion_start=np.array([seq_start[s] for s in seq_ids], dtype=np.int64) + starts,
            audio_start=audio_offsets + starts,
            motion_parts=motion_parts,
            audio=audio_rows,
        )

    def view_parts(self, name: str) -> list[np.ndarray | None]:
        """The arrays of view ``name`` over the whole store, each as (rows, width) float32 (the
        cached whole arrays reshaped, copied only when not float32); None for FACT's six zero
        columns. Motion parts are indexed by global motion frame, audio parts by music frame."""
        self._require_view_arrays(name)
        parts: list[np.ndarray | None] = []
        for kind, array in VIEWS[name]:
            if kind == "zeros6":
                parts.append(None)
                continue
            values = self._full(f"{kind}/{array}")
            values = values.reshape(values.shape[0], -1)
            parts.append(values if values.dtype == np.float32 else values.astype(np.float32))
        return parts

    def iter_measures(
        self,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
    ) -> Iterator[MeasureWindow]:
        """Every measure of the sequences in ``split``, with the chosen motion and audio views
        sliced to the measure. With an audio view, measures not fully covered by audio are
        left out."""
        views: dict[str, np.ndarray] = {}
        for row in self.measure_rows(split, scheme):
            seq_id = row["seq_id"]
            if seq_id not in views:
                views.clear()
                views[seq_id] = np.empty(0)
                if motion:
                    views["motion"] = self.view(seq_id, motion)
                if audio:
                    if self.audio_frames(seq_id) == 0:
                        continue
                    views["audio"] = self.view(seq_id, audio)
            if audio and ("audio" not in views or views["audio"].shape[0] < row["frame_stop"]):
                continue
            s0, s1 = row["frame_start"], row["frame_stop"]
            yield MeasureWindow(
                seq_id=seq_id,
                measure=row["measure"],
                frame_start=s0,
                frame_stop=s1,
                motion=views["motion"][s0:s1] if motion else None,
                audio=views["audio"][s0:s1] if audio else None,
                genre_onehot=self.genre_onehot(seq_id),
            )


def open_store(path: str | Path, version: str | None = None) -> DanceStore:
    """Open ``version`` (default: the latest committed) of the store at ``path``."""
    return DanceStore(path, version)


def open_split(
    store: str | Path | DanceStore, version: str | None, split: str | None, scheme: str
) -> DanceStore:
    """The store opened (once), after checking that ``split`` names sequences: StoreError for
    an unknown split or one with no sequences, with what its split file listed."""
    opened = store if isinstance(store, DanceStore) else DanceStore(store, version)
    if split is not None and not opened._split_members(split, scheme):
        raise StoreError(opened.empty_split_reason(split, scheme), opened.path)
    return opened


def check_window_count(
    store: DanceStore, split: str | None, scheme: str, with_audio: bool, count: int
) -> None:
    """Loud, not empty (for the window datasets): a StoreError naming the reason when ``split``
    yields no windows, and a one-line warning on stderr when audio windows leave out sequences
    of the split that have no music."""
    seq_ids = store.seq_ids(split, scheme)  # an unknown split is an error there
    if split is not None and not seq_ids:
        raise StoreError(store.empty_split_reason(split, scheme), store.path)
    silent = [s for s in seq_ids if store.audio_frames(s) == 0] if with_audio else []
    where = f"split {split!r} of scheme {scheme!r}" if split else "the store"
    if count == 0:
        if silent and len(silent) == len(seq_ids):
            first = store._no_music_reason(silent[0])
            reason = (
                f"none of its {len(seq_ids)} sequences has music ({first}); read motion only "
                "with audio=None"
            )
        else:
            reason = f"none of its {len(seq_ids)} sequences is long enough for one window"
        raise StoreError(f"no windows in {where}, version {store.version}: {reason}", store.path)
    if silent:
        warn_once(
            f"{store.path}: audio windows leave out {len(silent)} of {len(seq_ids)} sequences of "
            f"{where} that have no music (e.g. {store._no_music_reason(silent[0])}); "
            "audio=None keeps them"
        )
