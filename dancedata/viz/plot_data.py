"""Gather what the sequence figure draws, as plain arrays on the sequence's own clock.

Time base (the x axis of every panel): motion frame f of the sequence is at t = f / fps seconds
from the sequence's first frame; audio feature row i of :meth:`DanceStore.audio` meets motion
frame i (CONTRACT.md), so it is at i / fps too. The waveform is the music file decoded by
:mod:`dancedata.io.audio` at its own sample rate, from track time ``audio_offset / fps`` s on
(``audio_offset`` is counted in feature frames), so sample k is at k / sr s of the sequence.

Nothing here draws (no matplotlib), so it can be tested and reused without the ``viz`` extra.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import DancedataError
from dancedata.read.loader import DanceStore
from dancedata.read.sequence_reader import _SequenceReader
from dancedata.store.reader import _VersionReader

STEM_ORDER: tuple[str, ...] = ("drums", "bass", "vocals", "other")
# Joints of the joint-angle panel when the skeleton has them (SMPL-24 names); otherwise the
# joints whose angles vary most are drawn instead.
DEFAULT_JOINTS: tuple[str, ...] = ("left_knee", "right_knee", "left_elbow", "right_elbow")


@dataclass(frozen=True)
class Waveform:
    """Min/max envelope of the decoded music over the sequence: one (lo, hi) pair per bin.

    ``times`` (s, sequence clock) are the bins' centres; ``sr`` the file's sample rate."""

    times: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    sr: int
    path: str


@dataclass(frozen=True)
class KeyframeTrack:
    """The keyframes of one (strategy, N, run) in this sequence, as sequence frames."""

    label: str
    strategy: str
    n_keyframes: int
    run_id: str
    frames: np.ndarray


@dataclass
class SequencePlotData:
    """Everything :func:`dancedata.viz.plot.sequence_figure` draws for one sequence.

    Frame arrays are motion frames of the sequence (0 = its first frame); ``None`` or empty
    means the store lacks it, with the reason in ``notes``."""

    seq_id: str
    version: str
    fps: float
    n_frames: int
    audio_frames: int
    meta: dict[str, Any]
    waveform: Waveform | None = None
    onset_env: np.ndarray | None = None
    onset_peak_frames: np.ndarray | None = None
    beat_frames: np.ndarray | None = None
    measure_bounds: np.ndarray | None = None
    stems: dict[str, np.ndarray] = field(default_factory=dict)
    nmfd: np.ndarray | None = None
    nmfd_components: tuple[str, ...] = ("kick", "snare", "hihat")
    keyframes: list[KeyframeTrack] = field(default_factory=list)
    joint_angles_deg: dict[str, np.ndarray] = field(default_factory=dict)
    euler_order: str = ""
    interior_angles_deg: dict[str, np.ndarray] = field(default_factory=dict)
    interior_source: str = ""
    notes: list[str] = field(default_factory=list)

    def seconds(self, frames: np.ndarray) -> np.ndarray:
        """Sequence frames → seconds on the figure's x axis: f / fps."""
        return np.asarray(frames, dtype=np.float64) / self.fps


def peak_envelope(y: np.ndarray, sr: float, n_bins: int) -> tuple[np.ndarray, ...]:
    """(times, lo, hi): min and max of ``y`` over ``n_bins`` equal bins, times at bin centres
    in seconds. Draws a waveform faithfully at figure resolution without plotting every
    sample."""
    y = np.asarray(y, dtype=np.float32)
    if y.size == 0:
        empty = np.zeros(0, np.float64)
        return empty, empty, empty
    n_bins = max(1, min(int(n_bins), y.size))
    edges = np.linspace(0, y.size, n_bins + 1).astype(np.int64)
    lo = np.minimum.reduceat(y, edges[:-1])
    hi = np.maximum.reduceat(y, edges[:-1])
    times = (edges[:-1] + edges[1:]) / 2.0 / float(sr)
    return times, lo.astype(np.float64), hi.astype(np.float64)


def measure_boundaries(rows: list[dict[str, Any]]) -> np.ndarray:
    """Sorted unique measure boundary frames: every measure's ``frame_start`` and
    ``frame_stop`` (so the end of the last measure is drawn too)."""
    bounds = {int(r["frame_start"]) for r in rows} | {int(r["frame_stop"]) for r in rows}
    return np.array(sorted(bounds), dtype=np.int64)


def _store(store: DanceStore | str | Path, version: str | None) -> DanceStore:
    return store if isinstance(store, DanceStore) else DanceStore(store, version)


def _decode_waveform(
    row: dict[str, Any], track: dict[str, Any], fps: float, n_bins: int
) -> Waveform:
    from dancedata.io.audio import load_mono

    path = Path(str(track["path"]))
    sr = int(track["sr"])
    y = load_mono(path, sr)
    start = int(round(int(row["audio_offset"]) / fps * sr))
    stop = start + int(round(int(row["n_frames"]) / fps * sr))
    times, lo, hi = peak_envelope(y[start:stop], sr, n_bins)
    return Waveform(times=times, lo=lo, hi=hi, sr=sr, path=str(path))


def read_keyframes(reader: _VersionReader | _SequenceReader) -> list[dict[str, Any]] | None:
    """Rows of the version's ``keyframes`` table (docs/EXPERIMENTS.md §2.5), or None without one."""
    if not reader.has_table("keyframes"):
        return None
    return reader.table("keyframes").to_pylist()


def keyframe_tracks(rows: list[dict[str, Any]], seq_id: str) -> list[KeyframeTrack]:
    """One track per (strategy, n_keyframes, run_id) holding keyframes of ``seq_id``, in the
    order strategies first appear; frames are ``frame_in_sequence``, sorted and unique."""
    groups: dict[tuple[str, int, str], list[int]] = {}
    for r in rows:
        if r["seq_id"] != seq_id:
            continue
        key = (str(r["strategy"]), int(r["n_keyframes"]), str(r.get("run_id") or ""))
        groups.setdefault(key, []).append(int(r["frame_in_sequence"]))
    runs_per_setting: dict[tuple[str, int], int] = {}
    for strategy, n, _ in groups:
        runs_per_setting[(strategy, n)] = runs_per_setting.get((strategy, n), 0) + 1
    tracks = []
    for (strategy, n, run_id), frames in groups.items():
        label = f"{strategy} N={n}"
        if runs_per_setting[(strategy, n)] > 1:
            label += f" ({run_id[:8]})"
        tracks.append(
            KeyframeTrack(label, strategy, n, run_id, np.unique(np.array(frames, np.int64)))
        )
    return tracks


def _euler_order(attrs: dict[str, Any]) -> str:
    order = attrs.get("order", "")
    if isinstance(order, list):
        unique = sorted(set(map(str, order)))
        return unique[0] if len(unique) == 1 else "per joint"
    return str(order)


def _joint_angles(
    store: DanceStore, seq_id: str, joints: tuple[str, ...], n_auto: int
) -> tuple[dict[str, np.ndarray], str]:
    euler = store.motion(seq_id, "euler")  # (F, J, 3) radians
    skeleton = store.group_attrs("motion").get("skeleton") or {}
    names = list(skeleton.get("joints") or [f"joint{j}" for j in range(euler.shape[1])])
    chosen = [names.index(j) for j in joints if j in names]
    if not chosen:
        spread = np.nanstd(euler, axis=(0, 2)) if euler.shape[0] else np.zeros(euler.shape[1])
        chosen = sorted(np.argsort(-np.nan_to_num(spread))[:n_auto].tolist())
    attrs = dict(store.zarr("motion/euler").attrs)
    angles = {
        names[j]: unwrap_degrees(np.degrees(euler[:, j, :].astype(np.float64))) for j in chosen
    }
    return angles, _euler_order(attrs)


def unwrap_degrees(angles: np.ndarray) -> np.ndarray:
    """(F, K) angles in degrees made continuous along frames (``np.unwrap``, period 360): a
    joint turning through ±180° is drawn as one curve instead of full-height spikes. NaN frames
    stay NaN and the finite frames either side of them are unwrapped as neighbours."""
    out = np.array(angles, dtype=np.float64, copy=True)
    for k in range(out.shape[1]):
        finite = np.isfinite(out[:, k])
        if finite.sum() > 1:
            out[finite, k] = np.unwrap(out[finite, k], period=360.0)
    return out


# Position arrays that interior joint angles are taken from when there is no motion/euler,
# best first; pose2d keeps its x, y channels only.
POSITION_ARRAYS: tuple[str, ...] = ("motion/positions", "motion/keypoints3d", "motion/pose2d")


def _interior_angles(
    store: DanceStore, seq_id: str, names: set[str]
) -> tuple[dict[str, np.ndarray], str]:
    from dancedata.viz.joint_angles import hinge_triples, interior_angles_deg

    for array in POSITION_ARRAYS:
        if array not in names:
            continue
        attrs = dict(store.zarr(array).attrs)
        skeleton = attrs.get("skeleton") or store.group_attrs("motion").get("skeleton")
        if not skeleton or "parents" not in skeleton:
            continue
        triples = hinge_triples(skeleton["joints"], skeleton["parents"])
        if not triples:
            continue
        points = store.motion(seq_id, array.split("/", 1)[1])
        if array == "motion/pose2d":
            points = points[..., :2]
        angles = interior_angles_deg(points, [t[1:] for t in triples])
        return {t[0]: angles[:, k] for k, t in enumerate(triples)}, array
    return {}, ""


def gather(
    store: DanceStore | str | Path,
    seq_id: str,
    *,
    version: str | None = None,
    joints: tuple[str, ...] = DEFAULT_JOINTS,
    waveform_bins: int = 4000,
) -> SequencePlotData:
    """Read one sequence's panels from ``store``. Missing pieces (no music, no featurize, no
    segment, no keyframes, music file moved) are left empty with a note, never an error; an
    unknown ``seq_id`` is a StoreError."""
    ds = _store(store, version)
    row = ds.sequence(seq_id)
    fps = float(row["fps"])
    data = SequencePlotData(
        seq_id=seq_id,
        version=ds.version,
        fps=fps,
        n_frames=int(row["n_frames"]),
        audio_frames=ds.audio_frames(seq_id),
        meta={k: row.get(k) for k in ("genre", "bpm", "dancer", "music_id", "source")},
    )
    names = set(ds.array_names())
    track = ds.music_track(seq_id) if data.audio_frames else None
    if track is None:
        data.notes.append("no music for this sequence")
    else:
        try:
            data.waveform = _decode_waveform(row, track, fps, waveform_bins)
        except DancedataError as exc:
            data.notes.append(f"waveform not drawn: {exc}")

    def audio(name: str) -> np.ndarray | None:
        if not data.audio_frames or f"audio/{name}" not in names:
            return None
        return ds.audio(seq_id, name)

    data.onset_env = audio("onset_env")
    peaks, beats = audio("onset_peaks"), audio("beats")
    data.onset_peak_frames = None if peaks is None else np.flatnonzero(peaks)
    data.beat_frames = None if beats is None else np.flatnonzero(beats)
    if data.audio_frames and data.onset_env is None:
        data.notes.append("no audio features (run `dancedata featurize`)")
    for stem in STEM_ORDER:
        curve = audio(f"stems/{stem}/onset_env")
        if curve is not None:
            data.stems[stem] = curve
    data.nmfd = audio("nmfd_drums")
    if data.nmfd is not None:
        components = ds.zarr("audio/nmfd_drums").attrs.get("components")
        if components:
            data.nmfd_components = tuple(map(str, components))
    if ds.has_table("measures"):
        rows = [r for r in ds.measures.to_pylist() if r["seq_id"] == seq_id]
        data.measure_bounds = measure_boundaries(rows)
    else:
        data.notes.append("no measures table (run `dancedata segment`)")
    kf_rows = read_keyframes(ds)
    if kf_rows:
        data.keyframes = keyframe_tracks(kf_rows, seq_id)
    if "motion/euler" in names:
        data.joint_angles_deg, data.euler_order = _joint_angles(ds, seq_id, joints, len(joints))
    else:
        data.interior_angles_deg, data.interior_source = _interior_angles(ds, seq_id, names)
    return data
