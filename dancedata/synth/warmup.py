"""Compile, once per machine, the numba code a featurize runs: the synthetic sample through it.

numba keeps compiled machine code on disk (``cache=True``), one folder per process's
``NUMBA_CACHE_DIR`` (the ``dancedata`` command points it at ``~/.cache/dancedata/numba``; worker
slots and the test suite's workers seed their own folders from there). A process whose folder is
empty compiles before its first track: librosa's gufuncs, which its modules build when imported
(measured: ≈ 21 CPU s), then dancedata's kernels (≈ 3 s). :func:`warm_kernels` pays that once,
serially, by running the real chain on a one-sequence synthetic AIST++ sample in a temporary
folder (synth → ingest → featurize with the default feature set and no feature cache), then
runs the rotation conversions in the other dtypes the readers and studies call them with (each
dtype is a compile of its own, ≈ 1 CPU s) and imports ``librosa.beat``, whose gufuncs the
Bailando beat metric uses. Nothing it writes outside
the numba folder survives: the sample and its store are deleted.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path
from typing import Any


def compiled_files(folder: Path) -> int:
    """numba's index and data files (``*.nbi``, ``*.nbc``) under ``folder``, its worker slots
    included; 0 when it does not exist."""
    if not folder.is_dir():
        return 0
    return sum(1 for p in folder.rglob("*.nb[ic]") if p.is_file() and not p.is_symlink())


def warm_kernels() -> dict[str, Any]:
    """Run the one-sequence sample through synth, ingest and featurize (default set, serial,
    feature cache off) in a temporary folder, convert rotations as the read API does, and
    import ``librosa.beat``; returns the numba
    folder of this process, its compiled files before and after, and the wall seconds.

    Must run in a process that has not imported numba yet with ``NUMBA_CACHE_DIR`` already set
    (numba reads it once), as the ``dancedata`` command does; otherwise numba caches beside
    each source file and the count reads 0.
    """
    from dancedata.exec.numba_cache import ENV_VAR

    folder = Path(os.environ[ENV_VAR]) if os.environ.get(ENV_VAR) else None
    before = compiled_files(folder) if folder else 0
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="dancedata-warmup-") as scratch:
        _run_sample(Path(scratch))
    _rotation_conversions()
    import librosa.beat  # noqa: F401 - its gufuncs compile (or load) at import

    return {
        "numba_cache_dir": str(folder) if folder else None,
        "compiled_files_before": before,
        "compiled_files_after": compiled_files(folder) if folder else 0,
        "seconds": round(time.perf_counter() - start, 2),
    }


def _run_sample(scratch: Path) -> None:
    """synth (1 sequence) → ingest → featurize in ``scratch``."""
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.ingest.aist.inputs import AistIngestOptions
    from dancedata.ingest.options import ingest_into
    from dancedata.synth.aist import synth_aist

    raw, store = scratch / "raw", scratch / "store"
    synth_aist(raw, n_sequences=1, seed=0, workers=1)
    ingest_into(store, "aist", raw, AistIngestOptions())
    featurize(store, FeaturizeOptions(use_cache=False))


def _rotation_conversions() -> None:
    """The compiled rotation conversions for float32 and float64 axis-angle in and out, with
    and without sign-continuous spans (featurize compiles only float64 in, float32 out)."""
    import numpy as np

    from dancedata.compute.rotation_kernels import (
        rotation_representations,
        rotations_from_axis_angle,
    )

    names = ("quat", "rotmat", "euler", "rot6d", "rot6d_rows")
    for dtype in (np.float32, np.float64):
        aa = np.full((3, 2, 3), 0.25, dtype=dtype)
        rotations_from_axis_angle(aa)
        rotation_representations(aa, names, "XYZ", dtype=dtype, bounds=np.array([[0, 3]]))
    overlapping = np.array([[0, 2], [1, 3]])  # quaternion signs span by span (_sign_spans)
    rotation_representations(aa, names, "XYZ", dtype=np.float64, bounds=overlapping)
