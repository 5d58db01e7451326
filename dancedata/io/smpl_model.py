"""SMPL body model files: read the parts that give joint positions, and their rest joints.

No SMPL model ships with dancedata: the SMPL licence does not allow redistribution. Register at
https://smpl.is.tue.mpg.de and download a model (e.g. ``SMPL_NEUTRAL.pkl`` or an ``.npz``
export), then pass ``--smpl-model PATH`` or set ``$DANCEDATA_SMPL_MODEL``.

What is read: ``J_regressor`` (J, V), ``v_template`` (V, 3), ``kintree_table`` (2, J) and,
when present, ``shapedirs`` (V, 3, B). Joint positions follow SMPL without pose blend shapes
(they do not move joints): rest joints ``J = J_regressor @ (v_template + shapedirs @ betas)``,
then forward kinematics of the axis-angle pose about those joints, plus the translation
(:func:`dancedata.compute.smpl_joints.smpl_joint_positions`; this module only reads the file,
issue 15 item 3). AIST++ stores no betas, so betas default to zeros. Lengths are the model's
(metres).

File formats:

* ``.npz``: read with numpy (``allow_pickle=False``); arrays must be numeric.
* ``.pkl``: read by the restricted unpickler of :mod:`dancedata.io.safe_pickle`, which never runs
  code named in the file. Python 2 and 3 pickles of numpy arrays and of scipy sparse matrices
  (the official files store ``J_regressor`` as ``csc_matrix``) are accepted: sparse matrices are
  rebuilt as dense arrays from their stored index arrays without importing scipy's classes.
  Pickles holding chumpy objects (the original 2015 ``basicModel_*.pkl`` release) are refused
  with a message: convert them to ``.npz`` once where chumpy is installed.
"""

from __future__ import annotations

import _compat_pickle
import io
import os
import pickle
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.io.safe_pickle import _RestrictedUnpickler

__all__ = [
    "SMPL_MODEL_ENV",
    "SMPL_MODEL_HELP",
    "SmplModel",
    "cached_smpl_model",
    "load_smpl_model",
]

SMPL_MODEL_ENV = "DANCEDATA_SMPL_MODEL"
SMPL_MODEL_HELP = (
    "no SMPL model file given. dancedata cannot bundle one (the SMPL licence forbids "
    "redistribution): register at https://smpl.is.tue.mpg.de, download SMPL (e.g. "
    "SMPL_NEUTRAL.pkl, or an .npz export) and pass --smpl-model PATH or set "
    f"${SMPL_MODEL_ENV}"
)
_REQUIRED = ("J_regressor", "v_template", "kintree_table")


@dataclass(frozen=True, eq=False)
class SmplModel:
    """The joint-related parts of an SMPL model.

    Attributes:
        j_regressor: (J, V) float64 joint regressor (dense).
        v_template: (V, 3) float64 rest vertices, metres.
        shapedirs: (V, 3, B) float64 shape blend shapes, or None when the file has none.
        parents: (J,) parent of each joint, -1 for the root.
        path: the file read.
    """

    j_regressor: np.ndarray
    v_template: np.ndarray
    shapedirs: np.ndarray | None
    parents: tuple[int, ...]
    path: str

    @property
    def n_joints(self) -> int:
        return len(self.parents)

    def rest_joints(self, betas: np.ndarray | None = None) -> np.ndarray:
        """(J, 3) rest joint positions in metres for shape ``betas`` (zeros when None)."""
        vertices = self.v_template
        if betas is not None and np.any(betas):
            if self.shapedirs is None:
                raise InputError(
                    "the model has no shapedirs, so betas cannot be applied", self.path
                )
            betas = np.asarray(betas, dtype=np.float64).reshape(-1)
            n = min(len(betas), self.shapedirs.shape[2])
            vertices = vertices + self.shapedirs[:, :, :n] @ betas[:n]
        return self.j_regressor @ vertices

    def joint_offsets(self, betas: np.ndarray | None = None) -> np.ndarray:
        """(J, 3) offset of each joint from its parent at rest (the root's: its rest position)."""
        joints = self.rest_joints(betas)
        parents = np.asarray(self.parents)
        offsets = joints.copy()
        has_parent = parents >= 0
        offsets[has_parent] -= joints[parents[has_parent]]
        return offsets


# --------------------------------------------------------------------------------------------
# Loading


def load_smpl_model(path: str | Path) -> SmplModel:
    """Read an SMPL ``.npz`` or ``.pkl`` (see the module docstring). Raises InputError naming the
    file for anything unreadable, unsupported or incomplete."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"SMPL model file not found. {SMPL_MODEL_HELP}", path)
    if path.suffix.lower() == ".npz":
        data = _read_npz(path)
    elif path.suffix.lower() in (".pkl", ".pickle"):
        data = _read_pkl(path)
    else:
        raise InputError("SMPL model must be an .npz or .pkl file", path)
    return _model_from_dict(data, path)


@lru_cache(maxsize=4)
def _cached(path: str, mtime_ns: int, size: int) -> SmplModel:
    return load_smpl_model(path)


def cached_smpl_model(path: str | Path) -> SmplModel:
    """:func:`load_smpl_model`, cached per process while the file is unchanged."""
    try:
        stat = os.stat(path)
    except OSError:
        return load_smpl_model(path)  # raises the not-found message
    return _cached(str(path), stat.st_mtime_ns, stat.st_size)


def _read_npz(path: Path) -> dict[str, Any]:
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {key: npz[key] for key in npz.files if key in (*_REQUIRED, "shapedirs")}
    except ValueError as exc:
        if "allow_pickle" in str(exc):
            raise InputError(
                "the .npz holds Python objects (e.g. a pickled sparse matrix); only numeric "
                "arrays are read: save J_regressor as a dense array",
                path,
            ) from None
        raise InputError(f"unreadable .npz: {exc}", path) from None
    except (OSError, EOFError) as exc:
        raise InputError(f"unreadable .npz: {exc}", path) from None


# -- restricted pickle with scipy sparse matrices ----------------------------------------------


class _SparseState:
    """Stands in for a pickled scipy sparse matrix: keeps its state, runs nothing."""

    fmt = ""

    def __setstate__(self, state: Any) -> None:
        if isinstance(state, tuple) and len(state) == 2:  # (dict, slots)
            merged = dict(state[0] or {})
            merged.update(state[1] or {})
            state = merged
        self.state: dict[str, Any] = state if isinstance(state, dict) else {}

    def dense(self) -> np.ndarray:
        state = self.state
        shape = tuple(int(n) for n in state.get("_shape", state.get("shape", ())))
        if len(shape) != 2:
            raise ValueError(f"sparse {self.fmt} matrix without a 2-d shape")
        data = np.asarray(state["data"], dtype=np.float64)
        out = np.zeros(shape)
        if self.fmt == "coo":
            coords = state.get("coords") or (state["row"], state["col"])
            rows, cols = (np.asarray(c, dtype=np.int64) for c in coords)
        else:
            indices = np.asarray(state["indices"], dtype=np.int64)
            indptr = np.asarray(state["indptr"], dtype=np.int64)
            major = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
            rows, cols = (indices, major) if self.fmt == "csc" else (major, indices)
        np.add.at(out, (rows, cols), data)
        return out


class _Csc(_SparseState):
    fmt = "csc"


class _Csr(_SparseState):
    fmt = "csr"


class _Coo(_SparseState):
    fmt = "coo"


_SPARSE = {
    "csc_matrix": _Csc,
    "csc_array": _Csc,
    "csr_matrix": _Csr,
    "csr_array": _Csr,
    "coo_matrix": _Coo,
    "coo_array": _Coo,
}


def _reconstructor(cls: type, base: type, state: Any) -> Any:
    """``copyreg._reconstructor`` (protocol 0/1 pickles) for the stand-in classes only."""
    if not (isinstance(cls, type) and issubclass(cls, _SparseState)):
        raise pickle.UnpicklingError(f"refused to reconstruct {cls!r}")
    return cls.__new__(cls)


class _ChumpyFound(pickle.UnpicklingError):
    pass


class _SmplUnpickler(_RestrictedUnpickler):
    """The numpy-only unpickler, plus scipy sparse matrices rebuilt as stand-ins."""

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _compat_pickle.NAME_MAPPING:
            module, name = _compat_pickle.NAME_MAPPING[(module, name)]
        module = _compat_pickle.IMPORT_MAPPING.get(module, module)
        if module.split(".")[0] == "chumpy":
            raise _ChumpyFound(f"{module}.{name}")
        if module.startswith("scipy.sparse") and name in _SPARSE:
            return _SPARSE[name]
        if (module, name) == ("copyreg", "_reconstructor"):
            return _reconstructor
        if (module, name) == ("builtins", "object"):
            return object
        return super().find_class(module, name)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _read_pkl(path: Path) -> dict[str, Any]:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    try:
        data = _SmplUnpickler(io.BytesIO(raw), encoding="latin1").load()
    except _ChumpyFound as exc:
        raise InputError(
            f"this SMPL .pkl holds chumpy objects ({exc}), which dancedata does not load "
            "(chumpy is unmaintained and unpickling it runs its code). Convert it once where "
            "chumpy is installed: np.savez('smpl.npz', J_regressor=m['J_regressor'].toarray(), "
            "v_template=np.array(m['v_template']), shapedirs=np.array(m['shapedirs']), "
            "kintree_table=m['kintree_table']) (smplx's tools/clean_ch.py does the same), or use a "
            "chumpy-free SMPL file",
            path,
        ) from None
    except pickle.UnpicklingError as exc:
        raise InputError(f"unsupported content in SMPL pickle: {_one_line(exc)}", path) from None
    except Exception as exc:  # truncated or corrupt pickles raise many types
        problem = f"{type(exc).__name__}: {_one_line(exc)}"
        raise InputError(f"unreadable SMPL pickle ({problem})", path) from None
    if not isinstance(data, dict):
        raise InputError(f"SMPL pickle holds a {type(data).__name__}, not a dict", path)
    out = {}
    for key in (*_REQUIRED, "shapedirs"):
        if key not in data:
            continue
        value = data[key]
        try:
            out[key] = value.dense() if isinstance(value, _SparseState) else np.asarray(value)
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            raise InputError(f"SMPL pickle: cannot rebuild {key} ({exc})", path) from None
    return out


def _model_from_dict(data: dict[str, Any], path: Path) -> SmplModel:
    missing = [key for key in _REQUIRED if key not in data]
    if missing:
        raise InputError(f"not an SMPL model: missing {missing}", path)
    try:
        regressor = np.asarray(data["J_regressor"], dtype=np.float64)
        template = np.asarray(data["v_template"], dtype=np.float64)
        kintree = np.asarray(data["kintree_table"]).astype(np.int64)
        shapedirs = data.get("shapedirs")
        shapedirs = None if shapedirs is None else np.asarray(shapedirs, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"SMPL model arrays are not numeric ({exc})", path) from None
    if template.ndim != 2 or template.shape[1] != 3:
        raise InputError(f"v_template must be (V, 3), got {template.shape}", path)
    n_vertices = template.shape[0]
    if regressor.ndim != 2 or regressor.shape[1] != n_vertices:
        raise InputError(f"J_regressor must be (J, {n_vertices}), got {regressor.shape}", path)
    n_joints = regressor.shape[0]
    if kintree.ndim != 2 or kintree.shape != (2, n_joints):
        raise InputError(f"kintree_table must be (2, {n_joints}), got {kintree.shape}", path)
    if shapedirs is not None and (shapedirs.ndim != 3 or shapedirs.shape[:2] != (n_vertices, 3)):
        raise InputError(f"shapedirs must be (V, 3, B), got {shapedirs.shape}", path)
    parents = _parents_from_kintree(kintree, path)
    return SmplModel(regressor, template, shapedirs, parents, str(path))


def _parents_from_kintree(kintree: np.ndarray, path: Path) -> tuple[int, ...]:
    """kintree_table row 0 = parent of the joint in row 1; the root's parent is -1 or 2**32-1."""
    n = kintree.shape[1]
    ids = kintree[1]
    if sorted(ids.tolist()) != list(range(n)):
        raise InputError("kintree_table row 1 must list joints 0..J-1", path)
    parents = [-1] * n
    for parent, joint in zip(kintree[0].tolist(), ids.tolist(), strict=True):
        parents[joint] = -1 if (parent < 0 or parent >= n) else int(parent)
    if parents[0] != -1 or any(not 0 <= p < j for j, p in enumerate(parents) if j > 0):
        raise InputError("kintree_table: joint 0 must be the root and parents precede joints", path)
    return tuple(parents)
