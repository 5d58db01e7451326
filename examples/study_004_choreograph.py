"""The data side of a ChoreoGraph study (Au et al. 2022), end to end, on AIST++.

ChoreoGraph works on dance at 20 frames per second, in 4-second music segments that start and
end on music beats, with motion segments aligned to them by their motion beats (local minima of
joint speed) and re-tempoed (time-warped) onto the music's span. This script:

1. (``--demo``) writes a synthetic AIST++ folder (``dancedata synth aist``), or takes ``--raw``;
2. ingests it at 20 fps (``dancedata ingest aist --fps 20``: the 60 fps ingest, then
   ``resample``: SLERP rotations, linear positions);
3. computes joint positions and the motion beats (``featurize --motion-families
   positions,kinematics``: ``motion/motion_beats_mint``);
4. writes the beat and phrase tables (``segment --tables measures,beats,phrases``);
5. cuts the 4 s music segments and their beat-aligned motion spans
   (``compute.beat_units.choreograph_segments``) into ``segments.parquet``;
6. re-tempos the segment whose motion tempo differs most from its music's
   (``retime_positions``: the span between two motion beats resampled onto the span between two
   music beats) and renders it beside the original, with the music (``dancedata render
   --generated``);
7. with music, cuts that segment's log-mel (``mel96``, the study's input) from the 60 fps
   version, where the features run at 60 Hz: the contract keeps one audio row per motion frame,
   so the 20 fps version's features run at 20 Hz (sr 10240 Hz).

Every command is printed with its output; ``summary.json`` records the shapes and the re-tempo
factor. Run::

    python examples/study_004_choreograph.py --demo --out /tmp/choreograph-demo
    python examples/study_004_choreograph.py --raw AIST_ROOT --out /tmp/choreograph-real
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

FPS = 20.0
SEGMENT_S = 4.0


def run(*args: str) -> str:
    """Run ``dancedata ARGS``, print the command and what it printed; return its stdout."""
    print("$ dancedata " + " ".join(args), flush=True)
    proc = subprocess.run(
        [sys.executable, "-m", "dancedata.cli", *args], capture_output=True, text=True
    )
    for line in (proc.stdout + proc.stderr).strip().splitlines():
        print("  " + line)
    if proc.returncode != 0:
        raise SystemExit(f"dancedata {args[0]} failed (exit {proc.returncode})")
    return proc.stdout


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--demo", action="store_true", help="Synthetic AIST++ (2 sequences).")
    source.add_argument("--raw", type=Path, help="AIST++ annotation root (motions/, ...).")
    parser.add_argument("--out", type=Path, required=True, help="Output folder (created).")
    parser.add_argument("--no-video", action="store_true", help="Skip the MP4 render.")
    args = parser.parse_args(argv)

    import dancedata
    from dancedata.compute.beat_units import choreograph_segments, retime_positions

    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    store = out / "store"
    raw = args.raw
    if args.demo:
        raw = out / "raw"
        run("synth", "aist", str(raw), "--sequences", "2", "--seed", "0", "--force", "-q")
    has_music = any((raw / d).is_dir() and any((raw / d).iterdir()) for d in ("wav", "music"))
    ingest = ["ingest", "aist", str(raw), "--store", str(store), "--fps", f"{FPS:g}", "-q"]
    ingest += [] if has_music else ["--allow-missing-music"]
    ingested = json.loads(run(*ingest, "--json"))
    v60, v20 = ingested["counts"]["ingest_version"], ingested["version"]
    run("featurize", str(store), "--motion-families", "positions,kinematics", "--no-audio", "-q")
    run("segment", str(store), "--tables", "measures,beats,phrases", "--phrase-measures", "4", "-q")

    reader = dancedata.open_store(store)
    fps = float(reader.group_attrs("motion")["fps"])
    sequences = reader.table("sequences").to_pylist()
    beats = reader.table("beats").to_pylist()
    phrases = reader.table("phrases").to_pylist()
    motion_beats = reader.whole_array("motion/motion_beats_mint")
    positions = reader.whole_array("motion/positions").astype(np.float64)

    rows = []
    for seq in sequences:
        a, b = int(seq["frame_start"]), int(seq["frame_stop"])
        music_beats = [r["frame"] for r in beats if r["seq_id"] == seq["seq_id"]]
        seg = choreograph_segments(
            np.asarray(music_beats), np.flatnonzero(motion_beats[a:b]), fps, SEGMENT_S
        )
        for k in range(len(seg["music_start"])):
            rows.append(
                {"seq_id": seq["seq_id"], "segment": k, **{c: v[k].item() for c, v in seg.items()}}
            )
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.Table.from_pylist(rows), out / "segments.parquet")
    usable = [r for r in rows if np.isfinite(r["tempo_ratio"])]
    if not usable:
        raise SystemExit("no segment has a motion span between two motion beats")
    pick = max(usable, key=lambda r: abs(np.log(r["tempo_ratio"])))
    seq = next(s for s in sequences if s["seq_id"] == pick["seq_id"])
    a, n = int(seq["frame_start"]), int(seq["n_frames"])
    own = positions[a : a + n]
    src = (pick["motion_start"], pick["motion_stop"])
    dst = (pick["music_start"], pick["music_stop"])
    retimed = retime_positions(own, src, dst)
    factor = (src[1] - src[0]) / (dst[1] - dst[0])
    # the re-tempoed motion in the sequence's timeline: frames dst0..dst1 replaced
    timeline = own.copy()
    timeline[dst[0] : dst[1] + 1] = retimed
    generated = out / "generated"
    generated.mkdir(exist_ok=True)
    np.save(generated / f"{seq['seq_id']}.npy", timeline.astype(np.float32))
    np.savez(
        out / "retimed_segment.npz",
        positions=retimed.astype(np.float32),
        source_span=np.asarray(src),
        target_span=np.asarray(dst),
        factor=np.float64(factor),
    )
    print(
        f"segments: {len(rows)} beat-aligned 4 s segments in {len(sequences)} sequences "
        f"({len(beats)} beats, {len(phrases)} phrases at {fps:g} fps)"
    )
    print(
        f"re-tempo: {seq['seq_id']} motion frames {src[0]}..{src[1]} onto music beats "
        f"{dst[0]}..{dst[1]}: factor {factor:.4f} ({retimed.shape[0]} frames)"
    )
    video = None
    if not args.no_video:
        video = out / "retimed.mp4"
        render = ["render", str(store), seq["seq_id"], str(video), "--start", str(dst[0])]
        render += ["--stop", str(dst[1] + 1), "--generated", str(generated), "-q"]
        render += ["--width", "320", "--height", "240"]
        run(*render, *([] if has_music else ["--no-audio"]))
    mel = None
    if has_music:
        run(
            "featurize",
            str(store),
            "--version",
            v60,
            "--audio-families",
            "mel96",
            "--no-motion",
            "-q",
        )
        mel_reader = dancedata.open_store(store)
        music = {m["music_id"]: m for m in mel_reader.table("music").to_pylist()}
        row = next(
            s for s in mel_reader.table("sequences").to_pylist() if s["seq_id"] == seq["seq_id"]
        )
        k = round(mel_reader.group_attrs("audio")["fps"] / fps)  # 60 Hz rows per 20 fps frame
        first = music[row["music_id"]]["frame_start"] + int(row["audio_offset"])
        mel = np.asarray(mel_reader.zarr("audio/mel96")[first + k * dst[0] : first + k * dst[1]])
        np.save(out / "segment_mel96.npy", mel)
        print(f"music: mel96 of the segment at 60 Hz, {mel.shape} (the study's [96, 4*60] input)")
        run("checkout", str(store), reader.version)  # the 20 fps study version is the latest again
    summary = {
        "store": str(store),
        "versions": {"60fps": v60, "20fps": v20, "study": reader.version},
        "fps": fps,
        "sequences": len(sequences),
        "beats": len(beats),
        "phrases": len(phrases),
        "segments": len(rows),
        "picked": {"seq_id": seq["seq_id"], "motion_span": list(src), "music_span": list(dst)},
        "factor": factor,
        "retimed_shape": list(retimed.shape),
        "video": None if video is None else str(video),
        "mel96_shape": None if mel is None else list(mel.shape),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return summary


if __name__ == "__main__":
    main()
