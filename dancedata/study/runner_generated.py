"""Class M rows (trained in-betweeners): their in-betweens come from a model's output files.

A row's outputs are a folder of per-sequence files named by sequence id, the sequence's whole
motion from its frame 0 at 60 fps (only the frames of complete measures are scored): the
folder layout ``dancedata evaluate`` reads (:mod:`dancedata.io.generated_motion`), plus one
more layout for the thesis's own output space:

* ``<seq_id>.npy`` (F, 75): ``thesis_euler_75`` rows (trans m + 24 Euler triples in rad, the
  store's Euler order);
* ``<seq_id>.npy|.npz|.pkl`` with FACT (F, 225) rows (each matrix projected to the nearest
  rotation) or SMPL ``smpl_poses`` + ``smpl_trans``, read by
  :func:`dancedata.io.generated_motion.read_generated_motion`; converted to Euler angles in the
  store's order. Files with joint positions only cannot be scored in a rotation space and are
  reported.

Which folder serves which row: the config's ``[generated]`` table or ``--generated``, keyed by
``<row_key>@<N>`` (one N), ``<row_key>`` (every N) or ``*`` (a folder holding one subfolder
per ``<row_key>@<N>``). Every file read is hashed into the run id.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.methods.inbetween import Reconstruction, segment_map


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _euler75_npy(path: Path, max_frames: int) -> np.ndarray | None:
    """(F, 75) rows of a ``.npy`` in the thesis layout, or None for any other layout; a file
    declaring more than ``max_frames`` frames is refused before it is read."""
    if path.suffix.lower() != ".npy":
        return None
    try:
        values = np.load(path, allow_pickle=False, mmap_mode="r")
    except (OSError, ValueError) as exc:
        if "allow_pickle" in str(exc):
            return None  # a pickled .npy: read_generated_motion knows the one safe layout
        raise InputError(f"unreadable generated motion: {exc}", path) from None
    if values.ndim == 3 and values.shape[0] == 1:
        values = values[0]
    if values.ndim != 2 or values.shape[1] != 75:
        return None
    if values.shape[0] > max_frames:
        raise InputError(
            f"{values.shape[0]} frames, more than the {max_frames} this sequence can use "
            "(twice the ground truth + 1200)",
            path,
        )
    return np.asarray(values, dtype=np.float64)


def _to_euler75(path: Path, order: Any, max_frames: int) -> np.ndarray | str:
    """(F, 75) Euler rows of one generated file, or the reason it cannot give them."""
    rows = _euler75_npy(path, max_frames)
    if rows is None:
        from dancedata.compute.motion_representations import euler_per_joint
        from dancedata.compute.rotations import axis_angle_to_rotmat
        from dancedata.io.generated_motion import read_generated_motion
        from dancedata.metrics.evaluate_inputs import fact_rows_to_smpl

        motion = read_generated_motion(path, max_frames)
        if motion.fact_rows is not None:
            axis_angle, trans = fact_rows_to_smpl(motion.fact_rows)
        elif motion.axis_angle is not None:
            axis_angle, trans = motion.axis_angle, motion.trans
        else:
            return f"{path} holds joint positions only ({motion.layout}): no rotations to score"
        euler = euler_per_joint(axis_angle_to_rotmat(axis_angle), order)
        rows = np.concatenate([trans, euler.reshape(len(euler), -1)], axis=1)
    if not np.isfinite(rows).all():
        raise InputError("generated motion holds NaN or infinite values", path)
    return rows


class GeneratedOutputs:
    """The model-output folders of a run, looked up per (row key, N)."""

    def __init__(self, mapping: dict[str, str], config: Any) -> None:
        self.mapping = {k: Path(v) for k, v in mapping.items()}
        self.used: dict[str, dict[str, Any]] = {}
        for key, folder in self.mapping.items():
            if not folder.is_dir():
                raise InputError(f"generated outputs for {key!r}: not a folder", folder)

    def folder(self, row_key: str, n: int) -> Path | None:
        for key in (f"{row_key}@{n}", row_key):
            if key in self.mapping:
                return self.mapping[key]
        if "*" in self.mapping:
            sub = self.mapping["*"] / f"{row_key}@{n}"
            if sub.is_dir():
                return sub
        return None

    def reconstruction(self, row_key: str, n: int, data: Any, rows: np.ndarray
                       ) -> Reconstruction | str:  # fmt: skip
        """The generated in-betweens of the measures ``rows``, or the reason there are none."""
        folder = self.folder(row_key, n)
        if folder is None:
            return (
                "class M (trained model): no outputs given; pass --generated <row_key>@<N>=DIR "
                "(one <seq_id>.npy|.npz|.pkl per sequence)"
            )
        from dancedata.io.generated_motion import find_generated_file, generated_frame_limit

        seqs = sorted(set(data.measure_seq[rows].tolist()))
        files = {s: find_generated_file(folder, data.sequences[s]["seq_id"]) for s in seqs}
        missing = [data.sequences[s]["seq_id"] for s in seqs if files[s] is None]
        if missing:
            return (
                f"generated outputs for {row_key}@{n} in {folder} miss {len(missing)} of "
                f"{len(seqs)} sequences (first: {missing[0]}.npy|.npz|.pkl)"
            )
        compact = np.zeros((len(data.trans), 75))
        hashes = {}
        for s in seqs:
            seq_id = data.sequences[s]["seq_id"]
            path = files[s]
            assert path is not None
            limit = generated_frame_limit(int(data.sequences[s]["n_frames"]))
            x75 = _to_euler75(path, data.euler_order, limit)
            if isinstance(x75, str):
                return x75
            mine = rows[data.measure_seq[rows] == s]
            need = int((data.local_start[mine] + data.length[mine]).max())
            if len(x75) < need:
                return f"{path} has {len(x75)} frames; the sequence's measures need {need}"
            a = int(data.seq_offset[s])
            span = int(data.sequences[s]["n_frames"])
            compact[a : a + min(span, len(x75))] = x75[:span]
            hashes[seq_id] = _sha256(path)
        self.used[f"{row_key}@{n}"] = {"folder": str(folder), "sha256": hashes}
        lengths = data.length[rows]
        edges = np.stack([np.zeros_like(lengths), lengths - 1], axis=1)
        seg = segment_map(data.start[rows], lengths, edges)
        picked = compact[seg.frame]
        return Reconstruction(
            seg, picked[:, :3], data.euler_order, euler=picked[:, 3:].reshape(len(picked), -1, 3)
        )

    def input_hashes(self) -> list[str]:
        return [f"{key}:{seq}:{h}" for key, used in sorted(self.used.items())
                for seq, h in sorted(used["sha256"].items())]  # fmt: skip

    def describe(self) -> dict[str, Any]:
        return {k: {"folder": v["folder"], "files": len(v["sha256"])} for k, v in self.used.items()}
