"""AIST++-scale ingest: ``dancedata ingest aist`` on the synthetic full twin against a baseline.

1. ``dancedata synth aist --full`` (1408 sequences, 60 songs, keypoints2d and cameras) into
   ``bench/out/aist-full-twin`` (git-ignored). It is reused while a stamp of the synth sources
   matches; otherwise (or with ``--fresh``) it is rebuilt and the synth time is reported.
2. Times, each in its own subprocess, with the peak RSS of that process (``os.wait4``):
   * ``dancedata ingest aist`` into a new temporary store (checksums every input, streams every
     annotation into chunked, compressed zarr arrays, writes the tables);
   * the same with ``--workers <CPUs>`` (the reads in parallel processes);
   * the same on one genre (``--genres gBR``, ~1/10 of the data): peak RSS should not grow
     with dataset size;
   * a baseline in the style of public preprocessing scripts: ``pickle.load`` every motion,
     keypoints3d and keypoints2d pickle and ``np.save`` one .npy per sequence and array
     (no checksums, no validation, no compression, no tables).

Page cache is warm for all runs (the twin was just written or read). Usage:
    .venv/bin/python bench/bench_ingest.py [--fresh] [--keep]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
TWIN = HERE / "out" / "aist-full-twin"
STAMP = HERE / "out" / "aist-full-twin.stamp"
BIN = Path(sys.executable).parent / "dancedata"
# The twin depends on these sources only (and on the seed, fixed at 0).
SYNTH_SOURCES = ("dancedata/synth/*.py", "dancedata/compute/camera.py", "dancedata/compute/smpl.py")

BASELINE = r"""
import pickle, sys
from pathlib import Path
import numpy as np

raw, out = Path(sys.argv[1]), Path(sys.argv[2])
out.mkdir(parents=True, exist_ok=True)
for path in sorted((raw / "motions").glob("*.pkl")):
    seq = path.stem
    with open(path, "rb") as f:
        m = pickle.load(f)
    np.save(out / f"{seq}_poses.npy", m["smpl_poses"])
    np.save(out / f"{seq}_trans.npy", m["smpl_trans"] / m["smpl_scaling"])
    k3 = raw / "keypoints3d" / f"{seq}.pkl"
    if k3.exists():
        with open(k3, "rb") as f:
            k = pickle.load(f)
        np.save(out / f"{seq}_kp3d.npy", (k["keypoints3d"] / 100).astype(np.float32))
        np.save(out / f"{seq}_kp3d_optim.npy", (k["keypoints3d_optim"] / 100).astype(np.float32))
    k2 = raw / "keypoints2d" / f"{seq}.pkl"
    if k2.exists():
        with open(k2, "rb") as f:
            k = pickle.load(f)
        np.save(out / f"{seq}_kp2d.npy", k["keypoints2d"])
        np.save(out / f"{seq}_det.npy", k["det_scores"])
"""


def run_measured(label: str, argv: list[str]) -> tuple[float, float]:
    """Run ``argv``; return (wall seconds, peak RSS in MB of that process). Prints the 1-min
    load average at the start: on a shared machine it explains slow runs."""
    print(f"  {label}: starting at load average {os.getloadavg()[0]:.1f}", flush=True)
    start = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    stderr = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}):\n{stderr}")
    return wall, usage.ru_maxrss / 1024.0  # Linux reports KiB


def synth_stamp() -> str:
    """sha256 over the sources the synthetic twin is made from."""
    digest = hashlib.sha256()
    for pattern in SYNTH_SOURCES:
        for path in sorted(HERE.parent.glob(pattern)):
            digest.update(path.name.encode() + path.read_bytes())
    return digest.hexdigest()


def du_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) / 1e6


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fresh", action="store_true", help="rebuild the synthetic twin")
    parser.add_argument("--keep", action="store_true", help="keep the store and .npy output")
    args = parser.parse_args(argv)

    stamp = synth_stamp()
    current = TWIN.exists() and STAMP.is_file() and STAMP.read_text() == stamp
    if args.fresh or not current:
        shutil.rmtree(TWIN, ignore_errors=True)
        TWIN.parent.mkdir(parents=True, exist_ok=True)
        load = os.getloadavg()[0]
        wall, rss = run_measured(
            "synth --full", [str(BIN), "synth", "aist", str(TWIN), "--full", "-q"]
        )
        STAMP.write_text(stamp)
        print(
            f"synth aist --full: {wall:.1f} s wall, peak RSS {rss:.0f} MB (main process; "
            f"{os.cpu_count()} CPUs, 1-min load average at start {load:.1f})"
        )
    n_seq = len(list((TWIN / "motions").glob("*.pkl")))
    print(f"twin: {TWIN} — {n_seq} sequences, {du_mb(TWIN):.0f} MB")

    tmp = Path(tempfile.mkdtemp(prefix="bench-ingest-", dir=HERE / "out"))
    try:
        ingest = [str(BIN), "ingest", "aist", str(TWIN), "-q", "--store"]
        t_ours, rss_ours = run_measured("ingest (all)", [*ingest, str(tmp / "store")])
        store_mb = du_mb(tmp / "store")
        jobs = os.cpu_count() or 1
        t_par, rss_par = run_measured(
            f"ingest -j {jobs}", [*ingest, str(tmp / "store-j"), "--workers", str(jobs)]
        )
        t_one, rss_one = run_measured(
            "ingest (gBR)", [*ingest, str(tmp / "store-gBR"), "--genres", "gBR"]
        )
        t_base, rss_base = run_measured(
            "baseline", [sys.executable, "-c", BASELINE, str(TWIN), str(tmp / "npy")]
        )
        npy_mb = du_mb(tmp / "npy")
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)

    print(f"{'run':<34}{'wall s':>8}{'peak RSS MB':>13}{'output MB':>11}")
    print(f"{'dancedata ingest aist (all)':<34}{t_ours:>8.1f}{rss_ours:>13.0f}{store_mb:>11.0f}")
    label = f"dancedata ingest aist -j {jobs}"
    print(f"{label:<34}{t_par:>8.1f}{rss_par:>13.0f}{'':>11}")
    print(f"{'dancedata ingest aist (gBR only)':<34}{t_one:>8.1f}{rss_one:>13.0f}{'':>11}")
    print(f"{'baseline pickle → per-seq .npy':<34}{t_base:>8.1f}{rss_base:>13.0f}{npy_mb:>11.0f}")
    print(
        f"ratios dancedata / baseline: time {t_ours / t_base:.2f}x (-j {jobs}: "
        f"{t_par / t_base:.2f}x), peak RSS "
        f"{rss_ours / rss_base:.2f}x, output size {store_mb / npy_mb:.2f}x; "
        f"peak RSS all / one genre {rss_ours / rss_one:.2f}x"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
