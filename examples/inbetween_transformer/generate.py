"""Write a trained in-betweener's outputs as ``<seq_id>.npy`` FACT rows, for `dancedata evaluate`.

    .venv/bin/python examples/inbetween_transformer/generate.py data/stores/aist-demo \
        --checkpoint runs/motion9.pt --split test,val --out runs/motion9-out

One file per sequence of the split(s): (F, 225) float32 rows in the ``fact_motion_225`` layout
(6 zeros + root translation m + 24 row-major 3×3 rotations, each projected to the nearest
rotation by SVD with a determinant fix,
docs/EXPERIMENTS.md §3.3), frame i = the sequence's frame i at 60 fps,
F = the end of its last complete measure. Frames inside measures are the model's
``X_lin + f(·)``. Frames outside every measure (before the first one when the segmentation has a
downbeat phase, or in a gap) have no model input: they are the keyframe baseline (SLERP between
the neighbouring measure edges; the first edge held before it), and counted in generated.json.
A sequence with a measure the model cannot see (audio variants: measures the audio does not
cover) is not written and is listed with its reason.

``--baseline --keyframes N`` writes X_lin alone (even keyframes + linear_slerp), no model: the
``even+linear_slerp`` row through the same files and the same scorer.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch
from measure_batches import collate, keyframe_baseline, load_windows
from model import InbetweenTransformer, ModelConfig

from dancedata.errors import DancedataError, InputError
from dancedata.methods.keyframes import even_indices
from dancedata.metrics.evaluate_inputs import closest_rotmat


def project_rows(rows: np.ndarray) -> np.ndarray:
    """(F, 225) → the same rows with each 3×3 block replaced by its nearest rotation."""
    out = np.asarray(rows, dtype=np.float64).copy()
    out[:, :6] = 0.0
    out[:, 9:] = closest_rotmat(out[:, 9:].reshape(len(out), 24, 3, 3)).reshape(len(out), -1)
    return out


def sequence_frames(
    store, seq_id: str, rows: dict[int, dict], n_keyframes: int
) -> tuple[np.ndarray, int]:
    """The keyframe baseline over frames [0, end of the last measure) of one sequence, for the
    frames no measure covers, and how many such frames there are."""
    truth = store.view(seq_id, "fact_motion_225")
    keyframes = sorted(
        {
            r["frame_start"] + int(k)
            for r in rows.values()
            for k in even_indices(r["frame_stop"] - r["frame_start"], n_keyframes)
        }
    )
    first, last = keyframes[0], keyframes[-1]
    out = np.empty((last + 1, 225))
    out[first:] = keyframe_baseline(truth[first : last + 1], np.asarray(keyframes) - first)
    out[:first] = out[first]
    covered = sum(r["frame_stop"] - r["frame_start"] for r in rows.values())
    return out, last + 1 - covered


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def generate(args: argparse.Namespace) -> dict:
    torch.set_num_threads(args.threads)
    checkpoint = None
    if args.baseline:
        n_keyframes, variant, model, cfg, stats = args.keyframes, "motion", None, None, None
    else:
        if not args.checkpoint:
            raise InputError("give --checkpoint (or --baseline --keyframes N)")
        try:
            checkpoint = torch.load(args.checkpoint, map_location="cpu", weights_only=True)
            cfg = ModelConfig(**checkpoint["config"])
        except Exception as exc:  # torch.load raises pickle, zip and runtime errors alike
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise InputError(f"not a checkpoint of train.py: {first}", args.checkpoint) from None
        model = InbetweenTransformer(cfg)
        model.load_state_dict(checkpoint["state_dict"])
        model.eval()
        n_keyframes, variant, stats = (
            checkpoint["n_keyframes"],
            cfg.variant,
            checkpoint["audio_stats"],
        )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, dict] = {}
    skipped: dict[str, str] = {}
    for split in [s.strip() for s in args.split.split(",") if s.strip()]:
        windows, store = load_windows(args.store, split, n_keyframes, variant, args.version)
        if checkpoint is not None and store.version != checkpoint["store_version"]:
            print(
                f"note: trained on {checkpoint['store_version']}, generating from {store.version}",
                file=sys.stderr,
            )
        if cfg is not None:
            long = [w for w in windows if w.motion.shape[0] > cfg.max_len]
            if long:
                raise InputError(
                    f"{long[0].seq_id} measure {long[0].measure} has "
                    f"{long[0].motion.shape[0]} frames, more than the model's "
                    f"max_len {cfg.max_len}",
                    args.store,
                )
        predicted: dict[str, dict[int, np.ndarray]] = defaultdict(dict)
        for i in range(0, len(windows), args.batch_size):
            chunk = windows[i : i + args.batch_size]
            if model is None:
                rows = [w.x_lin for w in chunk]
            else:
                batch = collate(chunk, cfg.max_len, stats)
                with torch.no_grad():
                    residual = model(
                        batch["x_lin"], batch["pad_mask"], batch["genre"], batch["audio"]
                    ).numpy()
                rows = [w.x_lin + residual[j, : w.motion.shape[0]] for j, w in enumerate(chunk)]
            for w, r in zip(chunk, rows, strict=True):
                predicted[w.seq_id][w.frame_start] = r
        measures: dict[str, dict[int, dict]] = defaultdict(dict)
        for r in store.measure_rows(split, "crossmodal"):
            measures[r["seq_id"]][r["frame_start"]] = r
        for seq_id, rows in sorted(measures.items()):
            got = predicted.get(seq_id, {})
            missing = [start for start in rows if start not in got]
            if missing:
                skipped[seq_id] = (
                    f"{len(missing)} of {len(rows)} measures have no model input "
                    f"(first at frame {min(missing)})"
                )
                continue
            full, filled = sequence_frames(store, seq_id, rows, n_keyframes)
            for start, values in got.items():
                full[start : start + len(values)] = values
            path = out / f"{seq_id}.npy"
            tmp = out / f".{seq_id}.npy.tmp"
            with tmp.open("wb") as fh:
                np.save(fh, project_rows(full).astype(np.float32))
            tmp.replace(path)
            written[seq_id] = {
                "split": split,
                "frames": len(full),
                "baseline_frames": filled,
                "measures": len(rows),
            }
    manifest = {
        "layout": "fact_motion_225 (F, 225) float32 per <seq_id>.npy, rotations SVD-projected",
        "method": "even+linear_slerp" if args.baseline else f"even+transformer_{variant}",
        "n_keyframes": n_keyframes,
        "store": str(args.store),
        "store_version": store.version,
        "split": args.split,
        "checkpoint": None if args.baseline else str(args.checkpoint),
        "checkpoint_sha256": None if args.baseline else _sha256(Path(args.checkpoint)),
        "written": written,
        "skipped": skipped,
    }
    (out / "generated.json").write_text(json.dumps(manifest, indent=1))
    print(
        f"wrote {len(written)} sequences ({sum(v['frames'] for v in written.values())} frames) "
        f"to {out}" + (f"; skipped {len(skipped)}" if skipped else "")
    )
    for seq_id, reason in skipped.items():
        print(f"  skipped {seq_id}: {reason}", file=sys.stderr)
    return manifest


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("store")
    p.add_argument("--out", required=True, help="folder for <seq_id>.npy + generated.json")
    p.add_argument("--checkpoint", help="checkpoint written by train.py")
    p.add_argument("--baseline", action="store_true", help="write X_lin, no model")
    p.add_argument("--keyframes", type=int, default=9, help="N, with --baseline")
    p.add_argument("--split", default="test", help="split(s), comma-separated")
    p.add_argument("--version", default=None)
    p.add_argument("--batch-size", type=int, default=32)
    p.add_argument("--threads", type=int, default=1)
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    try:
        generate(parse_args(argv))
    except (DancedataError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
