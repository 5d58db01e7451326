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


_RECONSTRUCT = "_reconstruct"


def _guarded_reconstruct(original: Any) -> Any:
    """numpy pickles every array as ``_reconstruct(ndarray, (0,), b"b")`` followed by its real
    state; a pickle asking ``_reconstruct`` for a larger shape is trying to make us allocate
    (terabytes, say) and is refused before anything is allocated."""

    def reconstruct(subtype: Any, shape: Any, dtype: Any) -> Any:
        dims = shape if isinstance(shape, tuple) else (shape,)
        if not all(isinstance(d, int) and 0 <= d <= 1 for d in dims):
            raise pickle.UnpicklingError(
                f"refused numpy _reconstruct with shape {shape!r}: numpy itself only ever "
                "pickles (0,) there"
            )
        return original(subtype, shape, dtype)

    return reconstruct


class _RestrictedUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _ALLOWED_GLOBALS or (
            module in _NUMPY_DTYPE_CLASSES_MODULES and name.endswith("DType")
        ):
            found = super().find_class(module, name)
            return _guarded_reconstruct(found) if name == _RECONSTRUCT else found
        raise pickle.UnpicklingError(
            f"refused to load global {module}.{name}: only numpy arrays, scalars and plain "
            "containers are allowed"
        )


def _one_line(exc: BaseException) -> str:
    """The exception's message with its line breaks folded (pickle has multi-line messages)."""
    return " ".join(str(exc).split())


def loads_restricted(data: bytes, source: str | Path = "<bytes>") -> Any:
    """Unpickle ``data`` admitting only numpy arrays, numpy scalars and plain containers.

    Raises :class:`UnsafePickleError` for a disallowed global and :class:`InputError` for a
    truncated or otherwise unreadable pickle; nothing named in the pickle is ever called unless
    it is on the allow-list.
    """
    try:
        return _RestrictedUnpickler(io.BytesIO(data)).load()
    except pickle.UnpicklingError as exc:
        if str(exc).startswith("refused "):
            raise UnsafePickleError(f"unsafe pickle: {_one_line(exc)}", source) from None
        raise InputError(f"unreadable pickle: {_one_line(exc)}", source) from None
    except (MemoryError, OverflowError, RecursionError) as exc:
        raise InputError(
            f"unreadable pickle: it asks for more than can be built ({type(exc).__name__})", source
        ) from None
    except Exception as exc:  # EOFError, ValueError, LookupError (a codec name), ...: bad data
        raise InputError(
            f"unreadable pickle ({type(exc).__name__}: {_one_line(exc)})", source
        ) from None


def load_restricted(path: str | Path) -> Any:
    """Read and unpickle a file with :func:`loads_restricted`."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    return loads_restricted(data, path)
