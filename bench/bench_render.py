"""Render speed: a 60 s sequence at 640x480, against baselines run side by side.

Builds (in a temporary directory) a 60 s BVH store: the real CMU file 01_01.bvh (120 fps) with
its motion rows repeated to 60 s, ingested at 60 fps with the real 61 s track Vibe Ace as music
(--bpm 120), featurized (--stems none, for the tracked beats) and segmented. Then times:

* ``dancedata render``: :func:`dancedata.viz.render.render_sequence`, the whole command's work
  (store read, music decode, OpenCV drawing, H.264 + AAC encoding, progress bar);
* ``encode only``: the same writer fed the same number of pre-drawn frames and the same audio
  (the floor any renderer that encodes H.264 at this size pays);
* ``matplotlib per frame``: FuncAnimation-style drawing (one Line2D per bone updated, then
  ``canvas.draw()`` and the RGBA buffer read back) on :data:`MPL_FRAMES` frames, extrapolated
  to the sequence's frames; drawing only, no encoding (a lower bound for that approach).

Speed is seconds of video per second of rendering (> 1: faster than it plays).

Usage: .venv/bin/python bench/bench_render.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_DEFAULT_REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
MPL_FRAMES = 90
CLI = [sys.executable, "-m", "dancedata.cli"]


def long_bvh(source: Path, target: Path, seconds: float) -> int:
    """``source`` with its motion rows repeated to ``seconds`` at its 120 fps; frames written."""
    data = source.read_bytes()
    header_end = data.index(b"MOTION")
    body = data[data.index(b"\n", data.index(b"Frame Time")) + 1 :]
    rows = [r for r in body.split(b"\n") if r.strip()]
    frames = int(round(seconds * 120))
    reps = frames // len(rows) + 1
    motion = (rows * reps)[:frames]
    with target.open("wb") as f:
        f.write(data[:header_end])
        f.write(b"MOTION\nFrames: %d\nFrame Time: .0083333\n" % frames)
        f.write(b"\n".join(motion) + b"\n")
    return frames


def build_store(real: Path, work: Path, seconds: float) -> Path:
    bvh = work / "long_dance.bvh"
    long_bvh(real / "bvh" / "01_01.bvh", bvh, seconds)
    store = work / "store"
    music = real / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    steps = [
        ["ingest", "bvh", str(bvh), "--store", str(store), "--units", "0.056444", "--fps", "60",
         "--music", str(music), "--bpm", "120", "-q"],
        ["featurize", str(store), "--stems", "none", "-q"],
        ["segment", str(store), "-q"],
    ]  # fmt: skip
    for args in steps:
        subprocess.run(CLI + args, check=True)
    return store


def matplotlib_per_frame(track, n_frames: int) -> float:
    """Seconds per frame of FuncAnimation-style drawing at 640x480 (no encoding)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=100)
    pos = track.positions
    ax.set_xlim(np.nanmin(pos[..., 0]), np.nanmax(pos[..., 0]))
    ax.set_ylim(np.nanmin(pos[..., 1]), np.nanmax(pos[..., 1]))
    ax.set_aspect("equal")
    bones = [(j, p) for j, p in enumerate(track.parents) if p >= 0]
    lines = [ax.plot([], [], "-o", lw=2, ms=3)[0] for _ in bones]
    title = ax.set_title("")
    count = min(MPL_FRAMES, n_frames)
    start = time.perf_counter()
    for k in range(count):
        for line, (j, p) in zip(lines, bones, strict=True):
            line.set_data(pos[k, [j, p], 0], pos[k, [j, p], 1])
        title.set_text(f"frame {k}")
        fig.canvas.draw()
        np.asarray(fig.canvas.buffer_rgba())
    seconds = (time.perf_counter() - start) / count
    plt.close(fig)
    return seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    real = Path(os.environ.get("DANCEDATA_REAL_DATA", _DEFAULT_REAL))
    if not (real / "bvh" / "01_01.bvh").is_file():
        print(f"real data not found under {real}: skipped", file=sys.stderr)
        return 0
    from dancedata.progress import set_quiet
    from dancedata.viz.render import (
        RenderOptions,
        SkeletonRenderer,
        music_samples,
        render_sequence,
    )
    from dancedata.viz.render_encode import AUDIO_SR, VideoWriter

    set_quiet(True)
    with tempfile.TemporaryDirectory(prefix="bench-render-") as tmp:
        work = Path(tmp)
        began = time.perf_counter()
        store = build_store(real, work, args.seconds)
        built = time.perf_counter() - began
        print(f"store: {args.seconds:g} s BVH at 60 fps built in {built:.1f} s")
        import dancedata

        ds = dancedata.open_store(store)
        seq = ds.seq_ids()[0]

        cpu = time.process_time()
        result = render_sequence(store, seq, work / "render.mp4", RenderOptions())
        render_cpu = time.process_time() - cpu
        video_s = result.duration_s
        print(f"frames: {result.frames} at {result.fps:g} fps = {video_s:.1f} s of video, "
              f"640x480, {result.codec} + AAC, cores: {os.cpu_count()}")  # fmt: skip

        renderer = SkeletonRenderer(ds, seq, RenderOptions())
        audio, _ = music_samples(ds, seq, renderer.start, renderer.stop, AUDIO_SR)
        still = renderer.frame(0).copy()
        began, cpu = time.perf_counter(), time.process_time()
        with VideoWriter(work / "encode.mp4", 640, 480, renderer.fps, audio) as writer:
            for _ in range(renderer.n_frames):
                writer.write(still)
        encode_s, encode_cpu = time.perf_counter() - began, time.process_time() - cpu

        began, cpu = time.perf_counter(), time.process_time()
        for _ in renderer.frames():
            pass
        draw_s, draw_cpu = time.perf_counter() - began, time.process_time() - cpu

        cpu = time.process_time()
        mpl_s = matplotlib_per_frame(renderer.panels[0].track, renderer.n_frames) * result.frames
        mpl_cpu = (time.process_time() - cpu) / min(MPL_FRAMES, renderer.n_frames) * result.frames

    rows = [
        ("dancedata render (whole command)", result.render_s, render_cpu),
        ("  of which OpenCV drawing", draw_s, draw_cpu),
        ("encode only (same frames count + audio)", encode_s, encode_cpu),
        (f"matplotlib per frame, drawing only ({MPL_FRAMES} frames, extrap.)", mpl_s, mpl_cpu),
    ]
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    print(f"{'what':<62} {'wall s':>7} {'video s/s':>9} {'CPU s':>7}")
    for name, seconds, cpu_s in rows:
        print(f"{name:<62} {seconds:7.2f} {video_s / seconds:9.2f} {cpu_s:7.2f}")
    print(f"render vs matplotlib drawing: {mpl_s / result.render_s:.1f}x faster; "
          f"render vs encode only: {result.render_s / encode_s:.2f}x the time")  # fmt: skip
    ok = result.render_s < video_s
    print(f"goal (renders in less time than it plays): {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
