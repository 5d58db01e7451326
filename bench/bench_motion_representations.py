"""Motion representations (rotmat, euler XYZ, quat wxyz sign-continuous, rot6d) of 24-joint
axis-angle frames: dancedata's compiled pass against the scipy ``Rotation`` path it replaced
(one Rotation, as_matrix / as_euler / as_quat, numpy sign continuity per sequence), side by side
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


def dancedata_path(aa: np.ndarray, bounds: np.ndarray) -> dict[str, np.ndarray]:
    out = representations_from_axis_angle(aa, NAMES, "XYZ")
    out["quat"] = quat_sign_continuous_spans(out["quat"], bounds)
    return {k: v.astype(np.float32) for k, v in out.items()}


BATCH = 16384  # frames per featurize motion task (2 chunks of 8192)


def measure(fn, aa, bounds) -> tuple[float, float, dict]:
    """Run ``fn`` batch by batch, as featurize's motion tasks do (memory stays at a batch)."""
    cpu, wall = time.process_time(), time.perf_counter()
    parts: dict[str, list[np.ndarray]] = {k: [] for k in NAMES}
    for start in range(0, len(aa), BATCH):
        stop = min(start + BATCH, len(aa))
        inside = bounds[(bounds[:, 0] >= start) & (bounds[:, 0] < stop)]
        local = np.clip(inside - start, 0, stop - start)
        for k, v in fn(aa[start:stop], local).items():
            parts[k].append(v)
    out = {k: np.concatenate(v) for k, v in parts.items()}
    return time.process_time() - cpu, time.perf_counter() - wall, out


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
    dancedata_path(aa[:100], bounds[:1] // 730)  # load the compiled code (cached on disk)
    per_m = 1e6 / args.frames
    best: dict[str, list[float]] = {"scipy": [], "dancedata": []}
    for _ in range(args.rounds):
        for name, fn in (("scipy", scipy_path), ("dancedata", dancedata_path)):
            cpu, wall, out = measure(fn, aa, bounds)
            best[name].append(cpu)
            print(f"{name:10s} cpu {cpu * per_m:6.2f} s/Mframe  wall {wall * per_m:6.2f} s/Mframe")
            if name == "scipy":
                reference = out
            else:
                worst = max(float(np.abs(out[k] - reference[k]).max()) for k in NAMES)
                print(f"           max |dancedata - scipy| over the four arrays: {worst:.3g}")
    s, d = min(best["scipy"]), min(best["dancedata"])
    print(
        f"best CPU per million frames: scipy {s * per_m:.2f} s, dancedata {d * per_m:.2f} s, "
        f"x{s / d:.1f}; load {os.getloadavg()[0]:.1f}, {args.frames} frames x 24 joints"
    )


if __name__ == "__main__":
    main()
