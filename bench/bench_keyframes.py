"""Keyframes + in-betweening + MSE on a whole store: dancedata's batched functions against a
per-measure Python loop (the way a hand-written study script does it).

On a featurized, segmented store (default ``bench/out/aist-full`` when present, else
``data/stores/aist-demo``) it times, with BLAS pinned to one thread:

* keyframes for every strategy the store supports (even; onset, stems, nmfd when it has audio;
  dp) at N = 3, 5, 9 over **all** measures, as ``dancedata keyframes`` computes them;
* even keyframes + linear_slerp and + oracle Bézier, and the pooled euler75 MSE, over the
  measures of ``--split`` (crossmodal test by default);
* the baseline: the same selections and in-betweens one measure at a time (scipy
  ``find_peaks`` + a Python fill loop, a DP with a per-measure numpy error table, scipy ``Slerp``
  per joint, ``np.linalg.lstsq`` per segment), on ``--baseline-measures`` measures, scaled to
  the full count.

Usage: .venv/bin/python bench/bench_keyframes.py [--store PATH] [--split test]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
STRATEGIES = ("even", "peaks:onset", "peaks:stems", "peaks:nmfd", "dp")
NS = (3, 5, 9)


def supported(store: Path) -> list[str]:
    from dancedata.store.reader import _VersionReader

    reader = _VersionReader(store)
    out = ["even"]
    if reader.has_array("audio/onset_env"):
        out.append("peaks:onset")
    if reader.has_array("audio/stems/drums/onset_env"):
        out.append("peaks:stems")
    if reader.has_array("audio/nmfd_drums"):
        out.append("peaks:nmfd")
    out.append("dp")
    return out


def time_keyframes(store: Path, strategies: list[str]) -> tuple[float, dict[str, float], int]:
    """Seconds of the whole selection (read + select + table), per strategy, measures."""
    import tempfile

    from dancedata.study.keyframes import KeyframesOptions, keyframes

    with tempfile.TemporaryDirectory() as tmp:  # write into a copy: the store stays as it is
        import shutil

        copy = Path(tmp) / "store"
        shutil.copytree(store, copy, copy_function=os.link)
        start, cpu = time.perf_counter(), time.process_time()
        result = keyframes(copy, KeyframesOptions(strategies=strategies, n_keyframes=list(NS)))
        total = time.perf_counter() - start
        print(f"  (keyframes CPU {time.process_time() - cpu:.1f} s; load stretches wall time)")
    return total, result.counts["seconds"], int(result.counts["measures"])


def eval_measures(store: Path, split: str) -> tuple:
    import dancedata

    ds = dancedata.open_store(store)
    rows = ds.measure_rows(split)
    seq = {s: ds.sequence(s) for s in {r["seq_id"] for r in rows}}
    starts = np.array([seq[r["seq_id"]]["frame_start"] + r["frame_start"] for r in rows])
    lengths = np.array([r["frame_stop"] - r["frame_start"] for r in rows])
    return ds, starts, lengths


def batched_inbetween(ds, starts: np.ndarray, lengths: np.ndarray) -> dict[int, tuple]:
    from dancedata.methods.bezier import bezier_eval, bezier_fit
    from dancedata.methods.inbetween import linear_slerp, segment_map
    from dancedata.methods.keyframes import even_indices
    from dancedata.metrics.reconstruction_error import mse_euler75

    # Only the evaluated measures' frames, gathered once into compact arrays.
    frames = np.concatenate([np.arange(s, s + n) for s, n in zip(starts, lengths, strict=True)])
    quat = ds.zarr("motion/quat").get_orthogonal_selection((frames,))
    trans = ds.zarr("motion/trans").get_orthogonal_selection((frames,))
    euler = ds.zarr("motion/euler").get_orthogonal_selection((frames,))
    x75 = np.concatenate([trans, euler.reshape(len(euler), -1)], axis=1)
    compact_starts = np.cumsum(lengths) - lengths
    out = {}
    for n in NS:
        kf = np.stack([even_indices(int(length), n) for length in lengths])
        seg = segment_map(compact_starts, lengths, kf)
        rec = linear_slerp(quat, trans, seg, "XYZ", truth_euler=euler)
        truth = x75[seg.frame]
        lin = mse_euler75(truth, rec.euler75())
        p1, p2 = bezier_fit(x75, seg)
        bez = mse_euler75(truth, bezier_eval(x75, seg, p1, p2))
        out[n] = (lin, bez)
    return out


# ------------------------------------------------------------------- per-measure baseline


def loop_peaks(curve: np.ndarray, n: int, guard: int = 6) -> list[int]:
    from scipy.signal import find_peaks

    length = len(curve)
    peaks = [p for p in find_peaks(curve)[0] if guard <= p <= length - 1 - guard]
    peaks.sort(key=lambda p: (-curve[p], p))
    chosen = sorted({0, length - 1, *peaks[: n - 2]})
    while len(chosen) < n:
        best = None
        for a, b in zip(chosen[:-1], chosen[1:], strict=True):
            if b - a >= 2:
                key = (curve[a] + curve[b], b - a, -a)
                if best is None or key > best[0]:
                    best = (key, (a + b) // 2)
        chosen = sorted([*chosen, best[1]])
    return chosen


def loop_dp(x: np.ndarray, n: int) -> list[int]:
    length = len(x)
    table = np.full((length, length), np.inf)
    for a in range(length - 1):
        table[a, a + 1] = 0.0
        for b in range(a + 2, length):
            s = (np.arange(a, b + 1) - a) / (b - a)
            r = x[a : b + 1] - x[a] - s[:, None] * (x[b] - x[a])
            table[a, b] = np.sqrt((r**2).sum(axis=1)).max()
    cost = table[0].copy()
    back = []
    for _k in range(3, n + 1):
        new = np.full(length, np.inf)
        arg = np.zeros(length, dtype=int)
        for t in range(length):
            cand = np.maximum(cost[:t], table[:t, t])
            if t:
                arg[t] = int(np.argmin(cand))
                new[t] = cand[arg[t]]
        back.append(arg)
        cost = new
    kf = [length - 1]
    for arg in reversed(back):
        kf.append(int(arg[kf[-1]]))
    return [0, *reversed(kf)] if n > 2 else [0, length - 1]


def loop_inbetween(quat, trans, x75, start: int, length: int, n: int) -> tuple[float, float]:
    from scipy.spatial.transform import Rotation, Slerp

    from dancedata.methods.keyframes import even_indices

    kf = even_indices(length, n)
    frames = np.arange(length)
    q = quat[start : start + length]
    euler = np.empty((length, 24, 3))
    for j in range(24):
        rot = Rotation.from_quat(q[kf, j][:, [1, 2, 3, 0]])
        euler[:, j] = Slerp(kf, rot)(frames).as_euler("XYZ")
    t = np.stack([np.interp(frames, kf, trans[start + kf, d]) for d in range(3)], axis=1)
    truth = x75[start : start + length]
    lin = np.concatenate([t, euler.reshape(length, -1)], axis=1)
    bez = truth.copy()
    for a, b in zip(kf[:-1], kf[1:], strict=True):
        u = (np.arange(a, b + 1) - a) / (b - a)
        basis = np.stack([(1 - u) ** 3, 3 * (1 - u) ** 2 * u, 3 * (1 - u) * u**2, u**3], 1)
        for c in range(75):
            y = truth[a : b + 1, c] - basis[:, 0] * truth[a, c] - basis[:, 3] * truth[b, c]
            p = np.linalg.lstsq(basis[:, 1:3], y, rcond=None)[0]
            bez[a : b + 1, c] = basis @ np.array([truth[a, c], p[0], p[1], truth[b, c]])
    return float(np.sum((lin - truth) ** 2)), float(np.sum((bez - truth) ** 2))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = HERE / "out" / "aist-full"
    if not default.exists():
        default = HERE.parent / "data" / "stores" / "aist-demo"
    parser.add_argument("--store", type=Path, default=default)
    parser.add_argument("--split", default="test")
    parser.add_argument("--baseline-measures", type=int, default=20)
    args = parser.parse_args(argv)
    if not (args.store / "store.json").exists():
        print(f"no store at {args.store}: run `make pipeline` (or bench_pipeline) first")
        return 1
    strategies = supported(args.store)
    print(f"store {args.store}; strategies {', '.join(strategies)}; N = {NS}")

    total, per_strategy, n_measures = time_keyframes(args.store, strategies)
    print(f"dancedata keyframes, all measures ({n_measures}): {total:.2f} s  {per_strategy}")

    ds, starts, lengths = eval_measures(args.store, args.split)
    began, cpu = time.perf_counter(), time.process_time()
    scores = batched_inbetween(ds, starts, lengths)
    batched = time.perf_counter() - began
    print(f"  (in-betweening + MSE CPU {time.process_time() - cpu:.1f} s)")
    print(
        f"even + linear_slerp / oracle Bézier + MSE, {args.split} ({len(starts)} measures, "
        f"N = 3,5,9): {batched:.2f} s; MSE linear/Bézier {scores}"
    )

    # baseline on a sample of measures, scaled to all of them
    rng = np.random.default_rng(0)
    reader_quat = ds.whole_array("motion/quat")
    trans = ds.whole_array("motion/trans")
    euler = ds.whole_array("motion/euler")
    x75 = np.concatenate([trans, euler.reshape(len(euler), -1)], axis=1).astype(np.float64)
    rows = ds.measures.to_pylist()
    sample = rng.choice(len(rows), size=min(args.baseline_measures, len(rows)), replace=False)
    began = time.perf_counter()
    for i in sample.tolist():
        r = rows[i]
        start = ds.sequence(r["seq_id"])["frame_start"] + r["frame_start"]
        length = r["frame_stop"] - r["frame_start"]
        x = x75[start : start + length]
        for n in NS:
            loop_dp(x, n)
            if "peaks:onset" in strategies and ds.audio_frames(r["seq_id"]) >= r["frame_stop"]:
                curve = ds.audio(r["seq_id"], "onset_env")[r["frame_start"] : r["frame_stop"]]
                for _ in strategies[1:-1]:  # one peak pass per audio strategy
                    loop_peaks(np.asarray(curve, np.float64), n)
    per_measure_kf = (time.perf_counter() - began) / len(sample)
    began = time.perf_counter()
    for i in sample.tolist()[: max(1, len(sample) // 4)]:
        r = rows[i]
        start = ds.sequence(r["seq_id"])["frame_start"] + r["frame_start"]
        for n in NS:
            loop_inbetween(reader_quat, trans, x75, start, r["frame_stop"] - r["frame_start"], n)
    per_measure_ib = (time.perf_counter() - began) / max(1, len(sample) // 4)
    loop_total = per_measure_kf * n_measures + per_measure_ib * len(starts)
    print(
        f"per-measure loop baseline: keyframes {per_measure_kf:.3f} s/measure, in-between "
        f"{per_measure_ib:.3f} s/measure → {loop_total:.0f} s for the same work "
        f"(vs {total + batched:.1f} s, ×{loop_total / (total + batched):.0f})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
