"""Study 001 (genre LSTM), the way back from the network: its output files into a store, smoothed,
hip-repaired, exported as BVH and rendered with the music.

The network itself is not run here. Its output is stood in for by the reference store's own
rotations as quaternions (the study's output representation), with the two defects the study
fixes after the network: frame-to-frame jitter (Gaussian, ``--jitter-deg`` per joint and frame)
and half turns of the hip about the vertical axis on a few runs of frames (``--flips`` runs),
written as ``<seq_id>.npz`` files holding ``quat`` (F, J, 4 wxyz) and ``trans`` (F, 3), the
layout ``dancedata ingest generated`` reads for any rig. Then, as a user types them:

    dancedata ingest generated OUT/outputs --store OUT/generated --like STORE \\
        --smooth-cutoff 6 --repair-hip-flips --json
    dancedata export bvh OUT/generated SEQ OUT/SEQ.bvh
    dancedata render OUT/generated SEQ OUT/SEQ.mp4 --stop 120

and a summary (``OUT/summary.json``, printed): per sequence, the flip runs planted and found,
and the mean angle between the stored root/joints and the clean reference before and after the
post-processing (degrees).

    python examples/study_001_genre_lstm.py STORE OUT [--sequences 2] [--seed 1]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import dancedata
from dancedata.errors import DancedataError

UP = {"y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def dancedata_cli(*args: object) -> subprocess.CompletedProcess:
    """``dancedata ARGS`` as a user runs it (this interpreter's package)."""
    done = subprocess.run(
        [sys.executable, "-m", "dancedata.cli", *map(str, args)],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise SystemExit(f"dancedata {' '.join(map(str, args))} failed:\n{done.stderr}")
    return done


def plant_flips(n_frames: int, runs: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """``runs`` disjoint [start, stop) runs of 1-12 frames, none touching frame 0 or 1."""
    spans: list[tuple[int, int]] = []
    slots = np.sort(rng.choice(np.arange(1, max(2, n_frames // 40)), size=runs, replace=False))
    for slot in slots:
        start = int(slot * 40 + rng.integers(2, 10))
        spans.append((start, min(n_frames - 1, start + int(rng.integers(1, 13)))))
    return spans


def model_output(axis_angle: np.ndarray, spans: list[tuple[int, int]], up: str,
                 jitter_deg: float, rng: np.random.Generator) -> np.ndarray:  # fmt: skip
    """(F, J, 4) wxyz quaternions: the clean rotations, jittered, the hip flipped on ``spans``."""
    f, j, _ = axis_angle.shape
    noise = rng.normal(0.0, np.radians(jitter_deg) / np.sqrt(3), (f, j, 3))
    rot = Rotation.from_rotvec(axis_angle.reshape(-1, 3)) * Rotation.from_rotvec(
        noise.reshape(-1, 3)
    )
    rotvec = rot.as_rotvec().reshape(f, j, 3)
    half = Rotation.from_rotvec(np.pi * np.asarray(UP[up]))
    for a, b in spans:
        rotvec[a:b, 0] = (half * Rotation.from_rotvec(rotvec[a:b, 0])).as_rotvec()
    quat = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_quat()[:, [3, 0, 1, 2]]
    return quat.reshape(f, j, 4)


def mean_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    ra, rb = Rotation.from_rotvec(a.reshape(-1, 3)), Rotation.from_rotvec(b.reshape(-1, 3))
    return float(np.degrees((ra * rb.inv()).magnitude()).mean())


def quat_to_axis_angle(quat: np.ndarray) -> np.ndarray:
    f, j, _ = quat.shape
    return Rotation.from_quat(quat.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_rotvec().reshape(f, j, 3)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("store", type=Path, help="reference store (AIST++, BVH, ...)")
    parser.add_argument("out", type=Path, help="output folder (created)")
    parser.add_argument("--sequences", type=int, default=2)
    parser.add_argument("--flips", type=int, default=2, help="flip runs planted per sequence")
    parser.add_argument("--jitter-deg", type=float, default=2.0)
    parser.add_argument("--cutoff", type=float, default=6.0, help="Butterworth cutoff, Hz")
    parser.add_argument("--render-frames", type=int, default=120)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)

    ref = dancedata.open_store(args.store)
    up = str(ref.group_attrs("motion").get("up_axis") or "y")
    outputs = args.out / "outputs"
    outputs.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    planted: dict[str, list[tuple[int, int]]] = {}
    clean: dict[str, np.ndarray] = {}
    raw: dict[str, np.ndarray] = {}
    for seq_id in ref.seq_ids()[: args.sequences]:
        axis_angle = np.asarray(ref.motion(seq_id, "axis_angle"), dtype=np.float64)
        trans = np.asarray(ref.motion(seq_id, "trans"), dtype=np.float64)
        spans = plant_flips(len(axis_angle), args.flips, rng)
        quat = model_output(axis_angle, spans, up, args.jitter_deg, rng)
        np.savez(outputs / f"{seq_id}.npz", quat=quat.astype(np.float32), trans=trans)
        planted[seq_id], clean[seq_id], raw[seq_id] = spans, axis_angle, quat

    store = args.out / "generated"
    ingested = json.loads(
        dancedata_cli(
            "ingest", "generated", outputs, "--store", store, "--like", args.store,
            "--smooth-cutoff", args.cutoff, "--repair-hip-flips", "--json",
        ).stdout
    )  # fmt: skip
    gen = dancedata.open_store(store)
    flips = ingested["counts"]["hip_flips"]["per_sequence"]
    sequences = {}
    for seq_id, spans in planted.items():
        stored = np.asarray(gen.motion(seq_id, "axis_angle"), dtype=np.float64)
        before = quat_to_axis_angle(raw[seq_id])
        sequences[seq_id] = {
            "flips_planted": [list(s) for s in spans],
            "flips_found": flips[seq_id]["runs"],
            "flip_summary": flips[seq_id]["summary"],
            "root_error_deg": {
                "model_output": mean_angle_deg(before[:, 0], clean[seq_id][:, 0]),
                "ingested": mean_angle_deg(stored[:, 0], clean[seq_id][:, 0]),
            },
            "joint_error_deg": {
                "model_output": mean_angle_deg(before[:, 1:], clean[seq_id][:, 1:]),
                "ingested": mean_angle_deg(stored[:, 1:], clean[seq_id][:, 1:]),
            },
        }
    first = next(iter(planted))
    bvh = json.loads(
        dancedata_cli("export", "bvh", store, first, args.out / f"{first}.bvh", "--json").stdout
    )
    video = args.out / f"{first}.mp4"
    dancedata_cli("render", store, first, video, "--stop", args.render_frames, "-q")
    summary = {
        "reference": {"store": str(args.store), "version": ref.version},
        "generated": {"store": str(store), "version": ingested["version"]},
        "postprocess": gen.manifest["config"]["postprocess"],
        "sequences": sequences,
        "bvh": {"path": bvh["path"], "frames": bvh["frames"], "joints": bvh["joints"]},
        "video": str(video),
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    for seq_id, info in sequences.items():
        root, joints = info["root_error_deg"], info["joint_error_deg"]
        print(
            f"{seq_id}: planted {info['flips_planted']}, found {info['flips_found']}; root error "
            f"{root['model_output']:.2f} -> {root['ingested']:.2f} deg, joints "
            f"{joints['model_output']:.2f} -> {joints['ingested']:.2f} deg"
        )
    print(f"bvh: {bvh['path']} ({bvh['frames']} frames, {bvh['joints']} joints); video: {video}")
    return summary


if __name__ == "__main__":
    try:
        main()
    except DancedataError as exc:
        raise SystemExit(f"error: {exc}") from None
