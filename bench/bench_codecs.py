"""The chunk compressor: dancedata's (Blosc, zstd level 1, byte shuffle, 1 MiB blocks) against
the two it replaced, on the arrays a store holds most of, side by side in one process.

* ``zstd3``: zarr's default for numeric arrays (zstd level 3 over the whole chunk), which
  dancedata used for the motion and audio arrays before;
* ``blosc_auto``: Blosc zstd level 1 with byte shuffle and Blosc's own block size, which it used
  for the AIST++ keypoint arrays before;
* ``blosc_1mib``: the same with 1 MiB blocks, now every array's compressor
  (``dancedata.store.arrays.default_compressor``).

The arrays: the real AIST++ annotations (``$DANCEDATA_REAL_DATA/aist`` or
``../shared/data/real/aist``) when present, and a synthetic twin of 8 sequences, each ingested
and featurized (motion only) into a temporary store; then keypoints2d, keypoints3d, axis_angle
and the rotation representations are cut into the store's 8192-frame chunks and each chunk is
encoded and decoded with each compressor on one thread (as zarr's codec threads call it).
Reported: CPU seconds per GB of raw data to encode and to decode (the lowest of ``--rounds``)
and the compressed size as a share of raw.

    .venv/bin/python bench/bench_codecs.py [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
ARRAYS = ("keypoints2d", "keypoints3d", "axis_angle", "rotmat", "quat", "rot6d")
CHUNK = 8192


def compressors() -> dict[str, Any]:
    import numcodecs
    from numcodecs import Blosc, Zstd

    from dancedata.store.arrays import BLOSC_BLOCK_BYTES

    numcodecs.blosc.set_nthreads(1)
    return {
        "zstd3": Zstd(level=0),  # level 0: zstd's default, 3 (zarr's ZstdCodec(level=0))
        "blosc_auto": Blosc("zstd", 1, Blosc.SHUFFLE),
        "blosc_1mib": Blosc("zstd", 1, Blosc.SHUFFLE, blocksize=BLOSC_BLOCK_BYTES),
    }


def real_aist() -> Path | None:
    root = os.environ.get("DANCEDATA_REAL_DATA")
    candidates = [Path(root)] if root else []
    candidates.append(REPO.parent / "shared" / "data" / "real")
    for base in candidates:
        if (base / "aist" / "motions").is_dir():
            return base / "aist"
    return None


def featurized_store(raw: Path, store: Path) -> Path:
    """``raw`` ingested and featurized (motion only); the path of the latest data.zarr."""
    cli = [sys.executable, "-m", "dancedata.cli"]
    ingest = [*cli, "ingest", "aist", str(raw), "--store", str(store), "-q"]
    subprocess.run([*ingest, "--allow-missing-music"], check=True, cwd=REPO)
    subprocess.run([*cli, "featurize", str(store), "-q", "--no-audio"], check=True, cwd=REPO)
    versions = sorted((store / "versions").glob("v*"), key=lambda p: int(p.name[1:]))
    return versions[-1] / "data.zarr"


def measure(values: np.ndarray, codec: Any, rounds: int) -> tuple[float, float, float]:
    """(encode CPU s per GB, decode CPU s per GB, compressed share of raw), chunk by chunk."""
    chunks = [np.ascontiguousarray(values[i : i + CHUNK]) for i in range(0, len(values), CHUNK)]
    encode, decode = [], []
    for _ in range(rounds):
        start = time.process_time()
        frames = [codec.encode(chunk) for chunk in chunks]
        encode.append(time.process_time() - start)
        start = time.process_time()
        for frame in frames:
            codec.decode(frame)
        decode.append(time.process_time() - start)
    size = sum(len(frame) for frame in frames)
    gb = values.nbytes / 1e9
    return min(encode) / gb, min(decode) / gb, size / values.nbytes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    import zarr

    from dancedata.synth.aist import synth_aist

    codecs = compressors()
    with tempfile.TemporaryDirectory() as tmp:
        sources: dict[str, Path] = {}
        real = real_aist()
        if real is not None:
            sources["real AIST++"] = featurized_store(real, Path(tmp) / "real")
        synth_aist(Path(tmp) / "twin-raw", n_sequences=8, seed=3)
        sources["synthetic twin"] = featurized_store(Path(tmp) / "twin-raw", Path(tmp) / "twin")
        for label, root in sources.items():
            print(f"{label}:")
            units = "enc  dec s/GB  size"
            print(f"  {'array':<12} {'frames':>7}  " + "  ".join(f"{n:>24}" for n in codecs))
            print(f"  {'':<12} {'':>7}  " + "  ".join(f"{units:>24}" for _ in codecs))
            for name in ARRAYS:
                path = root / "motion" / name
                if not (path / "zarr.json").is_file():
                    continue
                values = np.asarray(zarr.open_array(path, mode="r")[:])
                cells = []
                for codec in codecs.values():
                    enc, dec, share = measure(values, codec, args.rounds)
                    cells.append(f"{enc:6.2f} {dec:6.2f}  {share * 100:5.1f} %")
                print(f"  {name:<12} {len(values):>7}  " + "  ".join(f"{c:>24}" for c in cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
