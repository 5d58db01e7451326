"""featurize's music inputs, checked before use: each file is still what ingest recorded, and
how much of it the motions need is decoded, within a documented limit.

Verification (per track of the parent's music table): the recorded stamp (``size_bytes``,
``mtime_ns``) equal to the file's is the fast path; otherwise the file is hashed and its sha256
compared with the recorded one (a copied or touched file with the same content passes and gets
its new stamp recorded). A different hash stops featurize with one line naming the file::

    <path>: changed since ingest (sha256 1a2b… on disk, 9f8e… recorded for music mBR0); run
    ingest again, or pass --accept-changed-music to featurize to use the file as it is now

``--accept-changed-music`` (:attr:`FeaturizeOptions.accept_changed_music`) is the re-ingest on
request: the new sha256, stamp and header (sr, n_samples, channels, duration_s) go into the new
version's music table, and the new hashes into its config (``music_accepted_changes``), so the
fingerprint differs from a run on the old content. A file that is gone stops featurize too.

Decoded span: a track's features are needed up to frame ``N = max(audio_offset + n_frames)``
over its sequences. featurize decodes the first ``(N - 1) × hop + n_fft / 2 + 1`` samples (at
``cfg.sr``) plus :data:`DECODE_MARGIN_S` seconds, capped at the track's length: for a track no
longer than that (every AIST++ track, any music cut to its dance) the whole file, and the numbers
are those of the whole track. A longer track (a ten-hour file under a one-minute dance) gives
features for the span only. Local features (onset envelope, MFCC, mel, STFT) on the frames the
sequences use equal those of the whole file (tests/featurize/test_audio_limits.py); features that
normalise, estimate or search over the whole signal (chroma: its tuning estimate; beats: the
global tempo; onset peaks: max-normalised; NMFD; the repetition-based stems) see the span, which
the feature cache key and the music table (``decoded_s``) record. A track no sequence uses is
decoded whole.

Limit: a span longer than ``max_audio_seconds`` (default :data:`DEFAULT_MAX_AUDIO_SECONDS`,
``--max-audio-seconds``; 0 = no limit) is refused before any decoding: with the default
families 10 decoded minutes peak at 2.5 GB RSS per worker (measured; ~2 GB per 10 minutes).
"""

from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass, field
from typing import Any

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.errors import InputError
from dancedata.io.audio import audio_info
from dancedata.io.audio_decode import DEFAULT_MAX_AUDIO_SECONDS, DecodedAudio
from dancedata.io.music_file import FileStamp, sha256_of_path
from dancedata.store.untrusted import kind_of

ACCEPT_OPTION = "--accept-changed-music"
LIMIT_OPTION = "--max-audio-seconds"
DECODE_MARGIN_S = 30.0  # beyond the last needed frame: ≥ every family's context window


@dataclass(frozen=True)
class CheckedTrack:
    """One verified track: the sha256 of the content on disk, its stamp, and the seconds of it
    to decode from the start (``partial``: fewer than the whole file)."""

    music_id: str
    path: str
    sha256: str
    stamp: FileStamp
    span_s: float
    partial: bool
    changed: bool  # content differs from the recorded one (accepted on request)


@dataclass
class MusicInputs:
    """Every track of the parent's music table, verified, with the rows the new version writes."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    tracks: list[CheckedTrack] = field(default_factory=list)

    def config(self) -> dict[str, Any]:
        """Config entries (fingerprint): the new hashes of accepted changed files, if any."""
        changed = {t.music_id: t.sha256 for t in self.tracks if t.changed}
        return {"music_accepted_changes": changed} if changed else {}


def check_music_inputs(
    music: list[dict[str, Any]],
    sequences: list[dict[str, Any]],
    cfg: AudioFeatureConfig,
    *,
    accept_changed: bool = False,
    max_audio_seconds: float | None = DEFAULT_MAX_AUDIO_SECONDS,
) -> MusicInputs:
    """Verify every music row's file, plan its decoded span and apply the limit.

    Raises:
        InputError: naming the file, when it is gone, changed since ingest (unless
            ``accept_changed``), or its span passes ``max_audio_seconds`` (None or 0: no limit).
    """
    needed = frames_needed(sequences)
    out = MusicInputs()
    for row in music:
        row = dict(row)
        track = _verify(row, accept_changed)
        reach = needed.get(row["music_id"])
        span_s, partial = decode_span_s(reach, cfg, float(row["duration_s"]))
        if max_audio_seconds and span_s > max_audio_seconds:
            if reach is None:
                why = "the whole track: no sequence uses it"
            elif partial:
                why = f"its sequences reach {reach / cfg.fps:.1f} s, plus {DECODE_MARGIN_S:g} s"
            else:
                why = f"the whole track: its sequences end within {DECODE_MARGIN_S:g} s of it"
            raise InputError(
                f"music {row['music_id']} would decode {span_s:.0f} s of audio ({why}), over the "
                f"{max_audio_seconds:g} s limit; pass {LIMIT_OPTION} {math.ceil(span_s)} (or 0 for "
                "no limit) to allow it",
                row["path"],
            )
        track = CheckedTrack(
            track.music_id, track.path, track.sha256, track.stamp, span_s, partial, track.changed
        )
        row.update(sha256=track.sha256, decoded_s=span_s, **track.stamp.columns())
        out.rows.append(row)
        out.tracks.append(track)
    return out


def frames_needed(sequences: list[dict[str, Any]]) -> dict[str, int]:
    """Per music id, the feature frames its sequences reach: max(audio_offset + n_frames)."""
    out: dict[str, int] = {}
    for seq in sequences:
        music_id = seq.get("music_id")
        if not music_id or seq.get("music_missing"):
            continue
        reach = int(seq.get("audio_offset") or 0) + int(seq["n_frames"])
        out[music_id] = max(out.get(music_id, 0), reach)
    return out


def decode_span_s(
    frames: int | None, cfg: AudioFeatureConfig, duration_s: float
) -> tuple[float, bool]:
    """Seconds to decode from the start of a ``duration_s`` track whose features are needed up
    to frame ``frames`` (None: all of them), and whether that is less than the whole track."""
    if frames is None:
        return duration_s, False
    last_sample = (max(frames, 1) - 1) * cfg.hop_length + cfg.n_fft // 2 + 1
    span = last_sample / cfg.sr + DECODE_MARGIN_S
    if span >= duration_s:
        return duration_s, False
    return span, True


def _verify(row: dict[str, Any], accept_changed: bool) -> CheckedTrack:
    """Check one row's file against its recorded stamp and sha256; on an accepted change update
    ``row`` with the file's header as it is now."""
    path, music_id = str(row["path"]), str(row["music_id"])
    try:
        info = os.stat(path)
    except OSError:
        raise InputError(
            f"music file not found (recorded for music {music_id} at ingest); restore it, or run "
            "ingest again",
            path,
        ) from None
    if not stat.S_ISREG(info.st_mode):
        # a path from the store's music table: a FIFO would hang the hash, /dev/zero never end
        raise InputError(
            f"music path is {kind_of(info.st_mode)}, not a regular file (recorded for music "
            f"{music_id}); nothing was read from it",
            path,
        )
    stamp = FileStamp.of(info)
    recorded_sha = row.get("sha256")
    recorded_stamp = FileStamp.recorded(row.get("size_bytes"), row.get("mtime_ns"))
    if recorded_sha and stamp == recorded_stamp:
        return CheckedTrack(music_id, path, recorded_sha, stamp, 0.0, False, False)
    try:
        sha = sha256_of_path(path)
    except OSError as exc:
        raise InputError(f"cannot read music file: {exc.strerror or exc}", path) from None
    if not recorded_sha or sha == recorded_sha:
        return CheckedTrack(music_id, path, sha, stamp, 0.0, False, False)
    if not accept_changed:
        raise InputError(
            f"changed since ingest (sha256 {sha[:12]}… on disk, {recorded_sha[:12]}… recorded "
            f"for music {music_id}); run ingest again, or pass {ACCEPT_OPTION} to featurize to "
            "use the file as it is now",
            path,
        )
    info = audio_info(path)
    row.update(
        sr=info.sr,
        n_samples=info.n_samples,
        duration_s=info.duration_s,
        **({"channels": info.channels} if "channels" in row else {}),
    )
    return CheckedTrack(music_id, path, sha, stamp, 0.0, False, True)


def decode_checked(
    path: str, sr: int, sha256: str | None, max_seconds: float | None, res_type: str = "soxr_hq"
) -> DecodedAudio:
    """Decode ``path`` (at most ``max_seconds`` s) from the very bytes hashed here: the file is
    opened once, hashed through the open handle and decoded from it, so the content decoded is
    the content hashed (a file replaced meanwhile by a rename does not matter: the handle keeps
    the old one). Its sha256 must equal ``sha256`` (the verified hash, the feature cache key);
    and it must be the same file, with the same size and mtime, once decoded.

    Raises:
        InputError: naming the file, when it is gone, differs from ``sha256``, changed while it
            was decoded, or cannot be decoded (see :func:`decode_mono`).
    """
    from dancedata.io.audio_decode import decode_mono
    from dancedata.io.music_file import sha256_of_handle

    try:
        # O_NONBLOCK: a path swapped for a FIFO since it was verified must not block the open
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise InputError(f"cannot open music file: {exc.strerror or exc}", path) from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise InputError(
            f"music path is {kind_of(mode)}, not a regular file; nothing was read from it", path
        )
    os.set_blocking(fd, True)
    handle = os.fdopen(fd, "rb")
    with handle:
        before = _identity(os.fstat(handle.fileno()))
        actual = sha256_of_handle(handle)
        if sha256 and actual != sha256:
            raise InputError(
                f"changed since ingest (sha256 {actual[:12]}… on disk, {sha256[:12]}… "
                f"verified); run ingest again, or pass {ACCEPT_OPTION} to featurize",
                path,
            )
        decoded = decode_mono(handle, sr, path=path, max_seconds=max_seconds, res_type=res_type)
        after = _identity(os.fstat(handle.fileno()))
    try:
        now = _identity(os.stat(path))  # the librosa fallback decodes by path
    except OSError:
        now = None
    if after != before or now != before:
        raise InputError("changed while featurize decoded it; run featurize again", path)
    return decoded


def _identity(stat: os.stat_result) -> tuple[int, int, int, int]:
    return (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)
