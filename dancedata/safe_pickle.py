"""Load pickles without executing them.

AIST++ ships its annotations as pickles. A plain ``pickle.load`` runs whatever callable the file
names, so a downloaded pickle could run code. This unpickler resolves only the globals numpy needs
to rebuild arrays, dtypes and scalars; any other global is refused before it is called.
"""

from __future__ import annotations

import io
import pickle
from pathlib import Path
from typing import Any

from dancedata.errors import InputError

# (module, name) pairs that rebuild numpy arrays, dtypes and scalars, across numpy 1.x and 2.x.
_ALLOWED_GLOBALS: frozenset[tuple[str, str]] = frozenset(
    {
        ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
        ("numpy.core.numeric", "_frombuffer"),
        ("numpy._core.numeric", "_frombuffer"),
        ("numpy", "ndarray"),
        ("numpy", "dtype"),
        ("collections", "OrderedDict"),
        # Protocol-2 pickles of numpy arrays encode raw bytes through _codecs.encode(str, 'latin1').
        ("_codecs", "encode"),
    }
)
_NUMPY_DTYPE_CLASSES_MODULES = ("numpy.dtypes",)


class UnsafePickleError(InputError):
    """The pickle names a global outside the numpy-only allow-list."""


class _RestrictedUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _ALLOWED_GLOBALS or (
            module in _NUMPY_DTYPE_CLASSES_MODULES and name.endswith("DType")
        ):
            return super().find_class(module, name)
        raise pickle.UnpicklingError(
            f"refused to load global {module}.{name}: only numpy arrays, scalars and plain "
            "containers are allowed"
        )


def loads_restricted(data: bytes, source: str | Path = "<bytes>") -> Any:
    """Unpickle ``data`` admitting only numpy arrays, numpy scalars and plain containers.

    Raises :class:`UnsafePickleError` for a disallowed global and :class:`InputError` for a
    truncated or otherwise unreadable pickle; nothing named in the pickle is ever called unless
    it is on the allow-list.
    """
    try:
        return _RestrictedUnpickler(io.BytesIO(data)).load()
    except pickle.UnpicklingError as exc:
        if "refused to load global" in str(exc):
            raise UnsafePickleError(f"unsafe pickle: {exc}", source) from None
        raise InputError(f"unreadable pickle: {exc}", source) from None
    except (EOFError, ValueError, TypeError, AttributeError, IndexError, KeyError) as exc:
        raise InputError(f"unreadable pickle ({type(exc).__name__}: {exc})", source) from None


def load_restricted(path: str | Path) -> Any:
    """Read and unpickle a file with :func:`loads_restricted`."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    return loads_restricted(data, path)
