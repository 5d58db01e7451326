"""Motion representations (rotmat, euler XYZ, quat wxyz sign-continuous, rot6d) of 24-joint
axis-angle frames: dancedata's compiled pass against the scipy ``Rotation`` path it replaced
(one Rotation, as_matrix / as_euler / as_quat, numpy sign continuity per sequence) and against
the earlier compiled float64 pass (signs in a second pass, then cast to float32), side by side
in one process on the same arrays, alternating, CPU seconds per million frames beside wall time.

    .venv/bin/python bench/bench_motion_representations.py [--frames 500000] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.motion_representations import representations_from_axis_angle
from dancedata.compute.rotation_kernels import quat_sign_continuous_spans
from dancedata.compute.rotations import quat_sign_continuous, rotmat_to_rot6d

NAMES = ("rotmat", "euler", "quat", "rot6d")


def scipy_path(aa: np.ndarray, bounds: np.ndarray) -> dict[str, np.ndarray]:
    lead = aa.shape[:-1]
    rot = Rotation.from_rotvec(aa.reshape(-1, 3).astype(np.float64))
    rotmat = rot.as_matrix().reshape(lead + (3, 3))
    out = {
        "rotmat": rotmat,
        "euler": rot.as_euler("XYZ").reshape(lead + (3,)),
        "quat": rot.as_quat(canonical=True)[:, [3, 0, 1, 2]].reshape(lead + (4,)),
        "rot6d": rotmat_to_rot6d(rotmat),
    }
    for a, b in bounds:
        out["quat"][a:b] = quat_sign_continuous(out["quat"][a:b])
    return {k: v.astype(np.float32) for k, v in out.items()}


def float64_pass(aa: np.ndarray, bounds: np.ndarray) -> dict[str, np.ndarray]:
    """The compiled pass as featurize used it before: float64 arrays, rot6d sliced from the
    matrices, signs in a second pass, then cast to the stored float32."""
    out = representations_from_axis_angle(aa, NAMES, "XYZ")
    out["quat"] = quat_sign_continuous_spans(out["quat"], bounds)
    return {k: v.astype(np.float32) for k, v in out.items()}


def dancedata_path(aa: np.ndarray, bounds: np.ndarray) -> dict[str, np.ndarray]:
    """featurize's pass: float32 written by the kernel, rot6d and signs in the same pass."""
    return representations_from_axis_angle(aa, NAMES, "XYZ", dtype=np.float32, bounds=bounds)


BATCH = 16384  # frames per featurize motion task (2 chunks of 8192)


def batches(aa: np.ndarray, bounds: np.ndarray):  # noqa: ANN201
    """(frames, local bounds) of each featurize-sized batch."""
    for start in range(0, len(aa), BATCH):
        stop = min(start + BATCH, len(aa))
        inside = bounds[(bounds[:, 0] >= start) & (bounds[:, 0] < stop)]
        yield aa[start:stop], np.clip(inside - start, 0, stop - start)


def measure(fn, aa, bounds) -> tuple[float, float]:
    """Run ``fn`` batch by batch, as featurize's motion tasks do: each batch's arrays are
    dropped before the next (featurize writes them into the store), so memory stays at a
    batch and the allocator reuses it."""
    cpu, wall = time.process_time(), time.perf_counter()
    for frames, local in batches(aa, bounds):
        fn(frames, local)
    return time.process_time() - cpu, time.perf_counter() - wall


def worst_difference(fn, reference, aa, bounds) -> float:
    """Largest |fn − reference| over every array of every batch (untimed)."""
    worst = 0.0
    for frames, local in batches(aa, bounds):
        got, want = fn(frames, local), reference(frames, local)
        for k in NAMES:
            assert got[k].dtype == want[k].dtype == np.float32, k
            worst = max(worst, float(np.abs(got[k] - want[k]).max()))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=500_000)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    aa = rng.normal(0, 0.6, (args.frames, 24, 3)).astype(np.float32)
    # AIST++-like sequences of ~730 frames (a batch cuts one; the bench clips it)
    cuts = np.arange(0, args.frames, 730)
    bounds = np.stack([cuts, np.minimum(cuts + 730, args.frames)], axis=1)
    for fn in (float64_pass, dancedata_path):  # load the compiled code (cached on disk)
        fn(aa[:100], np.array([[0, 100]]))
    per_m = 1e6 / args.frames
    paths = (("scipy", scipy_path), ("float64", float64_pass), ("dancedata", dancedata_path))
    best: dict[str, list[float]] = {name: [] for name, _ in paths}
    for _ in range(args.rounds):
        for name, fn in paths:
            cpu, wall = measure(fn, aa, bounds)
            best[name].append(cpu)
            print(f"{name:10s} cpu {cpu * per_m:6.2f} s/Mframe  wall {wall * per_m:6.2f} s/Mframe")
    for name, fn in paths[1:]:
        worst = worst_difference(fn, scipy_path, aa, bounds)
        print(f"max |{name} - scipy| over the four float32 arrays of every batch: {worst:.3g}")
    s, f, d = (min(best[name]) for name, _ in paths)
    print(
        f"best CPU per million frames: scipy {s * per_m:.2f} s, compiled float64 pass (before) "
        f"{f * per_m:.2f} s, dancedata {d * per_m:.2f} s; scipy/dancedata x{s / d:.1f}, "
        f"before/after x{f / d:.2f}; load {os.getloadavg()[0]:.1f}, {args.frames} frames x 24 "
        f"joints, {os.cpu_count()} cpu(s)"
    )


if __name__ == "__main__":
    main()
