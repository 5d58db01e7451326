"""BVH collection ingest: ``dancedata ingest bvh DIR --workers 2`` against the same files serially.

1. Synthesizes a folder of ``--files`` BVH files (default 1,000) in a temporary directory from
   the real CMU file ``01_01.bvh`` (cgspeed conversion: 31 joints, 96 channels, 120 fps; read
   from ``../shared/data/real`` or ``$DANCEDATA_REAL_DATA`` at bench time, never copied into the
   repository): file i holds ``--frames`` consecutive frames starting at a seeded offset, with
   seeded Gaussian noise (σ 0.5°) added to every rotation channel, written by
   :func:`dancedata.io.bvh.write_bvh`. One rig, one frame rate: one store.
2. Times, each in its own subprocess (wall and CPU seconds of the process tree):
   * ``dancedata ingest bvh DIR --units 0.056444 --store S1`` (serial);
   * the same with ``--workers N`` into ``S2`` (the reads in N processes);
   and checks that both stores hold the same bytes (``checksums.json`` files, every table).

Page cache is warm (the files were just written). Usage:
    .venv/bin/python bench/bench_bvh_ingest.py [--files 1000] [--frames 240] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dancedata.io.bvh import BvhClip, read_bvh, write_bvh

BIN = Path(sys.executable).parent / "dancedata"
REAL = Path(
    os.environ.get(
        "DANCEDATA_REAL_DATA", Path(__file__).resolve().parents[1].parent / "shared/data/real"
    )
)
SOURCE_FILE = "bvh/01_01.bvh"
CMU_UNITS = "0.056444"  # cgspeed BVH: metres per file unit
NOISE_DEG = 0.5


def synthesize(folder: Path, n_files: int, n_frames: int, seed: int = 0) -> tuple[int, int]:
    """Write ``n_files`` perturbed windows of the CMU file into ``folder``; returns
    (total frames, total bytes)."""
    source = read_bvh(REAL / SOURCE_FILE)
    skeleton = source.skeleton
    rotation = np.array(
        [
            channel.endswith("rotation")
            for j in range(skeleton.n_joints)
            for channel in skeleton.channels[j]
        ]
    )
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    n_frames = min(n_frames, source.n_frames)
    total_bytes = 0
    for i in range(n_files):
        start = int(rng.integers(0, source.n_frames - n_frames + 1))
        values = source.values[start : start + n_frames].copy()
        values[:, rotation] += rng.normal(0.0, NOISE_DEG, (n_frames, int(rotation.sum())))
        path = folder / f"take_{i:04d}.bvh"
        write_bvh(BvhClip(skeleton, source.frame_time_s, values), path)
        total_bytes += path.stat().st_size
    return n_files * n_frames, total_bytes


def timed(argv: list[str]) -> tuple[float, float, dict]:
    """Wall seconds, CPU seconds (the process and its children), and its JSON summary."""
    start = time.perf_counter()
    before = os.times()
    proc = subprocess.run(argv, capture_output=True, text=True)
    after = os.times()
    wall = time.perf_counter() - start
    if proc.returncode:
        sys.exit(f"{' '.join(argv)} failed:\n{proc.stderr}")
    cpu = (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )
    return wall, cpu, json.loads(proc.stdout)


def store_digest(store: Path) -> dict:
    """checksums.json's per-file checksums of the store's one version (manifest times left out)."""
    checksums = json.loads((store / "versions" / "v1" / "checksums.json").read_text())
    return checksums["files"]


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=1000)
    parser.add_argument("--frames", type=int, default=240)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    if not (REAL / SOURCE_FILE).is_file():
        print(f"skipped: {REAL / SOURCE_FILE} not found (set DANCEDATA_REAL_DATA)")
        return 0
    with tempfile.TemporaryDirectory(prefix="bench-bvh-ingest-") as tmp:
        folder = Path(tmp) / "bvh"
        t0 = time.perf_counter()
        frames, size = synthesize(folder, args.files, args.frames)
        print(
            f"data: {args.files} files x {args.frames} frames (120 fps, 31 joints) = {frames:,} "
            f"frames, {size / 1e6:.0f} MB, written in {time.perf_counter() - t0:.1f} s"
        )
        print(
            f"machine: {os.cpu_count()} CPUs, {platform.processor() or platform.machine()}, "
            f"Python {platform.python_version()}, load average {os.getloadavg()[0]:.1f} at start"
        )
        common = [str(BIN), "ingest", "bvh", str(folder), "--units", CMU_UNITS, "-q", "--json"]
        serial = timed([*common, "--store", str(Path(tmp) / "serial")])
        parallel = timed(
            [*common, "--store", str(Path(tmp) / "parallel"), "--workers", str(args.workers)]
        )
        same = store_digest(Path(tmp) / "serial") == store_digest(Path(tmp) / "parallel")
        print(f"{'run':<32}{'wall s':>8}{'CPU s':>8}{'files/s':>9}")
        for label, (wall, cpu, summary) in (
            ("ingest bvh (serial)", serial),
            (f"ingest bvh --workers {args.workers}", parallel),
        ):
            assert summary["counts"]["sequences"] == args.files
            print(f"{label:<32}{wall:>8.1f}{cpu:>8.1f}{args.files / wall:>9.1f}")
        print(f"ratio serial / --workers {args.workers}: x{serial[0] / parallel[0]:.2f} (wall)")
        print(f"read tasks: {parallel[2]['counts']['units']} of 8 files each")
        print(f"stores byte-identical (checksums.json files): {same}")
        print(f"load average at end {os.getloadavg()[0]:.1f}")
        return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
