"""Read one generated-motion file in the layouts that dance generators write.

A folder of generated motion holds one file per sequence, named by sequence id
(``<seq_id>.npy|.npz|.pkl``). Layouts recognised (a leading batch axis of 1 is dropped):

* ``fact225`` — FACT / mint rows (F, 225): 6 zeros, root translation (3, m), 24 row-major
  rotation matrices (216); ``.npy`` (mint ``outputs/*.npy``), or a pickle / ``.npz`` holding
  the rows under ``motion``, or mint's legacy ``pred_motion`` (F, 216) + ``pred_trans`` (F, 3).
* ``smpl`` — SMPL pose + translation (Bailando, EDGE, AIST++ annotations): ``smpl_poses``
  (F, 72) or (F, 24, 3) axis-angle (rad) with ``smpl_trans`` (F, 3), divided by ``smpl_scaling``
  when present (as AIST++ stores it). EDGE also writes ``full_pose`` (F, 24, 3) joint
  positions, which are kept alongside.
* ``positions`` — joint positions (F, J, 3) in metres: a ``.npy`` array, or ``positions`` /
  ``full_pose`` / ``pred_position`` (F, J·3 or J, 3) in a pickle or ``.npz``.

Pickles are read by the restricted unpickler (:mod:`dancedata.safe_pickle`), never by
``pickle.load``; ``.npy``/``.npz`` with ``allow_pickle=False``. Every problem raises
:class:`~dancedata.errors.InputError` naming the file. No unit or axis conversion happens here:
the caller records what it assumes (frame rate, y up).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError

__all__ = ["GENERATED_SUFFIXES", "GeneratedMotion", "find_generated_file", "read_generated_motion"]

GENERATED_SUFFIXES = (".npy", ".npz", ".pkl")
_POSITION_KEYS = ("positions", "full_pose", "pred_position")


@dataclass(frozen=True)
class GeneratedMotion:
    """The arrays of one generated sequence (float64), as found in the file.

    Attributes:
        layout: ``fact225``, ``smpl`` or ``positions``.
        path: the file read.
        fact_rows: (F, 225) FACT rows (``fact225``), else None.
        axis_angle: (F, 24, 3) SMPL axis-angle in rad (``smpl``), else None.
        trans: (F, 3) root translation in metres (``smpl``), else None.
        positions: (F, J, 3) joint positions in metres when the file holds them, else None.
    """

    layout: str
    path: str
    fact_rows: np.ndarray | None = None
    axis_angle: np.ndarray | None = None
    trans: np.ndarray | None = None
    positions: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        for array in (self.fact_rows, self.axis_angle, self.positions):
            if array is not None:
                return int(array.shape[0])
        return 0


def find_generated_file(folder: Path, seq_id: str) -> Path | None:
    """``folder/<seq_id>.npy|.npz|.pkl`` (first found in that order); else the one file named
    ``<prefix>_<seq_id>.<suffix>`` (EDGE writes ``<epoch>_<name>.pkl``); else None. Several
    prefixed files for one sequence are ambiguous: InputError."""
    for suffix in GENERATED_SUFFIXES:
        candidate = folder / f"{seq_id}{suffix}"
        if candidate.is_file():
            return candidate
    prefixed = sorted(
        p
        for suffix in GENERATED_SUFFIXES
        for p in folder.glob(f"*_{seq_id}{suffix}")
        if p.is_file()
    )
    if len(prefixed) > 1:
        names = ", ".join(p.name for p in prefixed[:4])
        raise InputError(f"several generated files for {seq_id} ({names}): keep one", folder)
    return prefixed[0] if prefixed else None


MAX_MEMBER_BYTES = 1 << 30  # one array of an .npz: far above any motion clip


def _check_npz_members(path: Path) -> None:
    """Refuse an .npz whose members claim more data than they hold, or more than
    :data:`MAX_MEMBER_BYTES`, before numpy allocates anything (numpy allocates the claimed
    shape first, then reads)."""
    import zipfile

    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            if info.file_size > MAX_MEMBER_BYTES:
                raise InputError(
                    f"member {info.filename} unpacks to {info.file_size} bytes "
                    f"(at most {MAX_MEMBER_BYTES} are read)",
                    path,
                )
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                read_header = (
                    np.lib.format.read_array_header_1_0
                    if version == (1, 0)
                    else np.lib.format.read_array_header_2_0
                )
                shape, _, dtype = read_header(member)
                claimed = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if claimed > info.file_size:
                    raise InputError(
                        f"member {info.filename} claims {shape} {dtype} but holds "
                        f"{info.file_size} bytes",
                        path,
                    )


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":  # mmap checks the claimed shape against the file's size
            return {"array": np.array(np.load(path, mmap_mode="r", allow_pickle=False))}
        if suffix == ".npz":
            _check_npz_members(path)
            with np.load(path, allow_pickle=False) as npz:
                return {k: np.asarray(npz[k]) for k in npz.files}
    except InputError:
        raise
    except Exception as exc:  # OSError, ValueError, EOFError, MemoryError, BadZipFile, ...
        reason = f"{type(exc).__name__}: {str(exc)[:200]}"
        raise InputError(f"cannot read as a numpy file ({reason})", path) from None
    if suffix == ".pkl":
        from dancedata.safe_pickle import load_restricted

        data = load_restricted(path)
        if isinstance(data, np.ndarray):
            return {"array": data}
        if not isinstance(data, dict):
            raise InputError(
                f"a generated-motion pickle must hold a dict of arrays, not {type(data).__name__}",
                path,
            )
        return {str(k): np.asarray(v) for k, v in data.items() if isinstance(v, np.ndarray)}
    raise InputError(f"generated motion must be one of {', '.join(GENERATED_SUFFIXES)}", path)


def _numbers(name: str, value: np.ndarray, path: Path) -> np.ndarray:
    array = np.asarray(value)
    if array.ndim >= 2 and array.shape[0] == 1:
        array = array[0]  # a batch of one
    if not np.issubdtype(array.dtype, np.number) or np.issubdtype(array.dtype, np.complexfloating):
        raise InputError(f"{name} must hold real numbers, not {array.dtype}", path)
    array = array.astype(np.float64)
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} holds NaN or Inf", path)
    if array.ndim == 0 or array.shape[0] < 2:
        raise InputError(f"{name} has {array.shape[0] if array.ndim else 0} frames (need 2)", path)
    return array


def _positions(name: str, value: np.ndarray, path: Path) -> np.ndarray:
    array = _numbers(name, value, path)
    if array.ndim == 2 and array.shape[1] % 3 == 0:
        array = array.reshape(array.shape[0], -1, 3)
    if array.ndim != 3 or array.shape[2] != 3:
        raise InputError(f"{name} must be (frames, joints, 3) positions, got {array.shape}", path)
    return array


def _fact_rows(name: str, value: np.ndarray, path: Path) -> np.ndarray:
    rows = _numbers(name, value, path)
    if rows.ndim != 2 or rows.shape[1] != 225:
        raise InputError(f"{name} must be (frames, 225) FACT rows, got {rows.shape}", path)
    return rows


def read_generated_motion(path: str | Path) -> GeneratedMotion:
    """Read one file and recognise its layout (module docstring); InputError for anything
    else, naming the file and what was found."""
    path = Path(path)
    data = _read_arrays(path)
    positions = None
    for key in _POSITION_KEYS:
        if key in data:
            positions = _positions(key, data[key], path)
            break
    if "smpl_poses" in data and "smpl_trans" in data:
        poses = _numbers("smpl_poses", data["smpl_poses"], path)
        if poses.ndim == 2 and poses.shape[1] == 72:
            poses = poses.reshape(-1, 24, 3)
        if poses.ndim != 3 or poses.shape[1:] != (24, 3):
            raise InputError(f"smpl_poses must be (frames, 72), got {poses.shape}", path)
        trans = _numbers("smpl_trans", data["smpl_trans"], path).reshape(poses.shape[0], -1)
        if trans.shape != (poses.shape[0], 3):
            raise InputError(
                f"smpl_trans must be ({poses.shape[0]}, 3) like smpl_poses, got "
                f"{data['smpl_trans'].shape}",
                path,
            )
        if "smpl_scaling" in data:
            scale = np.asarray(data["smpl_scaling"], dtype=np.float64).reshape(-1)
            if scale.size != 1 or not np.isfinite(scale[0]) or scale[0] <= 0:
                raise InputError("smpl_scaling must be one positive number", path)
            trans = trans / scale[0]
        return GeneratedMotion(
            "smpl", str(path), axis_angle=poses, trans=trans, positions=positions
        )
    if "pred_motion" in data and "pred_trans" in data:  # mint's legacy result pickles
        motion = _numbers("pred_motion", data["pred_motion"], path)
        motion = motion.reshape(motion.shape[0], -1)
        trans = _numbers("pred_trans", data["pred_trans"], path)
        if motion.shape[1] != 216 or trans.shape != (motion.shape[0], 3):
            raise InputError(
                f"pred_motion (F, 216) and pred_trans (F, 3) expected, got {motion.shape} "
                f"and {trans.shape}",
                path,
            )
        rows = np.concatenate([np.zeros((motion.shape[0], 6)), trans, motion], axis=1)
        return GeneratedMotion("fact225", str(path), fact_rows=rows, positions=positions)
    array = data.get("array", data.get("motion"))
    if array is not None:
        shape = np.shape(array)
        squeezed = shape[1:] if len(shape) >= 3 and shape[0] == 1 else shape
        if len(squeezed) == 2 and squeezed[1] == 225:
            return GeneratedMotion("fact225", str(path), fact_rows=_fact_rows("rows", array, path))
        if len(squeezed) == 3 and squeezed[2] == 3:
            found_positions = _positions("array", array, path)
            return GeneratedMotion("positions", str(path), positions=found_positions)
    if positions is not None:
        return GeneratedMotion("positions", str(path), positions=positions)
    found = {k: tuple(v.shape) for k, v in data.items()}
    raise InputError(
        f"unknown generated-motion layout (found {found}): expected (F, 225) FACT rows, "
        "smpl_poses + smpl_trans, or (F, J, 3) joint positions",
        path,
    )
