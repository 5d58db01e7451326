"""Study 001 (genre LSTM) end to end: a store's 30 fps quaternions and per-frame STFT as
training windows, a tiny LSTM trained on them for one epoch, its output brought back into a
store, smoothed, hip-repaired, exported as BVH and rendered with the music.

1. ``dancedata featurize STORE --representations quat --audio-families stft_frames --stems
   none`` when the store lacks ``motion/quat`` or ``audio/stft_frames`` (a new version of
   STORE; the feature cache goes under OUT/cache).
2. ``SecondsDataset(STORE, motion="motion/quat", audio="audio/stft_frames", seconds=1,
   hop_seconds=0.25)`` batched by ``training_loader`` (seeded shuffle, padded batches with a
   mask).
3. :class:`GenreLSTM`: log1p of the STFT magnitudes → linear → plus a linear embedding of the
   genre one-hot (when the store has genres) → one LSTM layer → J wxyz quaternions per frame,
   normalised to unit length. Loss: mean over real frames and joints of 1 − |<q, q_ref>| (sign
   invariant: q and −q are one rotation). Adam, one epoch, CPU, seeded
   (``torch.use_deterministic_algorithms``). It trains and predicts on the same sequences
   (``--split``, default all): the point is the data path, not generalisation.
4. The trained network runs on each sequence's whole STFT (``DanceStore.view``) and predicts its
   quaternions; the root translation is the reference's (the network predicts none). To
   exercise the repair step, half turns of the hip about the vertical axis are planted on a few
   runs of frames (``--flips`` runs per sequence); the network does not make them. Written as
   ``<seq_id>.npz`` holding ``quat`` (F, J, 4 wxyz) and ``trans`` (F, 3), the layout
   ``dancedata ingest generated`` reads for any rig. Then, as a user types them:

    dancedata ingest generated OUT/outputs --store OUT/generated --like STORE \\
        --smooth-cutoff 6 --repair-hip-flips --json
    dancedata export bvh OUT/generated SEQ OUT/SEQ.bvh
    dancedata render OUT/generated SEQ OUT/SEQ.mp4 --stop 120

A summary (``OUT/summary.json``, printed): the training losses (every batch; the loss over all
windows before and after the epoch), per sequence the frames and joints predicted, the flip
runs planted and found, and the mean angle (degrees) of the root between the network's own
prediction and the file with flips, and between it and the ingested (repaired, smoothed) store.

    python examples/study_001_genre_lstm.py STORE OUT [--sequences 2] [--seed 1]

Needs PyTorch (``pip install 'dancedata[learned]'``); without it the script says so, exit 1.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

import dancedata
from dancedata.errors import DancedataError

UP = {"y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
MOTION, AUDIO = "motion/quat", "audio/stft_frames"


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


def import_torch() -> Any:
    """torch, or exit 1 with how to install it."""
    try:
        import torch
    except ImportError:
        print(
            "error: this example trains a PyTorch LSTM and PyTorch is not installed: "
            "pip install 'dancedata[learned]'",
            file=sys.stderr,
        )
        raise SystemExit(1) from None
    return torch


def make_model(torch: Any, n_audio: int, n_genres: int, n_joints: int, hidden: int) -> Any:
    """The study's network, small: STFT frames (+ genre) in, unit quaternions (B, T, J, 4) out."""
    nn = torch.nn

    class GenreLSTM(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.audio = nn.Linear(n_audio, hidden)
            self.genre = nn.Linear(n_genres, hidden, bias=False) if n_genres else None
            self.lstm = nn.LSTM(hidden, hidden, batch_first=True)
            self.out = nn.Linear(hidden, n_joints * 4)

        def forward(self, audio: Any, genre: Any) -> Any:
            x = self.audio(torch.log1p(audio.clamp(min=0)))  # magnitudes span decades
            if self.genre is not None:
                x = x + self.genre(genre)[:, None, :]
            h, _ = self.lstm(torch.relu(x))
            q = self.out(h).reshape(*h.shape[:2], n_joints, 4)
            return torch.nn.functional.normalize(q, dim=-1)

    return GenreLSTM()


def quat_loss(pred: Any, target: Any, mask: Any) -> Any:
    """Mean over real frames and joints of 1 − |<q, q_ref>| (0 when equal, sign invariant)."""
    dot = (pred * target).sum(-1).abs()  # (B, T, J)
    m = mask[..., None].to(dot.dtype).expand_as(dot)
    return ((1.0 - dot) * m).sum() / m.sum().clamp(min=1.0)


def plant_flips(n_frames: int, runs: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """``runs`` disjoint [start, stop) runs of 1-12 frames, none touching frame 0 or 1."""
    spans: list[tuple[int, int]] = []
    slots = np.sort(rng.choice(np.arange(1, max(2, n_frames // 40)), size=runs, replace=False))
    for slot in slots:
        start = int(slot * 40 + rng.integers(2, 10))
        spans.append((start, min(n_frames - 1, start + int(rng.integers(1, 13)))))
    return spans


def flip_hip(quat: np.ndarray, spans: list[tuple[int, int]], up: str) -> np.ndarray:
    """(F, J, 4) wxyz with the root turned by a half turn about ``up`` on ``spans``."""
    out = quat.copy()
    half = Rotation.from_rotvec(np.pi * np.asarray(UP[up]))
    for a, b in spans:
        root = Rotation.from_quat(out[a:b, 0][:, [1, 2, 3, 0]])
        out[a:b, 0] = (half * root).as_quat()[:, [3, 0, 1, 2]]
    return out


def mean_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Mean rotation angle (degrees) between axis-angle arrays ``a`` and ``b`` (..., 3)."""
    ra, rb = Rotation.from_rotvec(a.reshape(-1, 3)), Rotation.from_rotvec(b.reshape(-1, 3))
    return float(np.degrees((ra * rb.inv()).magnitude()).mean())


def quat_to_axis_angle(quat: np.ndarray) -> np.ndarray:
    f, j, _ = quat.shape
    return Rotation.from_quat(quat.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_rotvec().reshape(f, j, 3)


def ensure_features(store: Path, cache: Path) -> None:
    """Featurize ``store`` (a new version) unless its latest version has both arrays."""
    ref = dancedata.open_store(store)
    try:
        ref.view(ref.seq_ids()[0], [MOTION, AUDIO])
        return
    except (DancedataError, KeyError):
        pass
    dancedata_cli(
        "featurize", store, "--representations", "quat", "--audio-families", "stft_frames",
        "--stems", "none", "--cache-dir", cache, "-q",
    )  # fmt: skip


def train(torch: Any, store: Path, args: argparse.Namespace) -> tuple[Any, dict]:
    """One epoch of Adam on the windows of ``store``; the model and the losses."""
    from dancedata.read.torch_batching import training_loader
    from dancedata.read.torch_data import SecondsDataset

    torch.manual_seed(args.seed)
    torch.use_deterministic_algorithms(True)
    torch.set_num_threads(1)
    ds = SecondsDataset(
        store, split=args.split, seconds=args.window_seconds, hop_seconds=args.window_seconds / 4,
        motion=MOTION, audio=AUDIO, normalize=False, seed=args.seed,
    )  # fmt: skip
    (quat_part,) = ds.columns["motion"]
    n_joints = quat_part.shape[0]
    n_audio = ds.columns["audio"][-1].stop
    n_genres = int(ds[0]["genre"].shape[0])
    model = make_model(torch, n_audio, n_genres, n_joints, args.hidden)
    optimiser = torch.optim.Adam(model.parameters(), lr=args.lr)
    loader = training_loader(ds, args.batch_size, seed=args.seed)

    def loss_of(batch: dict) -> Any:
        target = batch["motion"].reshape(*batch["motion"].shape[:2], n_joints, 4)
        return quat_loss(model(batch["audio"], batch["genre"]), target, batch["mask"])

    def all_windows() -> float:
        with torch.no_grad():
            total = [(float(loss_of(b)), int(b["mask"].sum())) for b in loader]
        return sum(v * n for v, n in total) / sum(n for _, n in total)

    before = all_windows()
    batches = []
    model.train()
    for batch in loader:
        loss = loss_of(batch)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        batches.append(float(loss.detach()))
    model.eval()
    losses = {
        "loss": "mean over real frames and joints of 1 - |<q, q_ref>| (wxyz unit quaternions)",
        "windows": len(ds),
        "window_seconds": args.window_seconds,
        "batch_size": args.batch_size,
        "epochs": 1,
        "batches": batches,
        "first_batch": batches[0],
        "last_batch": batches[-1],
        "all_windows_before": before,
        "all_windows_after": all_windows(),
        "model": {
            "hidden": args.hidden,
            "genre_names": list(ds.source.genres),
            "audio_columns": n_audio,
            "joints": n_joints,
            "parameters": sum(p.numel() for p in model.parameters()),
        },
    }
    return model, losses


def predict(torch: Any, model: Any, ref: Any, seq_id: str, genres: list[str]) -> np.ndarray:
    """(F, J, 4) float64 unit quaternions the model predicts from the whole track's STFT."""
    audio = torch.from_numpy(np.asarray(ref.view(seq_id, AUDIO), dtype=np.float32))[None]
    genre = torch.zeros(1, len(genres))
    name = ref.sequence(seq_id).get("genre")
    if name in genres:
        genre[0, genres.index(name)] = 1.0
    with torch.no_grad():
        quat = model(audio, genre)[0].double().numpy()
    return quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("store", type=Path, help="reference store (AIST++, BVH, ...)")
    parser.add_argument("out", type=Path, help="output folder (created)")
    parser.add_argument("--sequences", type=int, default=2, help="sequences predicted")
    parser.add_argument("--split", default=None, help="split trained on (default: all)")
    parser.add_argument("--window-seconds", type=float, default=1.0)
    parser.add_argument("--batch-size", type=int, default=8)
    parser.add_argument("--hidden", type=int, default=64)
    parser.add_argument("--lr", type=float, default=1e-2)
    parser.add_argument("--flips", type=int, default=2, help="flip runs planted per sequence")
    parser.add_argument("--cutoff", type=float, default=6.0, help="Butterworth cutoff, Hz")
    parser.add_argument("--render-frames", type=int, default=120)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    torch = import_torch()

    args.out.mkdir(parents=True, exist_ok=True)
    ensure_features(args.store, args.out / "cache")
    model, losses = train(torch, args.store, args)
    print(
        f"trained 1 epoch on {losses['windows']} windows of {args.window_seconds:g} s: loss "
        f"first batch {losses['first_batch']:.4f}, last batch {losses['last_batch']:.4f}; "
        f"all windows {losses['all_windows_before']:.4f} -> {losses['all_windows_after']:.4f}"
    )
    ref = dancedata.open_store(args.store)
    up = str(ref.group_attrs("motion").get("up_axis") or "y")
    genres = losses["model"]["genre_names"]
    outputs = args.out / "outputs"
    outputs.mkdir(exist_ok=True)
    rng = np.random.default_rng(args.seed)
    planted: dict[str, list[tuple[int, int]]] = {}
    predicted: dict[str, np.ndarray] = {}
    for seq_id in ref.seq_ids()[: args.sequences]:
        trans = np.asarray(ref.motion(seq_id, "trans"), dtype=np.float64)
        quat = predict(torch, model, ref, seq_id, genres)
        spans = plant_flips(len(quat), args.flips, rng)
        np.savez(outputs / f"{seq_id}.npz", quat=flip_hip(quat, spans, up).astype(np.float32),
                 trans=trans)  # fmt: skip
        planted[seq_id], predicted[seq_id] = spans, quat

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
        pred = quat_to_axis_angle(predicted[seq_id])
        flipped = quat_to_axis_angle(flip_hip(predicted[seq_id], spans, up))
        reference = ref.motion(seq_id, "axis_angle")
        sequences[seq_id] = {
            "frames": {"predicted": len(pred), "reference": int(reference.shape[0])},
            "joints": {"predicted": int(pred.shape[1]), "reference": int(reference.shape[1])},
            "flips_planted": [list(s) for s in spans],
            "flips_found": flips[seq_id]["runs"],
            "flip_summary": flips[seq_id]["summary"],
            "root_vs_prediction_deg": {
                "with_flips": mean_angle_deg(flipped[:, 0], pred[:, 0]),
                "ingested": mean_angle_deg(stored[:, 0], pred[:, 0]),
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
        "training": losses,
        "generated": {"store": str(store), "version": ingested["version"]},
        "postprocess": gen.manifest["config"]["postprocess"],
        "sequences": sequences,
        "bvh": {"path": bvh["path"], "frames": bvh["frames"], "joints": bvh["joints"]},
        "video": str(video),
    }
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))
    for seq_id, info in sequences.items():
        root = info["root_vs_prediction_deg"]
        print(
            f"{seq_id}: predicted {info['frames']['predicted']} frames x "
            f"{info['joints']['predicted']} joints; flips planted {info['flips_planted']}, "
            f"found {info['flips_found']}; root vs prediction {root['with_flips']:.2f} -> "
            f"{root['ingested']:.2f} deg"
        )
    print(f"bvh: {bvh['path']} ({bvh['frames']} frames, {bvh['joints']} joints); video: {video}")
    return summary


if __name__ == "__main__":
    try:
        main()
    except DancedataError as exc:
        raise SystemExit(f"error: {exc}") from None
