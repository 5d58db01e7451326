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
* ``rotations`` — any rig's joint rotations in the reference rig's joint order, with the root
  translation (F, 3) in metres under ``trans``: ``axis_angle`` (F, J, 3) radians or ``quat``
  (F, J, 4) quaternions wxyz (not necessarily unit), in an ``.npz`` or a pickle (a model
  trained on a BVH store's ``motion/quat`` writes these).
* ``positions`` — joint positions (F, J, 3) in metres: a ``.npy`` array, or ``positions`` /
  ``full_pose`` / ``pred_position`` (F, J·3 or J, 3) in a pickle or ``.npz``.

Pickles are read by the restricted unpickler (:mod:`dancedata.io.safe_pickle`), never by
``pickle.load``; ``.npy``/``.npz`` with ``allow_pickle=False``, except the one pickled ``.npy``
layout dance generators write, ``np.save(path, dict)`` (Bailando's ``{"pred_position": (F, 72)}``):
its dict is read by the same restricted unpickler, admitting only that 0-d object array around
a dict; any other object array is refused with how to convert it.

Sizes are checked before loading: an ``.npy`` header or each ``.npz`` member header must declare
at most ``max_frames`` frames (:func:`generated_frame_limit`: twice the ground truth plus 1200
frames) and at most 1024 values a frame, an ``.npz`` at most 64 members. Every problem raises
:class:`~dancedata.errors.InputError` naming the file. No unit or axis conversion happens here:
the caller records what it assumes (frame rate, y up).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import InputError

__all__ = [
    "GENERATED_SUFFIXES",
    "GeneratedMotion",
    "find_generated_file",
    "generated_frame_limit",
    "read_generated_arrays",
    "read_generated_motion",
]

GENERATED_SUFFIXES = (".npy", ".npz", ".pkl")
_POSITION_KEYS = ("positions", "full_pose", "pred_position")


@dataclass(frozen=True)
class GeneratedMotion:
    """The arrays of one generated sequence (float64), as found in the file.

    Attributes:
        layout: ``fact225``, ``smpl``, ``rotations`` or ``positions``.
        path: the file read.
        fact_rows: (F, 225) FACT rows (``fact225``), else None.
        axis_angle: (F, 24, 3) SMPL axis-angle in rad (``smpl``), (F, J, 3) (``rotations``
            given as axis-angle), else None.
        quat: (F, J, 4) wxyz quaternions as found (``rotations`` given as quaternions), else
            None.
        trans: (F, 3) root translation in metres (``smpl``, ``rotations``), else None.
        positions: (F, J, 3) joint positions in metres when the file holds them, else None.
    """

    layout: str
    path: str
    fact_rows: np.ndarray | None = None
    axis_angle: np.ndarray | None = None
    trans: np.ndarray | None = None
    positions: np.ndarray | None = None
    quat: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        for array in (self.fact_rows, self.axis_angle, self.quat, self.positions):
            if array is not None:
                return int(array.shape[0])
        return 0


def find_generated_file(folder: Path, seq_id: str) -> Path | None:
    """``folder/<seq_id>.npy|.npz|.pkl`` (first found in that order); else the one file named
    ``<prefix>_<seq_id>.<suffix>`` (EDGE writes ``<epoch>_<name>.pkl``); else None. Several
    prefixed files for one sequence are ambiguous: InputError.

    Names are compared as strings with the folder's own entries (never a glob, never a path
    built from ``seq_id``), so an id holding ``[``, ``*`` or ``../`` can only match a file of
    exactly that name directly inside ``folder``; ids with a path separator match nothing."""
    if not seq_id or "/" in seq_id or "\\" in seq_id or seq_id in (".", ".."):
        return None
    try:
        entries = os.listdir(folder)
    except OSError as exc:
        raise InputError(f"cannot list the folder: {exc.strerror}", folder) from None
    names = set(entries)
    for suffix in (*GENERATED_SUFFIXES, ".pkl.npy"):  # Bailando saves <name>.pkl with np.save
        name = f"{seq_id}{suffix}"
        if name in names and (folder / name).is_file():
            return folder / name
    tails = tuple(f"_{seq_id}{suffix}" for suffix in GENERATED_SUFFIXES)
    prefixed = sorted(
        folder / name for name in entries if name.endswith(tails) and (folder / name).is_file()
    )
    if len(prefixed) > 1:
        names_shown = ", ".join(p.name for p in prefixed[:4])
        raise InputError(f"several generated files for {seq_id} ({names_shown}): keep one", folder)
    return prefixed[0] if prefixed else None


MAX_MEMBER_BYTES = 1 << 30  # one array of an .npz: far above any motion clip
MAX_MEMBERS = 64  # arrays in one .npz (the layouts above use at most 4)
MAX_ROW_VALUES = 1024  # numbers per frame: FACT rows are 225, SMPL-X positions 127 × 3
FRAME_MARGIN = 1200  # frames beyond twice the ground truth (20 s at 60 fps)


def generated_frame_limit(gt_frames: int, src_fps: float | None = None,
                          dst_fps: float | None = None) -> int:  # fmt: skip
    """The most frames a generated file for a sequence of ``gt_frames`` ground-truth frames
    may hold: twice the ground truth at the file's frame rate (``src_fps``; the store's
    ``dst_fps`` when not given) plus :data:`FRAME_MARGIN`. Checked on the file's declared shapes
    before anything is loaded, so a header claiming gigabytes costs nothing."""
    ratio = (src_fps / dst_fps) if src_fps and dst_fps else 1.0
    return int(2 * gt_frames * ratio) + FRAME_MARGIN


def _read_npy_header(fh: Any, where: str, path: Path) -> tuple[tuple[int, ...], np.dtype]:
    try:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
    except Exception as exc:  # ValueError, EOFError, SyntaxError, ...: not a .npy header
        raise InputError(
            f"cannot read as a numpy file ({where}: {type(exc).__name__})", path
        ) from None
    return tuple(int(n) for n in shape), dtype


def _check_shape(shape: tuple[int, ...], dtype: np.dtype, where: str, path: Path,
                 max_frames: int | None) -> None:  # fmt: skip
    """Refuse a declared shape no motion layout has, or with more frames than allowed."""
    dims = shape[1:] if len(shape) >= 2 and shape[0] == 1 else shape
    frames = dims[0] if dims else 0
    row = int(np.prod(dims[1:], dtype=object)) if len(dims) > 1 else 1
    if len(dims) > 3 or row > MAX_ROW_VALUES:
        raise InputError(f"{where}: shape {shape} is not (frames, values) motion", path)
    if max_frames is not None and frames > max_frames:
        raise InputError(
            f"{where}: {frames} frames declared, more than the {max_frames} this sequence can "
            "use (twice the ground truth + 1200)",
            path,
        )
    if dtype.itemsize > 16:
        raise InputError(f"{where}: dtype {dtype} is not a number type", path)


def _check_npz_members(path: Path, max_frames: int | None) -> None:
    """Refuse an .npz with more than :data:`MAX_MEMBERS` arrays, or whose members claim more
    data than they hold, more than :data:`MAX_MEMBER_BYTES`, or more frames than
    ``max_frames``, before numpy allocates anything (numpy allocates the claimed shape first,
    then reads)."""
    import zipfile

    with zipfile.ZipFile(path) as archive:
        infos = archive.infolist()
        if len(infos) > MAX_MEMBERS:
            raise InputError(
                f"an .npz of {len(infos)} members (at most {MAX_MEMBERS} arrays are read)", path
            )
        for info in infos:
            if info.file_size > MAX_MEMBER_BYTES:
                raise InputError(
                    f"member {info.filename[:80]} unpacks to {info.file_size} bytes "
                    f"(at most {MAX_MEMBER_BYTES} are read)",
                    path,
                )
            with archive.open(info) as member:
                where = f"member {info.filename[:80]}"
                shape, dtype = _read_npy_header(member, where, path)
                if dtype.hasobject:
                    raise InputError(f"{where}: object arrays (pickles) are not read", path)
                claimed = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if claimed > info.file_size:
                    raise InputError(
                        f"{where} claims {shape} {dtype} but holds {info.file_size} bytes",
                        path,
                    )
                _check_shape(shape, dtype, where, path, max_frames)


class _ObjectDtype:
    """Stands in for numpy's object dtype inside a pickled ``np.save`` of a dict: never a real
    dtype, so no object array is ever built."""

    def __setstate__(self, state: Any) -> None:
        if not (isinstance(state, tuple) and len(state) == 8 and state[:7] == (
                3, "|", None, None, None, -1, -1)):  # fmt: skip
            raise InputError(f"object dtype state {str(state)[:80]} is not numpy's")


def _make_dict_unpickler() -> Any:
    """The restricted unpickler (:mod:`dancedata.io.safe_pickle`) plus exactly one shape of object
    array: the 0-d array ``np.save(path, {...})`` writes around a dict (Bailando's outputs),
    which yields the dict itself. Arrays inside the dict are built by the restricted path."""
    from dancedata.io import safe_pickle

    def dtype(*args: Any) -> Any:
        if args[:1] == ("O8",) and len(args) == 3:
            return _ObjectDtype()
        return safe_pickle._dtype_call(args)

    class DictUnpickler(safe_pickle.RestrictedUnpickler):
        def find_class(self, module: str, name: str) -> Any:
            if (module, name) == ("numpy", "dtype"):
                return dtype
            return super().find_class(module, name)

        def _array_from_state(self, state: Any) -> Any:
            body = state[1:] if isinstance(state, tuple) and len(state) == 5 else state
            if isinstance(body, tuple) and len(body) == 4 and isinstance(body[1], _ObjectDtype):
                shape, _, fortran, data = body
                if (
                    shape != ()
                    or fortran
                    or not (isinstance(data, list) and len(data) == 1 and isinstance(data[0], dict))
                ):
                    raise InputError("an object array other than np.save's 0-d dict")
                return data[0]
            return super()._array_from_state(state)

    return DictUnpickler


def _read_pickled_npy(path: Path, offset: int) -> dict[str, Any]:
    """The dict of a ``.npy`` written by ``np.save(path, dict)``, read by the restricted
    unpickler; InputError naming the layout and how to convert it for anything else."""
    import io

    from dancedata.io.safe_pickle import DEFAULT_LIMITS

    convert = (
        "a pickled .npy must be np.save of a dict of arrays (Bailando writes "
        "{'pred_position': (F, 72)}); else convert it where you trust it: "
        "np.savez(OUT, **np.load(IN, allow_pickle=True).item())"
    )
    size = path.stat().st_size
    if size > DEFAULT_LIMITS.max_file_bytes:
        raise InputError(f"a pickled .npy of {size} bytes; {convert}", path)
    with path.open("rb") as fh:
        fh.seek(offset)
        data = fh.read()
    try:
        value = _make_dict_unpickler()(io.BytesIO(data)).load()
    except Exception as exc:  # the unpickler's refusals and malformed data: one line
        reason = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
        raise InputError(f"unsafe or unreadable pickle ({reason}); {convert}", path) from None
    if not isinstance(value, dict):
        raise InputError(f"the pickle holds a {type(value).__name__}; {convert}", path)
    return value


def read_generated_arrays(path: Path, max_frames: int | None = None) -> dict[str, np.ndarray]:
    """The arrays of one generated-motion file by name (``array`` for a bare ``.npy``), every
    declared shape checked against ``max_frames`` first (module docstring); InputError naming
    the file otherwise."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            with path.open("rb") as fh:
                shape, dtype = _read_npy_header(fh, "header", path)
                offset = fh.tell()
            if dtype.hasobject:
                data = _read_pickled_npy(path, offset)
                return {str(k): np.asarray(v) for k, v in data.items()
                        if isinstance(v, np.ndarray)}  # fmt: skip
            _check_shape(shape, dtype, "the array", path, max_frames)
            # mmap checks the claimed shape against the file's size
            return {"array": np.array(np.load(path, mmap_mode="r", allow_pickle=False))}
        if suffix == ".npz":
            _check_npz_members(path, max_frames)
            with np.load(path, allow_pickle=False) as npz:
                return {k: np.asarray(npz[k]) for k in npz.files}
    except InputError:
        raise
    except Exception as exc:  # OSError, ValueError, EOFError, MemoryError, BadZipFile, ...
        reason = f"{type(exc).__name__}: {str(exc)[:200]}"
        raise InputError(f"cannot read as a numpy file ({reason})", path) from None
    if suffix == ".pkl":
        from dancedata.io.safe_pickle import load_restricted

        data = load_restricted(path)
        if isinstance(data, np.ndarray):
            data = {"array": data}
        if not isinstance(data, dict):
            raise InputError(
                f"a generated-motion pickle must hold a dict of arrays, not {type(data).__name__}",
                path,
            )
        arrays = {str(k): np.asarray(v) for k, v in data.items() if isinstance(v, np.ndarray)}
        for key, value in arrays.items():
            _check_shape(value.shape, value.dtype, key, path, max_frames)
        return arrays
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


def _rig_rotations(
    data: dict[str, np.ndarray], positions: np.ndarray | None, path: Path
) -> GeneratedMotion:
    """The ``rotations`` layout: ``axis_angle`` (F, J, 3) or ``quat`` (F, J, 4) + ``trans``."""
    key, width = ("axis_angle", 3) if "axis_angle" in data else ("quat", 4)
    rotations = _numbers(key, data[key], path)
    if rotations.ndim == 2 and rotations.shape[1] % width == 0:
        rotations = rotations.reshape(rotations.shape[0], -1, width)
    if rotations.ndim != 3 or rotations.shape[2] != width:
        raise InputError(f"{key} must be (frames, joints, {width}), got {rotations.shape}", path)
    if key == "quat" and np.any(np.linalg.norm(rotations, axis=-1) < 1e-8):
        raise InputError("quat holds a zero quaternion (no rotation)", path)
    trans = _numbers("trans", data["trans"], path)
    if trans.shape != (rotations.shape[0], 3):
        raise InputError(
            f"trans must be ({rotations.shape[0]}, 3) like {key}, got {trans.shape}", path
        )
    if key == "quat":
        return GeneratedMotion("rotations", str(path), quat=rotations, trans=trans,
                               positions=positions)  # fmt: skip
    return GeneratedMotion("rotations", str(path), axis_angle=rotations, trans=trans,
                           positions=positions)  # fmt: skip


def read_generated_motion(path: str | Path, max_frames: int | None = None) -> GeneratedMotion:
    """Read one file and recognise its layout (module docstring); InputError for anything
    else, naming the file and what was found. ``max_frames`` (see
    :func:`generated_frame_limit`) refuses a file declaring more frames, before loading it."""
    path = Path(path)
    data = read_generated_arrays(path, max_frames)
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
    if "trans" in data and ("axis_angle" in data or "quat" in data):
        return _rig_rotations(data, positions, path)
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
        "smpl_poses + smpl_trans, axis_angle or quat + trans, or (F, J, 3) joint positions",
        path,
    )
