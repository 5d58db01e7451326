"""Skeleton videos of stored sequences with their music: ``dancedata render``.

    from dancedata.viz.render import RenderOptions, render_sequence, skeleton_frames
    for rgb in skeleton_frames("data/stores/aist-demo", seq_id):   # (480, 640, 3) uint8
        ...
    render_sequence("data/stores/aist-demo", seq_id, "out.mp4", RenderOptions(view="side"))

What is drawn: the sequence's joints (:mod:`dancedata.viz.skeleton_source` says which array, and
:mod:`dancedata.compute.camera` how each kind of coordinates is put on screen: world 3-d joints
with their up axis up, video 2-d poses as the camera saw them), one frame per motion frame at the
sequence's own fps; a header with the time, the frame, the current measure (from the measures
table, 1-based) and beat (tracked beats of ``audio/beats`` counted from the measure's start, with
a dot lit for 0.12 s after each beat); a timeline with measure and beat ticks. ``compare``
sequences (same store, or ``STORE::SEQ`` from another) and ``generated`` motion files are drawn
in panels side by side, each with its own camera, frame k of a panel being the one at the same
time (``floor(t · fps_panel)``, held on its last frame when it is shorter).

Audio: the music of the sequence (``music`` table path), decoded with the project's audio reader
(PyAV for tracks only it reads), mono at 48 kHz, cut to the rendered frames: motion frame i is at
music time ``(audio_offset + i) / fps`` (CONTRACT.md §3), so the audio of frames
``[start, stop)`` is the music from ``(audio_offset + start) / fps`` for ``(stop - start) / fps``
seconds, padded with silence where the music ends first. Encoded as AAC in MP4 with H.264 video
(:mod:`dancedata.viz.render_encode`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.camera import ViewCamera, screen_axes
from dancedata.compute.camera import fit_view_camera as fit_camera
from dancedata.compute.camera import project_orthographic as project
from dancedata.errors import DancedataError, InputError
from dancedata.read.loader import DanceStore, open_store
from dancedata.viz.skeleton_draw import (
    FrameLayout,
    MusicTiming,
    SkeletonStyle,
    draw_background,
    draw_header,
    draw_skeleton,
)
from dancedata.viz.skeleton_source import SkeletonTrack, load_generated, load_skeleton

__all__ = [
    "MissingVizExtra",
    "Panel",
    "RenderOptions",
    "RenderResult",
    "SkeletonRenderer",
    "music_samples",
    "music_timing",
    "render_sequence",
    "render_still",
    "require_av",
    "skeleton_frames",
]

VIZ_EXTRA_HINT = "pip install 'dancedata[viz]'"
STORE_SEPARATOR = "::"


class MissingVizExtra(DancedataError):
    """PyAV (the ``viz`` extra) is not installed."""


def require_av(what: str = "dancedata render") -> None:
    """Raise :class:`MissingVizExtra` naming the extra when PyAV does not import."""
    try:
        import av  # noqa: F401
    except ImportError as exc:
        raise MissingVizExtra(
            f"{what} needs the optional 'viz' extra: {VIZ_EXTRA_HINT} (av is not importable: {exc})"
        ) from None


@dataclass(frozen=True)
class RenderOptions:
    """How to render (see the module docstring).

    Attributes:
        width, height: frame size in pixels (even numbers: yuv420p).
        view: front, side or top (2-d video poses: front only).
        start, stop: frame range of the sequence, half-open (None: its start / end).
        source: which joints to draw (:data:`dancedata.viz.skeleton_source.SOURCES`).
        smpl_model: SMPL model file for ``source="smpl"`` (and generated SMPL rotations).
        compare: more sequences, side by side: ``SEQ`` (same store) or ``STORE::SEQ``.
        generated: generated-motion files or folders (``<seq_id>.npy|npz|pkl``), side by side.
        generated_fps: frame rate of generated motion (default: the sequence's).
        generated_up_axis: up axis of generated motion (default y, as SMPL/AIST++).
        audio: mux the music in.
        version: store version to read (default latest).
    """

    width: int = 640
    height: int = 480
    view: str = "front"
    start: int | None = None
    stop: int | None = None
    source: str = "auto"
    smpl_model: str | Path | None = None
    compare: tuple[str, ...] = ()
    generated: tuple[str | Path, ...] = ()
    generated_fps: float | None = None
    generated_up_axis: str = "y"
    audio: bool = True
    version: str | None = None


@dataclass
class RenderResult:
    """What :func:`render_sequence` wrote."""

    out: str
    seq_id: str
    frames: int
    fps: float
    start: int
    stop: int
    width: int
    height: int
    view: str
    codec: str
    audio: bool
    audio_note: str | None
    panels: list[dict[str, Any]]
    render_s: float
    skipped: list[dict[str, str]] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return self.frames / self.fps

    @property
    def speed(self) -> float:
        """Seconds of video per second of rendering (> 1: faster than real time)."""
        return self.duration_s / self.render_s if self.render_s > 0 else float("inf")

    def as_dict(self) -> dict[str, Any]:
        return {**asdict(self), "duration_s": self.duration_s, "speed": self.speed}

    def message(self, command: str) -> str:
        if self.codec == "png":
            return (
                f"{command}: wrote {self.out} (frame {self.start} of {self.seq_id}, "
                f"{self.width}x{self.height}, {len(self.panels)} panel(s))"
            )
        sound = "with music" if self.audio else f"no audio ({self.audio_note})"
        return (
            f"{command}: wrote {self.out} ({self.frames} frames at {self.fps:g} fps, "
            f"{self.duration_s:.2f} s, {self.width}x{self.height}, {len(self.panels)} panel(s), "
            f"{sound}) in {self.render_s:.1f} s ({self.speed:.1f}x real time)"
        )


@dataclass(frozen=True)
class Panel:
    """One side-by-side panel: its joints and the camera that shows them."""

    track: SkeletonTrack
    camera: ViewCamera
    floor_px: float | None


def _open(store: str | Path | DanceStore, version: str | None) -> DanceStore:
    return store if isinstance(store, DanceStore) else open_store(store, version)


def music_timing(store: DanceStore, seq_id: str) -> MusicTiming:
    """Measures (measures table) and tracked beats (``audio/beats``) of ``seq_id``, in sequence
    frames; empty parts where the store has none."""
    starts = stops = np.zeros(0, dtype=np.int64)
    if store.has_table("measures"):
        rows = [r for r in store.measures.to_pylist() if r["seq_id"] == seq_id]
        rows.sort(key=lambda r: r["frame_start"])
        starts = np.array([r["frame_start"] for r in rows], dtype=np.int64)
        stops = np.array([r["frame_stop"] for r in rows], dtype=np.int64)
    beats = np.zeros(0, dtype=np.int64)
    if store.has_array("audio/beats") and store.audio_frames(seq_id) > 0:
        beats = np.flatnonzero(store.audio(seq_id, "beats")).astype(np.int64)
    per = (store.manifest.get("config") or {}).get("beats_per_measure")
    per = int(per) if isinstance(per, int | float) and per > 0 else None
    return MusicTiming(starts, stops, beats, per if starts.size else None)


def _decode_music(path: str, sr: int, seconds: float) -> np.ndarray:
    """Mono float32 at ``sr`` Hz of the first ``seconds`` of the music (at most)."""
    from dancedata.io.audio import load_mono

    try:
        return load_mono(path, sr, max_seconds=seconds)
    except InputError:
        from dancedata.io.av_audio import av_available, decode_audio_track

        if not av_available():
            raise
        pcm, native = decode_audio_track(path, seconds)  # e.g. a video's own audio track
        mono = pcm.mean(axis=0)
        if native != sr:
            import librosa

            mono = librosa.resample(mono, orig_sr=native, target_sr=sr, res_type="soxr_hq")
        return np.ascontiguousarray(mono, dtype=np.float32)


def music_samples(
    store: DanceStore, seq_id: str, start: int, stop: int, sr: int
) -> tuple[np.ndarray | None, str | None]:
    """Mono float32 music of frames ``[start, stop)`` at ``sr`` Hz, exactly
    ``round((stop - start) / fps · sr)`` samples (silence past the music's end), or
    (None, why) when the sequence has no music."""
    row = store.sequence(seq_id)
    if row.get("music_missing") or not row.get("music_id"):
        return None, "the sequence has no music"
    track = store.music_track(seq_id)
    if track is None or not track.get("path"):
        return None, f"music {row['music_id']} is not in the music table"
    path = Path(track["path"])
    if not path.is_file():
        raise InputError("music file of the sequence not found (moved since ingest?)", path)
    fps = float(row["fps"])
    offset = int(row.get("audio_offset") or 0)
    first = int(round((offset + start) / fps * sr))
    count = int(round((stop - start) / fps * sr))
    y = _decode_music(str(path), sr, (offset + stop) / fps + 1.0)
    out = np.zeros(count, dtype=np.float32)
    piece = y[max(first, 0) : max(first, 0) + count]
    out[: piece.size] = piece
    return out, None


def _floor_px(track: SkeletonTrack, camera: ViewCamera, view: str) -> float | None:
    if track.kind != "world" or view == "top":
        return None
    up = screen_axes(track.up_axis, view)[1]
    heights = np.asarray(track.positions, dtype=np.float64)[..., :3] @ up
    if not np.isfinite(heights).any():
        return None
    floor = float(np.nanmin(heights))
    return float(camera.centre_px[1] - camera.scale * (floor - camera.centre[1]))


def _compare_track(store: DanceStore, ref: str, options: RenderOptions) -> SkeletonTrack:
    if STORE_SEPARATOR in ref:
        other_path, seq = ref.rsplit(STORE_SEPARATOR, 1)
        other = open_store(other_path)
        track = load_skeleton(other, seq, options.source, options.smpl_model)
        name = Path(other_path.rstrip("/")).name
        return SkeletonTrack(**{**track.__dict__, "label": f"{name}: {track.label}"})
    return load_skeleton(store, ref, options.source, options.smpl_model)


class SkeletonRenderer:
    """Frames of one sequence (and its side-by-side panels) as BGR uint8 images."""

    def __init__(
        self, store: str | Path | DanceStore, seq_id: str, options: RenderOptions | None = None
    ) -> None:
        self.options = options = options or RenderOptions()
        self.store = _open(store, options.version)
        self.seq_id = seq_id
        main = load_skeleton(self.store, seq_id, options.source, options.smpl_model)
        tracks = [main]
        tracks += [_compare_track(self.store, ref, options) for ref in options.compare]
        tracks += [
            load_generated(
                path,
                seq_id,
                main,
                options.smpl_model,
                options.generated_fps,
                options.generated_up_axis,
            )
            for path in options.generated
        ]
        self.fps = main.fps
        self.n_total = main.n_frames
        start = 0 if options.start is None else int(options.start)
        stop = main.n_frames if options.stop is None else int(options.stop)
        if not 0 <= start < stop <= main.n_frames:
            raise InputError(
                f"frame range [{start}, {stop}) is not inside the sequence's {main.n_frames} "
                "frames (--start/--stop)"
            )
        self.start, self.stop = start, stop
        self.layout = FrameLayout(options.width, options.height, len(tracks))
        if options.width // len(tracks) < 64 or options.height < 120:
            raise InputError(
                f"{options.width}x{options.height} is too small for {len(tracks)} panel(s)"
            )
        self.panels = []
        for k, track in enumerate(tracks):
            camera = fit_camera(
                track.positions,
                track.kind,
                track.up_axis,
                options.view,
                self.layout.drawing_area(k),
            )
            self.panels.append(Panel(track, camera, _floor_px(track, camera, options.view)))
        self.styles = [SkeletonStyle.of(p.track.parents, p.track.joints) for p in self.panels]
        self.pixels = [project(p.camera, p.track.positions) for p in self.panels]
        self.timing = music_timing(self.store, seq_id)
        self.background = draw_background(
            self.layout,
            [p.track.label for p in self.panels],
            [p.floor_px for p in self.panels],
            self.timing,
            stop - start,
            start,
        )
        self._image = np.empty_like(self.background)

    @property
    def n_frames(self) -> int:
        return self.stop - self.start

    def panel_frame(self, k: int, frame: int) -> int:
        """Frame of panel k shown at main-sequence frame ``frame`` (same time, held at its end)."""
        track = self.panels[k].track
        if k == 0:
            return frame
        j = int(np.floor(frame / self.fps * track.fps + 1e-6))
        return min(max(j, 0), track.n_frames - 1)

    def frame(self, frame: int) -> np.ndarray:
        """The BGR image of main-sequence frame ``frame`` (a buffer reused by the next call)."""
        image = self._image
        np.copyto(image, self.background)
        for k in range(len(self.panels)):
            j = self.panel_frame(k, frame)
            draw_skeleton(image, self.pixels[k][j], self.styles[k])
        draw_header(
            image,
            self.layout,
            frame,
            self.n_total,
            self.fps,
            self.timing,
            frame - self.start,
            self.n_frames,
        )
        return image

    def frames(self) -> Iterator[np.ndarray]:
        """BGR images of the rendered range, in order (each a reused buffer)."""
        for frame in range(self.start, self.stop):
            yield self.frame(frame)


def skeleton_frames(
    store: str | Path | DanceStore, seq_id: str, options: RenderOptions | None = None
) -> Iterator[np.ndarray]:
    """(H, W, 3) uint8 RGB frames of ``seq_id`` (fresh arrays), as :func:`render_sequence`
    encodes them; for notebooks (``plt.imshow(next(frames))``)."""
    renderer = SkeletonRenderer(store, seq_id, options)
    for image in renderer.frames():
        yield image[:, :, ::-1].copy()


def render_still(
    store: str | Path | DanceStore,
    seq_id: str,
    out: str | Path,
    options: RenderOptions | None = None,
) -> RenderResult:
    """Write the frame at ``options.start`` (default: the first) as a PNG image, drawn as
    :func:`render_sequence` draws it, with the whole sequence on the timeline; no audio, no
    PyAV needed."""
    import dataclasses

    import cv2

    began = time.perf_counter()
    options = options or RenderOptions()
    renderer = SkeletonRenderer(store, seq_id, dataclasses.replace(options, start=0, stop=None))
    frame = int(options.start or 0)
    if not 0 <= frame < renderer.n_total:
        raise InputError(
            f"frame {frame} is not inside the sequence's {renderer.n_total} frames (--start)"
        )
    out = Path(out)
    if not out.parent.is_dir():
        raise InputError("the output folder does not exist", out.parent)
    if not cv2.imwrite(str(out), renderer.frame(frame)):
        raise InputError("cannot write the PNG image", out)
    return RenderResult(
        out=str(out),
        seq_id=seq_id,
        frames=1,
        fps=renderer.fps,
        start=frame,
        stop=frame + 1,
        width=options.width,
        height=options.height,
        view=options.view,
        codec="png",
        audio=False,
        audio_note="a still image",
        panels=[_panel_summary(p) for p in renderer.panels],
        render_s=time.perf_counter() - began,
    )


def _panel_summary(panel: Panel) -> dict[str, Any]:
    track = panel.track
    return {
        "label": track.label,
        "source": track.source,
        "kind": track.kind,
        "up_axis": track.up_axis,
        "fps": track.fps,
        "frames": track.n_frames,
    }


def render_sequence(
    store: str | Path | DanceStore,
    seq_id: str,
    out: str | Path,
    options: RenderOptions | None = None,
) -> RenderResult:
    """Render ``seq_id`` to the MP4 ``out`` with its music (module docstring); progress on
    stderr (``dancedata.progress``)."""
    require_av()
    from dancedata.exec.prefetch import prefetched
    from dancedata.progress import progress_bar
    from dancedata.viz.render_encode import AUDIO_SR, VideoWriter, bgr_to_i420, video_codec

    began = time.perf_counter()
    options = options or RenderOptions()
    renderer = SkeletonRenderer(store, seq_id, options)
    audio, note = (None, "--no-audio")
    if options.audio:
        audio, note = music_samples(renderer.store, seq_id, renderer.start, renderer.stop, AUDIO_SR)
    codec = video_codec()
    bar = progress_bar(f"render {seq_id}", renderer.n_frames, unit="frame")
    try:
        with VideoWriter(out, options.width, options.height, renderer.fps, audio, codec) as writer:
            # drawing and colour conversion (OpenCV, GIL released) in a thread, one step
            # ahead of the encoder: each I420 frame is a new array, the drawn image is reused
            drawn = (bgr_to_i420(image) for image in renderer.frames())
            for planes in prefetched(drawn, depth=4):
                writer.write_i420(planes)
                bar.update(1)
    finally:
        bar.close()
    return RenderResult(
        out=str(out),
        seq_id=seq_id,
        frames=renderer.n_frames,
        fps=renderer.fps,
        start=renderer.start,
        stop=renderer.stop,
        width=options.width,
        height=options.height,
        view=options.view,
        codec=codec,
        audio=audio is not None,
        audio_note=note,
        panels=[_panel_summary(p) for p in renderer.panels],
        render_s=time.perf_counter() - began,
    )
