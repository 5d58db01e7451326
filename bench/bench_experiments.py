"""`dancedata experiment run` against a per-measure Python loop doing the same work (issue 12.7).

Work, on the measures of one split (crossmodal ``test`` by default, gJB excluded as the spec's
default): keyframes of every strategy the store supports (even; onset, stems, nmfd when it has
audio; dp) at N = 3, 5, 9; for each, linear translation + SLERP and oracle-Bézier in-betweens;
the pooled euler75 MSE of each (strategy, in-betweener, N).

* dancedata: :func:`dancedata.study.runner.run_experiment` with that matrix (reading the
  store, selecting, reconstructing, scoring; results written to a temporary folder), timed
  cold (first call in the process: imports, numba compilation) and warm.
* baseline: the same work one measure at a time, as a hand-written study script does it:
  scipy ``find_peaks`` + a Python fill loop, a DP with a per-measure numpy error table
  (bench_keyframes.py's ``loop_peaks`` / ``loop_dp``), scipy ``Slerp`` per joint,
  ``np.linalg.lstsq`` per segment and channel, a running sum for the MSE. It runs on
  ``--baseline-measures`` measures (default: all of the split) and is scaled to the split.

Both sides' MSE values are printed side by side (same measures when the baseline runs on all).
BLAS is pinned to one thread. Writes bench/out/bench_experiments.json.

Usage: .venv/bin/python bench/bench_experiments.py [--store PATH] [--split test]
       [--baseline-measures K]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
NS = (3, 5, 9)
INBETWEENERS = ("linear_slerp", "bezier_oracle")


def supported(store: Path) -> list[str]:
    from dancedata.store.reader import _VersionReader

    reader = _VersionReader(store)
    out = ["even"]
    for name, array in (
        ("onset", "audio/onset_env"),
        ("stems", "audio/stems/drums/onset_env"),
        ("nmfd", "audio/nmfd_drums"),
    ):
        if reader.has_array(array):
            out.append(name)
    return [*out, "dp"]


def ours(store: Path, split: str, strategies: list[str]) -> tuple[float, float, dict, int]:
    """(wall s, CPU s, {(row_key, N): mse}, measures) of one run_experiment call."""
    from dancedata.study.config import build_config
    from dancedata.study.runner import run_experiment

    config = build_config(
        {
            "id": "bench",
            "n_keyframes": list(NS),
            "matrix": {"keyframes": strategies, "inbetween": list(INBETWEENERS)},
            "split": {"eval": [split]},
            "metrics": {"names": ["mse"]},
        }
    )
    with tempfile.TemporaryDirectory() as tmp:
        wall, cpu = time.perf_counter(), time.process_time()
        out = run_experiment(config, store, out_dir=Path(tmp) / "results")
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    values = {(r["row_key"], r["n_keyframes"]): r["value"] for r in out.rows}
    if out.skipped:
        print(f"  skipped: {[s.as_dict() for s in out.skipped]}")
    return wall, cpu, values, int(out.record["n_measures"])


# ------------------------------------------------------------------- per-measure baseline


def loop_reconstruct(quat, trans, x75, start: int, length: int, kf: np.ndarray) -> tuple:
    """Squared-error sums of linear+SLERP and oracle Bézier for one measure."""
    from scipy.spatial.transform import Rotation, Slerp

    frames = np.arange(length)
    q = quat[start : start + length][:, :, [1, 2, 3, 0]]  # wxyz → scipy xyzw
    truth = x75[start : start + length]
    euler = np.empty((length, 24, 3))
    for j in range(24):
        euler[:, j] = Slerp(kf, Rotation.from_quat(q[kf, j]))(frames).as_euler("XYZ")
    t = np.stack([np.interp(frames, kf, truth[kf, d]) for d in range(3)], axis=1)
    linear = np.concatenate([t, euler.reshape(length, -1)], axis=1)
    linear[kf] = truth[kf]
    bezier = truth.copy()
    for a, b in zip(kf[:-1].tolist(), kf[1:].tolist(), strict=True):
        u = (np.arange(a, b + 1) - a) / (b - a)
        basis = np.stack([(1 - u) ** 3, 3 * (1 - u) ** 2 * u, 3 * (1 - u) * u**2, u**3], 1)
        for c in range(75):
            if b - a < 3:  # too few interior frames: the chord (as the spec says)
                bezier[a : b + 1, c] = (1 - u) * truth[a, c] + u * truth[b, c]
                continue
            y = truth[a : b + 1, c] - basis[:, 0] * truth[a, c] - basis[:, 3] * truth[b, c]
            p = np.linalg.lstsq(basis[:, 1:3], y, rcond=None)[0]
            bezier[a : b + 1, c] = basis @ np.array([truth[a, c], p[0], p[1], truth[b, c]])
    return float(np.sum((linear - truth) ** 2)), float(np.sum((bezier - truth) ** 2))


def baseline(store: Path, split: str, strategies: list[str], sample: int) -> tuple:
    """(wall s, CPU s, {(row_key, N): mse}, measures done) of the per-measure loop."""
    from bench_keyframes import loop_dp, loop_peaks

    import dancedata
    from dancedata.methods.keyframes import even_indices

    wall, cpu = time.perf_counter(), time.process_time()
    ds = dancedata.open_store(store)
    rows = [r for r in ds.measure_rows(split) if ds.sequence(r["seq_id"]).get("genre") != "gJB"]
    if 0 < sample < len(rows):
        pick = np.random.default_rng(0).choice(len(rows), size=sample, replace=False)
        rows = [rows[i] for i in sorted(pick.tolist())]
    sums: dict[tuple[str, int], float] = {}
    frames = 0
    for r in rows:
        seq_id = r["seq_id"]
        a, b = r["frame_start"], r["frame_stop"]
        quat = ds.motion(seq_id, "quat").astype(np.float64)
        x75 = ds.view(seq_id, "thesis_euler_75").astype(np.float64)
        has_audio = ds.audio_frames(seq_id) >= b
        curves = {}
        if has_audio:
            curves = {
                "onset": ds.audio(seq_id, "onset_env"),
                "stems": ds.weighted_stem_onsets(seq_id),
                "nmfd": ds.weighted_nmfd(seq_id),
            }
        frames += b - a
        for n in NS:
            for strategy in strategies:
                if strategy == "even":
                    kf = even_indices(b - a, n)
                elif strategy == "dp":
                    kf = np.array(loop_dp(x75[a:b], n))
                elif has_audio:
                    kf = np.array(loop_peaks(np.asarray(curves[strategy][a:b], np.float64), n))
                else:
                    continue
                lin, bez = loop_reconstruct(quat, None, x75, a, b - a, kf)
                for ib, value in zip(INBETWEENERS, (lin, bez), strict=True):
                    key = (f"{strategy}+{ib}", n)
                    sums[key] = sums.get(key, 0.0) + value
    values = {key: total / (frames * 25) for key, total in sums.items()}
    return time.perf_counter() - wall, time.process_time() - cpu, values, len(rows)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = HERE / "out" / "aist-full"
    if not (default / "store.json").exists():
        default = HERE.parent / "data" / "stores" / "aist-demo"
    parser.add_argument("--store", type=Path, default=default)
    parser.add_argument("--split", default="test")
    parser.add_argument("--baseline-measures", type=int, default=0, help="0: all of the split")
    args = parser.parse_args(argv)
    if not (args.store / "store.json").exists():
        print(f"no store at {args.store}: run `make pipeline` (or bench_pipeline) first")
        return 1
    strategies = supported(args.store)
    print(f"store {args.store}; split {args.split}; strategies {strategies}; N = {NS}; "
          f"load average {os.getloadavg()[0]:.1f}")  # fmt: skip

    cold = ours(args.store, args.split, strategies)
    warm = ours(args.store, args.split, strategies)
    print(f"dancedata experiment run, {warm[3]} measures × {len(strategies)} strategies × "
          f"2 in-betweeners × 3 N + MSE: cold {cold[0]:.2f} s wall / {cold[1]:.2f} s CPU, "
          f"warm {warm[0]:.2f} s wall / {warm[1]:.2f} s CPU")  # fmt: skip

    loop = baseline(args.store, args.split, strategies, args.baseline_measures)
    scale = warm[3] / loop[3]
    print(f"per-measure loop: {loop[3]} measures in {loop[0]:.1f} s wall / {loop[1]:.1f} s CPU"
          f" → {loop[0] * scale:.1f} s wall for {warm[3]} measures")  # fmt: skip
    ratio_wall = loop[0] * scale / warm[0]
    ratio_cpu = loop[1] * scale / warm[1]
    print(f"ratio loop / dancedata (warm): ×{ratio_wall:.0f} wall, ×{ratio_cpu:.0f} CPU; "
          f"vs cold: ×{loop[0] * scale / cold[0]:.0f} wall")  # fmt: skip
    same = loop[3] == warm[3]
    print(f"{'row@N':28s} {'dancedata':>12s} {'loop':>12s}" + ("" if same else "  (loop: sample)"))
    worst = 0.0
    for key in sorted(warm[2]):
        mine, theirs = warm[2][key], loop[2].get(key, float("nan"))
        rel = abs(mine - theirs) / max(abs(theirs), 1e-12)
        worst = max(worst, rel) if same else worst
        print(f"{key[0] + '@' + str(key[1]):28s} {mine:12.6g} {theirs:12.6g}")
    if same:
        print(f"largest relative MSE difference, same measures: {worst:.2e}")
    out = HERE / "out" / "bench_experiments.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({
        "store": str(args.store), "split": args.split, "strategies": strategies,
        "measures": warm[3], "cold_wall_s": cold[0], "cold_cpu_s": cold[1],
        "warm_wall_s": warm[0], "warm_cpu_s": warm[1], "loop_measures": loop[3],
        "loop_wall_s": loop[0], "loop_cpu_s": loop[1], "ratio_wall": ratio_wall,
        "ratio_cpu": ratio_cpu, "max_rel_mse_diff": worst if same else None,
        "load_average": os.getloadavg()[0],
    }, indent=2))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
