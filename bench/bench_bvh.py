"""BVH parse throughput: dancedata's reader against a pure-Python line-by-line parse.

Builds a ~50 MB BVH in a temporary directory by repeating the motion rows of the real CMU file
01_01.bvh (96 channels, 120 fps) and times, best of a few runs:

* ``dancedata``: :func:`dancedata.io.bvh.read_bvh` (hierarchy tokenizer + pyarrow rows);
* ``numpy.loadtxt``: numpy's C text parser on the motion rows only (context);
* ``pure Python``: the motion rows only, ``[float(t) for t in line.split()]`` per line, then
  ``np.array`` — a lower bound for any line-by-line Python reader, which would also have to
  parse the hierarchy.

Usage: .venv/bin/python bench/bench_bvh.py [--mb 50] [--repeat 3]
"""

from __future__ import annotations

import argparse
import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dancedata.io.bvh import read_bvh

_DEFAULT_REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"


def build_large_bvh(source: Path, target: Path, megabytes: float) -> tuple[int, int]:
    """Write ``source``'s hierarchy and its motion rows repeated to about ``megabytes`` MB.
    Returns (frames, bytes)."""
    data = source.read_bytes()
    header_end = data.index(b"MOTION")
    body = data[data.index(b"\n", data.index(b"Frame Time")) + 1 :]
    rows = [r for r in body.split(b"\n") if r.strip()]
    reps = max(1, int(megabytes * 1e6 / len(body)) + 1)
    frames = len(rows) * reps
    motion = b"\n".join(rows) + b"\n"
    with target.open("wb") as f:
        f.write(data[:header_end])
        f.write(b"MOTION\nFrames: %d\nFrame Time: .0083333\n" % frames)
        for _ in range(reps):
            f.write(motion)
    return frames, target.stat().st_size


def motion_rows(path: Path) -> bytes:
    data = path.read_bytes()
    return data[data.index(b"\n", data.index(b"Frame Time")) + 1 :]


def pure_python(path: Path) -> np.ndarray:
    rows = []
    with path.open() as f:
        for line in f:
            if line.startswith("Frame Time"):
                break
        for line in f:
            if line.strip():
                rows.append([float(t) for t in line.split()])
    return np.array(rows)


def numpy_loadtxt(path: Path) -> np.ndarray:
    return np.loadtxt(io.BytesIO(motion_rows(path)), dtype=np.float64, comments=None, ndmin=2)


def best_time(fn, repeat: int) -> tuple[float, object]:
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mb", type=float, default=50.0, help="size of the test file in MB")
    parser.add_argument("--repeat", type=int, default=3, help="runs per parser (best is kept)")
    args = parser.parse_args(argv)

    source = Path(os.environ.get("DANCEDATA_REAL_DATA", _DEFAULT_REAL)) / "bvh" / "01_01.bvh"
    if not source.is_file():
        print(f"real file not found: {source}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "large.bvh"
        frames, size = build_large_bvh(source, path, args.mb)
        mb = size / 1e6
        print(f"file: {mb:.1f} MB, {frames} frames x 96 channels (01_01.bvh rows repeated)")

        t_ours, clip = best_time(lambda: read_bvh(path), args.repeat)
        t_np, ref_np = best_time(lambda: numpy_loadtxt(path), args.repeat)
        t_py, ref_py = best_time(lambda: pure_python(path), args.repeat)
        assert np.array_equal(clip.values, ref_py) and np.array_equal(ref_np, ref_py)

    print(f"{'parser':<16}{'seconds':>9}{'MB/s':>9}{'vs pure Python':>16}")
    for name, t in [("dancedata", t_ours), ("numpy.loadtxt", t_np), ("pure Python", t_py)]:
        print(f"{name:<16}{t:>9.2f}{mb / t:>9.1f}{t_py / t:>15.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
