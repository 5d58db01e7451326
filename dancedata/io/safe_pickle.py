"""Load numpy pickles without executing them and without letting them choose how memory is used.

AIST++ ships its annotations as pickles of dicts of numpy arrays. A plain ``pickle.load`` runs
whatever callable the file names. Restricting the callables (``find_class``) is not enough: once
``numpy.dtype`` and ``numpy.ndarray`` are admitted, the file also chooses their arguments and
their BUILD state, which numpy trusts. A 200-byte file can then

* set dtype flags so that bytes of the file are used as ``PyObject*`` pointers (SIGSEGV);
* call ``numpy.ndarray(shape, dtype)`` directly: uninitialised heap memory, any size (a
  352-byte file asked for 2.3 GB), or a zero-stride view of a 4-byte buffer as millions of rows;
* name memo index ``2**28`` (``LONG_BINPUT``): the C unpickler grows its memo table to 4 GB;
* nest 200,000 tuples: hashing them as a dict key overflows the C stack (SIGSEGV).

None of these is reachable from ``find_class``: the memo table, the nesting and numpy's state
handling happen inside the C unpickler and numpy. So this module does not subclass
``pickle.Unpickler`` at all: :class:`RestrictedUnpickler` is its own interpreter of pickle
opcodes (protocols 0-5; a loop, never recursion, with a dict memo). It builds plain containers
itself and builds numpy objects only through three narrow functions that check everything first:

* dtypes: the type string must be one of ``b1 i1 i2 i4 i8 u1 u2 u4 u8 f2 f4 f8`` (bool,
  integer, float: never object, string, void, structured, datetime or complex), and the BUILD
  state must be exactly what numpy writes for such a type: version 3, byte order ``< > = |``,
  no subarray, no names, no fields, elsize and alignment -1, flags 0;
* arrays (``_reconstruct`` + BUILD, protocol-5 ``_frombuffer``): the shape must be a tuple of
  at most :attr:`PickleLimits.max_ndim` non-negative ints, and the data bytes present in the
  file must be exactly ``prod(shape) * itemsize`` long; this is checked before anything is
  allocated, then the bytes are copied into a new C- (or Fortran-) contiguous array that owns
  them. ``numpy.ndarray`` itself is never called, so no uninitialised memory, no strides;
* scalars (``scalar(dtype, bytes)``): the bytes must be exactly one item.

Everything the file can make grow is bounded (:class:`PickleLimits`): the file size, the number
of opcodes, the memo index, the stack, the number of container items, the nesting depth
(containers inside containers, checked as tuples are built and again over the whole result,
which must also be free of cycles), the size of integers, and the bytes of all arrays together,
which may not exceed twice the file's own size (a memoised buffer cannot be reused to build
gigabytes). Dict keys and set items are limited to kinds whose hashes cannot be made to collide
(strings, bytes, small ints, tuples of strings), so no load can be made quadratic. Every
refusal is raised as :class:`UnsafePickleError` (``unsafe pickle: refused ...``) and every
malformed file as :class:`~dancedata.errors.InputError` (``unreadable pickle: ...``), one line
naming the file. Real AIST++ pickles load bit-identically to ``pickle.load``.

Subclasses may override :meth:`RestrictedUnpickler.find_class` to admit their own callables
(``dancedata.io.smpl_model`` admits stand-ins for scipy sparse matrices); those are trusted code
and are called with the file's arguments, so they must not trust them.
"""

from __future__ import annotations

import codecs
import io
import math
import pickle
import reprlib
import struct
import sys
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Literal

import numpy as np

from dancedata.errors import InputError

__all__ = [
    "DEFAULT_LIMITS",
    "PickleLimits",
    "RestrictedUnpickler",
    "UnsafePickleError",
    "load_restricted",
    "loads_restricted",
]


@dataclass(frozen=True)
class PickleLimits:
    """Bounds on what a pickle may make this process build.

    The defaults are far above what numpy pickles need (an AIST++ motion pickle nests 3 deep,
    memoises 40 objects and has 2 dims per array) and far below what would hurt.
    """

    max_file_bytes: int = 1 << 30  # 1 GiB: the largest AIST++ pickle is ~60 MB
    max_depth: int = 32  # containers inside containers
    max_memo_index: int = 1 << 20  # memo slots (index of PUT, BINPUT, LONG_BINPUT, MEMOIZE)
    max_stack: int = 1 << 18  # values on the stack above one MARK
    max_items: int = 1 << 24  # items put into containers, over the whole file
    max_int_bytes: int = 64  # LONG1 / LONG4 payload; text INT / LONG: 3x as many digits
    max_ndim: int = 32  # numpy allows 64
    max_dim: int = 1 << 40  # one array dimension
    max_opcodes: int = 1 << 21  # bounds the time: 2 M opcodes run in 2-10 s


DEFAULT_LIMITS = PickleLimits()

# The type strings numpy writes as the first argument of numpy.dtype for plain number types.
NUMERIC_TYPESTRS: frozenset[str] = frozenset(
    {"b1", "i1", "i2", "i4", "i8", "u1", "u2", "u4", "u8", "f2", "f4", "f8"}
)
_BYTE_ORDERS = frozenset("<>=|")


class UnsafePickleError(InputError):
    """The pickle asks for something outside what a numpy data pickle needs: a global off the
    allow-list, a dtype or array state numpy would not write, or more than the limits allow."""


class _Refused(pickle.UnpicklingError):
    """Raised inside the interpreter: refused on purpose (message starts with 'refused')."""


class _Malformed(pickle.UnpicklingError):
    """Raised inside the interpreter: the bytes are not a complete, well-formed pickle."""


_short = reprlib.Repr()
_short.maxlevel, _short.maxtuple, _short.maxlist, _short.maxdict = 2, 6, 6, 4
_short.maxstring, _short.maxother, _short.maxlong = 40, 40, 40


# -- the numpy callables a pickle may name -----------------------------------------------------
class _Global:
    """Stands for one allow-listed global; the interpreter decides what calling it does."""

    def __init__(self, role: str, qualname: str) -> None:
        self.role, self.qualname = role, qualname

    def __repr__(self) -> str:
        return self.qualname


def _globals_table() -> dict[tuple[str, str], _Global]:
    table: dict[tuple[str, str], _Global] = {}
    for core in ("numpy.core", "numpy._core"):
        table[(f"{core}.multiarray", "_reconstruct")] = _Global("reconstruct", "_reconstruct")
        table[(f"{core}.multiarray", "scalar")] = _Global("scalar", "numpy scalar")
        table[(f"{core}.numeric", "_frombuffer")] = _Global("frombuffer", "_frombuffer")
    table[("numpy", "ndarray")] = _Global("ndarray", "numpy.ndarray")
    table[("numpy", "dtype")] = _Global("dtype", "numpy.dtype")
    table[("collections", "OrderedDict")] = _Global("ordered_dict", "collections.OrderedDict")
    # Protocol-2 pickles made by Python 3 encode bytes as _codecs.encode(str, 'latin1').
    table[("_codecs", "encode")] = _Global("codecs_encode", "_codecs.encode")
    # ... and empty bytes (an empty array's data) as bytes().
    for builtins in ("builtins", "__builtin__"):
        table[(builtins, "bytes")] = _Global("bytes", "bytes")
    return table


_GLOBALS = _globals_table()


class _PendingArray:
    """``_reconstruct(ndarray, (0,), b"b")`` before its BUILD gives the real state."""

    result: np.ndarray | None = None


class _PendingDtype:
    """``numpy.dtype(typestr, align, copy)`` before its BUILD gives the byte order."""

    def __init__(self, typestr: str) -> None:
        self.typestr = typestr
        self.result: np.dtype | None = None


_LEAF_TYPES = (
    type(None),
    bool,
    int,
    float,
    str,
    bytes,
    bytearray,
    np.ndarray,
    np.generic,
    np.dtype,
)
_MUTABLE = (list, dict, set)


def _is_int(value: object, expected: int) -> bool:
    """``value == expected`` for a plain int or bool only (an array would compare elementwise)."""
    return type(value) in (int, bool) and value == expected


def _is_flag(value: object) -> bool:
    return _is_int(value, 0) or _is_int(value, 1)


_HASH_MODULUS = sys.hash_info.modulus  # ints below it hash to themselves: no collisions
_KEY_ATOMS = (str, bytes, bool, type(None))  # str and bytes hashes are randomised per process


def _check_keys(keys: list[Any]) -> None:
    """Dict keys and set items may be strings, bytes, None, bools, ints of magnitude below
    2**61 - 1, or tuples of strings, bytes, None and bools. Other hashes (large ints, floats,
    tuples of numbers) are deterministic, so a file could make a million keys collide and the
    load take hours."""
    for key in keys:
        kind = type(key)
        if kind in _KEY_ATOMS or (kind is int and -_HASH_MODULUS < key < _HASH_MODULUS):
            continue
        if kind is tuple and all(type(item) in _KEY_ATOMS for item in key):
            continue
        raise _refuse(
            f"a {kind.__name__} as a dict key or set item: only strings, bytes, small ints "
            "and tuples of strings (other hashes can be made to collide and stall the load)"
        )


def _refuse(message: str) -> _Refused:
    return _Refused("refused " + message)


def _check_dtype(dtype: np.dtype) -> np.dtype:
    """``dtype`` if it is a plain bool/int/float dtype (a last check on what was built)."""
    if (
        dtype.kind not in "biuf"
        or dtype.hasobject
        or dtype.fields is not None
        or dtype.subdtype is not None
        or dtype.metadata is not None
        or dtype.flags != 0
        or dtype.itemsize not in (1, 2, 4, 8)
    ):
        raise _refuse(f"dtype {dtype!r}: only plain bool, integer and float dtypes are loaded")
    return dtype


def _dtype_call(args: tuple) -> _PendingDtype:
    if len(args) != 3 or not isinstance(args[0], str):
        raise _refuse(f"numpy.dtype{_short.repr(args)}: numpy writes (typestr, align, copy)")
    typestr, align, copy = args
    if typestr not in NUMERIC_TYPESTRS:
        raise _refuse(
            f"dtype {typestr!r}: only bool, integer and float arrays are loaded "
            f"({' '.join(sorted(NUMERIC_TYPESTRS))})"
        )
    if not (_is_flag(align) and _is_flag(copy)):
        raise _refuse(f"numpy.dtype{_short.repr(args)}: align and copy must be booleans")
    return _PendingDtype(typestr)


def _dtype_from_state(typestr: str, state: object) -> np.dtype:
    """The dtype ``typestr`` with the byte order of its BUILD ``state``, which must be the
    state numpy writes for a plain number type and nothing else (flags, fields, subarrays and
    sizes in the state are how a file makes numpy misread memory)."""
    itemsize = int(typestr[1:])
    expected = "(3, '<' or '>', None, None, None, -1, -1, 0)"
    if not (isinstance(state, tuple) and len(state) == 8):
        raise _refuse(f"dtype state {_short.repr(state)} for {typestr!r}: expected {expected}")
    version, order, subarray, names, fields, elsize, alignment, flags = state
    plain = (
        type(version) is int
        and version == 3
        and isinstance(order, str)
        and order in _BYTE_ORDERS
        and (order != "|" or itemsize == 1)
        and subarray is None
        and names is None
        and fields is None
        and type(elsize) is int
        and elsize in (-1, itemsize)
        and type(alignment) is int
        and alignment in (-1, itemsize)
        and type(flags) is int
        and flags == 0
    )
    if not plain:
        raise _refuse(f"dtype state {_short.repr(state)} for {typestr!r}: expected {expected}")
    dtype = np.dtype(typestr)
    if itemsize > 1 and order in "<>":
        dtype = dtype.newbyteorder(order)
    return _check_dtype(dtype)


def _as_dtype(value: object) -> np.dtype:
    if isinstance(value, _PendingDtype):
        return value.result if value.result is not None else np.dtype(value.typestr)
    if isinstance(value, np.dtype):
        return _check_dtype(value)
    raise _refuse(f"{type(value).__name__} where a numpy dtype belongs")


def _as_buffer(value: object, what: str) -> bytes | bytearray:
    if isinstance(value, (bytes, bytearray)):
        return value
    if isinstance(value, str):  # Python 2 pickles read with encoding="latin1"
        try:
            return value.encode("latin1")
        except UnicodeEncodeError:
            raise _Malformed(f"{what} is text that is not latin-1 bytes") from None
    raise _refuse(f"{what} given as {type(value).__name__}: only bytes are loaded")


# -- the interpreter ---------------------------------------------------------------------------
class RestrictedUnpickler:
    """An interpreter of pickle opcodes that builds only containers, numbers, strings, bytes and
    checked numpy arrays, dtypes and scalars (see the module docstring for why and what).

    The interface follows :class:`pickle.Unpickler`: ``RestrictedUnpickler(file, encoding=...)
    .load()``; subclasses may override :meth:`find_class`. Raises ``pickle.UnpicklingError``
    (refusals start with "refused") or the exception of a malformed value (``ValueError`` ...);
    :func:`loads_restricted` turns them all into one-line InputErrors.
    """

    def __init__(
        self,
        file: BinaryIO,
        *,
        fix_imports: bool = True,
        encoding: str = "ASCII",
        errors: str = "strict",
        buffers: object = None,
        limits: PickleLimits = DEFAULT_LIMITS,
    ) -> None:
        if buffers is not None:
            raise _refuse("out-of-band buffers")
        self._file = file
        self.encoding, self.errors, self.limits = encoding, errors, limits

    # -- what a subclass may change --
    def find_class(self, module: str, name: str) -> Any:
        """The stand-in for global ``module.name``; anything off the allow-list is refused."""
        found = _GLOBALS.get((module, name))
        if found is None:
            raise _refuse(
                f"to load global {module}.{name}: only numpy arrays, scalars and plain "
                "containers are allowed"
            )
        return found

    # -- driver --
    def load(self) -> Any:
        data = self._file.read(self.limits.max_file_bytes + 1)
        if len(data) > self.limits.max_file_bytes:
            raise _refuse(f"a pickle larger than {self.limits.max_file_bytes} bytes")
        if not data:
            raise _Malformed("the file is empty")
        self._raw = data
        self._data = memoryview(data)
        self._pos = 0
        self._stack: list[Any] = []
        self._metastack: list[list[Any]] = []
        self._memo: dict[int, Any] = {}
        self._depths: dict[int, int] = {}  # id -> nesting depth of containers built here
        self._keep: list[Any] = []  # keeps those containers alive so their ids stay unique
        self._trusted: dict[int, Any] = {}  # callables a subclass's find_class returned
        self._trusted_objects: dict[int, Any] = {}  # what they made (BUILD may set their state)
        self._items = 0
        # Bytes all arrays, scalars and encoded strings may take together: an array's bytes are
        # in the file once, and built at most twice (protocols 0-2: latin-1 text, then array).
        self._budget = 2 * len(data)
        self._proto = 0
        dispatch = _DISPATCH
        data_len = len(data)
        budget = self.limits.max_opcodes
        while self._pos < data_len:
            budget -= 1
            if budget < 0:
                raise _refuse(f"a pickle of more than {self.limits.max_opcodes} opcodes")
            opcode = data[self._pos]
            self._pos += 1
            handler = dispatch.get(opcode)
            if handler is None:
                raise _Malformed(f"unknown opcode 0x{opcode:02x} at offset {self._pos - 1}")
            if handler is _STOP:
                return self._finish()
            handler(self)
        raise _Malformed("truncated: the pickle ends without its STOP opcode")

    def _finish(self) -> Any:
        if not self._stack:
            raise _Malformed("STOP with an empty stack")
        result = self._value(self._stack.pop())
        self._check_result(result)
        return result

    # -- reading the byte stream --
    def _take(self, n: int, what: str) -> memoryview:
        end = self._pos + n
        if n < 0 or end > len(self._data):
            left = len(self._data) - self._pos
            raise _Malformed(
                f"truncated: {what} needs {n} bytes at offset {self._pos}, {left} remain"
            )
        chunk = self._data[self._pos : end]
        self._pos = end
        return chunk

    def _uint(self, size: int, what: str) -> int:
        return int.from_bytes(self._take(size, what), "little")

    def _line(self, what: str) -> bytes:
        end = self._raw.find(b"\n", self._pos)
        if end < 0:
            raise _Malformed(f"truncated: {what} without its end of line")
        line = bytes(self._data[self._pos : end])
        self._pos = end + 1
        return line

    # -- the stack --
    def _push(self, value: Any) -> None:
        stack = self._stack
        if len(stack) >= self.limits.max_stack:
            raise _refuse(f"more than {self.limits.max_stack} values on the stack")
        stack.append(value)

    def _pop(self) -> Any:
        if not self._stack:
            raise _Malformed("a value is popped from an empty stack")
        return self._stack.pop()

    def _top(self) -> Any:
        if not self._stack:
            raise _Malformed("the stack is empty")
        return self._stack[-1]

    def _pop_mark(self) -> list[Any]:
        if not self._metastack:
            raise _Malformed("no MARK to pop to")
        items = self._stack
        self._stack = self._metastack.pop()
        return items

    def _value(self, value: Any) -> Any:
        """``value`` as it may be stored in a container or passed as an argument: a pending
        numpy object must have had its BUILD."""
        if isinstance(value, _PendingArray):
            if value.result is None:
                raise _refuse("an array used before its state is given")
            return value.result
        if isinstance(value, _PendingDtype):
            return _as_dtype(value)
        return value

    # -- containers: items and nesting bounded --
    def _count(self, n: int) -> None:
        self._items += n
        if self._items > self.limits.max_items:
            raise _refuse(f"more than {self.limits.max_items} container items")

    def _depth_of(self, value: Any) -> int:
        return self._depths.get(id(value), 0)

    def _record(self, container: Any, depth: int) -> Any:
        if depth > self.limits.max_depth:
            raise _refuse(f"containers nested more than {self.limits.max_depth} deep")
        if id(container) not in self._depths:
            self._keep.append(container)
        self._depths[id(container)] = depth
        return container

    def _new_container(self, container: Any, items: list[Any]) -> Any:
        depth = 1 + max(map(self._depth_of, items), default=0)
        return self._record(container, depth)

    def _grow(self, container: Any, items: list[Any]) -> None:
        depth = max(self._depth_of(container), 1 + max(map(self._depth_of, items), default=0))
        self._record(container, depth)

    def _items_of(self, values: list[Any]) -> list[Any]:
        self._count(len(values))
        return [self._value(v) for v in values]

    def _tuple(self, values: list[Any]) -> None:
        items = self._items_of(values)
        self._push(self._new_container(tuple(items), items))

    def _mutable_target(self, kind: type, opcode: str) -> Any:
        target = self._top()
        if type(target) is not kind and not (kind is dict and type(target) is OrderedDict):
            raise _Malformed(f"{opcode} on a {type(target).__name__}")
        return target

    def _set_items(self, values: list[Any]) -> None:
        if len(values) % 2:
            raise _Malformed("SETITEMS with an odd number of values")
        items = self._items_of(values)
        target = self._mutable_target(dict, "SETITEMS")
        _check_keys(items[0::2])
        for k in range(0, len(items), 2):
            target[items[k]] = items[k + 1]
        self._grow(target, items)

    # -- memo --
    def _memo_index(self, index: int) -> int:
        if not 0 <= index < self.limits.max_memo_index:
            raise _refuse(
                f"memo index {index} (at most {self.limits.max_memo_index} slots are allowed)"
            )
        return index

    def _put(self, index: int) -> None:
        self._memo[self._memo_index(index)] = self._top()

    def _get(self, index: int) -> None:
        try:
            value = self._memo[index]
        except KeyError:
            raise _Malformed(f"memo slot {index} is read before it is written") from None
        if isinstance(value, (_PendingArray, _PendingDtype)) and value.result is not None:
            value = value.result
        self._push(value)

    # -- calls --
    def _global(self, module: Any, name: Any) -> None:
        if not (isinstance(module, str) and isinstance(name, str)):
            raise _Malformed("a global named by something other than two strings")
        found = self.find_class(module, name)
        if not isinstance(found, _Global):
            self._trusted[id(found)] = found  # the subclass vouches for it
        self._push(found)

    def _spend(self, n: int, what: str) -> None:
        self._budget -= n
        if self._budget < 0:
            raise _refuse(
                f"{what}: the pickle builds more array bytes than twice the "
                f"{len(self._data)} bytes it holds"
            )

    def _call(self, func: Any, args: Any) -> Any:
        if not isinstance(args, tuple):
            raise _Malformed(f"call arguments are a {type(args).__name__}, not a tuple")
        if isinstance(func, _Global):
            return self._call_global(func, args)
        if id(func) in self._trusted and callable(func):
            made = func(*args)
            self._trusted_objects[id(made)] = made
            return made
        raise _refuse(f"to call a {type(func).__name__}: only allow-listed globals are called")

    def _call_global(self, func: _Global, args: tuple) -> Any:
        role = func.role
        if role == "reconstruct":
            return self._reconstruct(args)
        if role == "dtype":
            return _dtype_call(args)
        if role == "frombuffer":
            if len(args) != 4:
                raise _refuse(f"_frombuffer with {len(args)} arguments: numpy writes 4")
            buffer, dtype, shape, order = args
            if not (isinstance(order, str) and order in ("C", "F")):
                raise _refuse(f"_frombuffer order {_short.repr(order)}")
            return self._array(shape, _as_dtype(dtype), order == "F", buffer)
        if role == "scalar":
            return self._scalar(args)
        if role == "codecs_encode":
            if not (
                len(args) == 2
                and isinstance(args[0], str)
                and isinstance(args[1], str)
                and args[1] in ("latin1", "latin-1")
            ):
                raise _refuse(f"_codecs.encode{_short.repr(args)}: only (str, 'latin1')")
            self._spend(len(args[0]), "_codecs.encode")
            return args[0].encode("latin1")
        if role == "bytes":
            if args:
                raise _refuse("bytes(...) with arguments: pickles only write bytes()")
            return b""
        if role == "ordered_dict":
            if args:
                raise _refuse("collections.OrderedDict with arguments")
            return self._record(OrderedDict(), 1)
        if role == "ndarray":
            raise _refuse(
                "a direct numpy.ndarray(...) call: it returns uninitialised memory or a view "
                "with any strides; numpy pickles never make it"
            )
        raise _refuse(f"to call {func.qualname}")  # pragma: no cover - every role is above

    def _reconstruct(self, args: tuple) -> _PendingArray:
        """numpy pickles every array as ``_reconstruct(ndarray, (0,), b"b")`` followed by its
        real state; anything else (a subclass, a real shape) is refused unbuilt."""
        if len(args) != 3:
            raise _refuse(f"numpy _reconstruct with {len(args)} arguments")
        subtype, shape, typecode = args
        if not (isinstance(subtype, _Global) and subtype.role == "ndarray"):
            raise _refuse(f"numpy _reconstruct of {_short.repr(subtype)}: only numpy.ndarray")
        plain_shape = (
            shape == 0
            if type(shape) is int
            else (type(shape) in (tuple, list) and len(shape) == 1 and _is_int(shape[0], 0))
        )
        if not plain_shape or not (isinstance(typecode, (bytes, str)) and typecode in (b"b", "b")):
            raise _refuse(
                f"numpy _reconstruct with shape {_short.repr(shape)}: numpy itself only ever "
                "pickles (0,) there"
            )
        return _PendingArray()

    def _array(self, shape: Any, dtype: np.dtype, fortran: bool, data: Any) -> np.ndarray:
        """A new array of ``shape`` and ``dtype`` holding a copy of ``data``, whose length must
        be exactly what the shape needs (checked before anything is allocated)."""
        limits = self.limits
        if not isinstance(shape, tuple) or len(shape) > limits.max_ndim:
            raise _refuse(
                f"array shape {_short.repr(shape)}: a tuple of at most {limits.max_ndim} dimensions"
            )
        if not all(type(n) is int and 0 <= n <= limits.max_dim for n in shape):
            raise _refuse(
                f"array shape {_short.repr(shape)}: dimensions are ints in [0, {limits.max_dim}]"
            )
        buffer = _as_buffer(data, "array data")
        count = math.prod(shape)
        needed = count * dtype.itemsize
        if len(buffer) != needed:
            raise _refuse(
                f"array {shape} {dtype}: its shape needs {needed} bytes, the pickle gives "
                f"{len(buffer)} bytes"
            )
        self._spend(needed, f"array {shape} {dtype}")
        order: Literal["C", "F"] = "F" if fortran else "C"
        if count == 0:
            return np.zeros(shape, dtype=dtype, order=order)
        flat = np.frombuffer(buffer, dtype=dtype, count=count)
        return flat.reshape(shape, order=order).copy(order=order)

    def _scalar(self, args: tuple) -> np.generic:
        if len(args) != 2:
            raise _refuse(f"numpy scalar with {len(args)} arguments")
        dtype = _as_dtype(args[0])
        buffer = _as_buffer(args[1], "scalar data")
        if len(buffer) != dtype.itemsize:
            raise _refuse(f"numpy scalar {dtype} of {len(buffer)} bytes")
        self._spend(len(buffer), "numpy scalar")
        return np.frombuffer(buffer, dtype=dtype, count=1)[0]

    def _build(self) -> None:
        state = self._value(self._pop())
        target = self._top()
        if isinstance(target, _PendingArray):
            if target.result is not None:
                raise _refuse("a second state for the same array")
            target.result = self._array_from_state(state)
            self._stack[-1] = target.result
        elif isinstance(target, _PendingDtype):
            if target.result is not None:
                raise _refuse("a second state for the same dtype")
            target.result = _dtype_from_state(target.typestr, state)
            self._stack[-1] = target.result
        elif id(target) in self._trusted_objects:
            self._set_trusted_state(target, state)
        else:
            raise _refuse(f"to set the state of a {type(target).__name__}")

    def _array_from_state(self, state: Any) -> np.ndarray:
        """numpy's array state: ``(1, shape, dtype, is_fortran, data)`` (or without the 1)."""
        if isinstance(state, tuple) and len(state) == 5 and _is_int(state[0], 1):
            state = state[1:]
        if not (isinstance(state, tuple) and len(state) == 4):
            raise _refuse(
                f"array state {_short.repr(state)}: numpy writes "
                "(1, shape, dtype, is_fortran, bytes)"
            )
        shape, dtype, fortran, data = state
        if not _is_flag(fortran):
            raise _refuse(f"array state with is_fortran={_short.repr(fortran)}")
        array = self._array(shape, _as_dtype(dtype), bool(fortran), data)
        if not array.dtype.isnative:  # numpy's own __setstate__ byte-swaps to native order
            array = array.astype(array.dtype.newbyteorder("="), order="K")
        return array

    @staticmethod
    def _set_trusted_state(target: Any, state: Any) -> None:
        """pickle's BUILD for an object a subclass's callable made."""
        setstate = getattr(target, "__setstate__", None)
        if setstate is not None:
            setstate(state)
            return
        slots = None
        if isinstance(state, tuple) and len(state) == 2:
            state, slots = state
        if state:
            target.__dict__.update(state)
        for key, value in (slots or {}).items():
            setattr(target, key, value)

    def _new_object(self, cls: Any, args: Any, kwargs: Any) -> None:
        if not (isinstance(cls, type) and id(cls) in self._trusted):
            raise _refuse(f"to create a {_short.repr(cls)}: only allow-listed classes")
        if not isinstance(args, tuple) or not isinstance(kwargs, dict):
            raise _Malformed("NEWOBJ arguments are not a tuple and a dict")
        made: object = cls.__new__(cls, *args, **kwargs)
        self._trusted_objects[id(made)] = made
        self._push(made)

    # -- the final check: bounded depth, no cycles, nothing unfinished --
    def _children(self, value: Any) -> list[Any] | None:
        kind = type(value)
        if kind in (tuple, list, set, frozenset):
            return list(value)
        if kind is dict or kind is OrderedDict:
            return [*value.keys(), *value.values()]
        if isinstance(value, _LEAF_TYPES):
            if isinstance(value, np.ndarray):
                _check_dtype(value.dtype)
            return None
        if id(value) in self._trusted_objects:
            return list(getattr(value, "__dict__", {}).values())
        what = value.qualname if isinstance(value, _Global) else type(value).__name__
        raise _refuse(f"a pickle whose content includes {what} itself")

    def _check_result(self, root: Any) -> None:
        """Walk the result without recursion: containers nest at most ``max_depth`` deep (the
        depth seen while building can be stale when a list is grown after being nested), the
        graph has no cycles, and it holds only loadable values."""
        limit = self.limits.max_depth
        depth: dict[int, int] = {}
        open_: set[int] = set()
        todo: list[tuple[Any, bool]] = [(root, False)]
        while todo:
            value, closing = todo.pop()
            key = id(value)
            if closing:
                done = self._children(value) or []
                here = 1 + max((depth.get(id(c), 0) for c in done), default=0)
                if here > limit:
                    raise _refuse(f"containers nested more than {limit} deep")
                depth[key] = here
                open_.discard(key)
                continue
            if key in depth:
                continue
            if key in open_:
                raise _refuse("a container that contains itself")
            children = self._children(value)
            if children is None:
                continue
            open_.add(key)  # open_ is the path from the root to here
            if len(open_) > limit:
                raise _refuse(f"containers nested more than {limit} deep")
            todo.append((value, True))
            todo.extend((c, False) for c in children if id(c) not in depth)


# -- opcode handlers ---------------------------------------------------------------------------
def _decode_text(u: RestrictedUnpickler, raw: bytes) -> str | bytes:
    """Protocol 0-2 8-bit strings, as pickle decodes them (``encoding="bytes"`` keeps bytes)."""
    if u.encoding == "bytes":
        return raw
    return raw.decode(u.encoding, u.errors)


def _text_int(u: RestrictedUnpickler, line: bytes, what: str) -> int:
    if len(line) > 3 * u.limits.max_int_bytes:
        raise _refuse(f"{what} of {len(line)} digits")
    try:
        return int(line[:-1] if line.endswith(b"L") else line, 0)
    except ValueError:
        raise _Malformed(f"{what} {_short.repr(line)} is not an integer") from None


def _op_int(u: RestrictedUnpickler) -> None:
    line = u._line("INT")
    if line == b"00":
        u._push(False)
    elif line == b"01":
        u._push(True)
    else:
        u._push(_text_int(u, line, "INT"))


def _op_long_text(u: RestrictedUnpickler) -> None:
    u._push(_text_int(u, u._line("LONG"), "LONG"))


def _op_long_bin(size: int) -> Any:
    def handler(u: RestrictedUnpickler) -> None:
        n = u._uint(size, "LONG length")
        if n > u.limits.max_int_bytes:
            raise _refuse(f"an integer of {n} bytes (at most {u.limits.max_int_bytes})")
        u._push(int.from_bytes(u._take(n, "LONG"), "little", signed=True))

    return handler


def _op_float(u: RestrictedUnpickler) -> None:
    line = u._line("FLOAT")
    try:
        u._push(float(line))
    except ValueError:
        raise _Malformed(f"FLOAT {_short.repr(line)} is not a number") from None


def _op_string(u: RestrictedUnpickler) -> None:
    line = u._line("STRING")
    if len(line) < 2 or line[0] != line[-1] or line[:1] not in (b'"', b"'"):
        raise _Malformed("STRING opcode argument must be quoted")
    u._push(_decode_text(u, codecs.escape_decode(line[1:-1])[0]))


def _op_sized(length_bytes: int, kind: str) -> Any:
    """Length-prefixed strings, bytes and bytearrays: the length is checked against the bytes
    that remain before anything is copied."""

    def handler(u: RestrictedUnpickler) -> None:
        n = u._uint(length_bytes, kind)
        raw = u._take(n, kind)
        if kind == "unicode":
            u._push(str(raw, "utf-8", "surrogatepass"))
        elif kind == "bytes":
            u._push(bytes(raw))
        elif kind == "bytearray":
            u._push(bytearray(raw))
        else:  # Python 2 str
            u._push(_decode_text(u, bytes(raw)))

    return handler


def _op_unicode_text(u: RestrictedUnpickler) -> None:
    u._push(u._line("UNICODE").decode("raw-unicode-escape"))


def _op_tuple_n(n: int) -> Any:
    def handler(u: RestrictedUnpickler) -> None:
        if len(u._stack) < n:
            raise _Malformed(f"TUPLE{n} with {len(u._stack)} values on the stack")
        values = u._stack[len(u._stack) - n :]
        del u._stack[len(u._stack) - n :]
        u._tuple(values)

    return handler


def _op_mark(u: RestrictedUnpickler) -> None:
    if len(u._metastack) >= u.limits.max_depth:
        raise _refuse(f"MARKs nested more than {u.limits.max_depth} deep")
    u._metastack.append(u._stack)
    u._stack = []


def _op_list(u: RestrictedUnpickler) -> None:
    items = u._items_of(u._pop_mark())
    u._push(u._new_container(items, items))


def _op_dict(u: RestrictedUnpickler) -> None:
    values = u._pop_mark()
    if len(values) % 2:
        raise _Malformed("DICT with an odd number of values")
    items = u._items_of(values)
    _check_keys(items[0::2])
    made = {items[k]: items[k + 1] for k in range(0, len(items), 2)}
    u._push(u._new_container(made, items))


def _op_append(u: RestrictedUnpickler) -> None:
    value = u._value(u._pop())
    u._count(1)
    target = u._mutable_target(list, "APPEND")
    target.append(value)
    u._grow(target, [value])


def _op_appends(u: RestrictedUnpickler) -> None:
    items = u._items_of(u._pop_mark())
    target = u._mutable_target(list, "APPENDS")
    target.extend(items)
    u._grow(target, items)


def _op_setitem(u: RestrictedUnpickler) -> None:
    value = u._pop()
    key = u._pop()
    u._set_items([key, value])


def _op_additems(u: RestrictedUnpickler) -> None:
    items = u._items_of(u._pop_mark())
    target = u._mutable_target(set, "ADDITEMS")
    _check_keys(items)
    target.update(items)
    u._grow(target, items)


def _op_frozenset(u: RestrictedUnpickler) -> None:
    items = u._items_of(u._pop_mark())
    _check_keys(items)
    u._push(u._new_container(frozenset(items), items))


def _op_get_text(u: RestrictedUnpickler) -> None:
    u._get(_text_int(u, u._line("GET"), "GET"))


def _op_put_text(u: RestrictedUnpickler) -> None:
    u._put(_text_int(u, u._line("PUT"), "PUT"))


def _op_memoize(u: RestrictedUnpickler) -> None:
    u._put(len(u._memo))


def _op_global_text(u: RestrictedUnpickler) -> None:
    module = u._line("GLOBAL").decode("utf-8", "replace")
    name = u._line("GLOBAL").decode("utf-8", "replace")
    u._global(module, name)


def _op_stack_global(u: RestrictedUnpickler) -> None:
    name = u._pop()
    module = u._pop()
    u._global(module, name)


def _op_reduce(u: RestrictedUnpickler) -> None:
    args = u._value(u._pop())
    func = u._pop()
    u._push(u._call(func, args))


def _op_newobj(u: RestrictedUnpickler) -> None:
    args = u._value(u._pop())
    cls = u._pop()
    u._new_object(cls, args, {})


def _op_newobj_ex(u: RestrictedUnpickler) -> None:
    kwargs = u._value(u._pop())
    args = u._value(u._pop())
    cls = u._pop()
    u._new_object(cls, args, kwargs)


def _op_inst(u: RestrictedUnpickler) -> None:
    module = u._line("INST").decode("utf-8", "replace")
    name = u._line("INST").decode("utf-8", "replace")
    u.find_class(module, name)  # refuses anything off the allow-list by name
    raise _refuse(f"INST of {module}.{name}: numpy pickles never use it")


def _op_refused(what: str) -> Any:
    def handler(u: RestrictedUnpickler) -> None:
        raise _refuse(what)

    return handler


def _op_proto(u: RestrictedUnpickler) -> None:
    proto = u._uint(1, "PROTO")
    if proto > pickle.HIGHEST_PROTOCOL:
        raise _Malformed(f"unsupported pickle protocol {proto}")
    u._proto = proto


def _op_frame(u: RestrictedUnpickler) -> None:
    size = u._uint(8, "FRAME")
    if size > len(u._data) - u._pos:
        raise _Malformed(
            f"truncated: a frame of {size} bytes at offset {u._pos}, {len(u._data) - u._pos} remain"
        )


def _op_pop(u: RestrictedUnpickler) -> None:
    if u._stack:
        u._stack.pop()
    else:
        u._pop_mark()


def _op_dup(u: RestrictedUnpickler) -> None:
    u._push(u._top())


def _push_const(value: Any) -> Any:
    return lambda u: u._push(value)


def _op_fixed(size: int, fmt: str, what: str) -> Any:
    unpack = struct.Struct(fmt).unpack

    def handler(u: RestrictedUnpickler) -> None:
        u._push(unpack(u._take(size, what))[0])

    return handler


def _op_memo_bin(size: int, put: bool) -> Any:
    def handler(u: RestrictedUnpickler) -> None:
        index = u._uint(size, "memo index")
        if put:
            u._put(index)
        else:
            u._get(index)

    return handler


_STOP = object()

_DISPATCH: dict[int, Any] = {
    ord(code): handler
    for code, handler in {
        "(": _op_mark,
        ".": _STOP,
        "0": _op_pop,
        "1": lambda u: u._pop_mark(),
        "2": _op_dup,
        "F": _op_float,
        "I": _op_int,
        "J": _op_fixed(4, "<i", "BININT"),
        "K": _op_fixed(1, "<B", "BININT1"),
        "L": _op_long_text,
        "M": _op_fixed(2, "<H", "BININT2"),
        "N": _push_const(None),
        "P": _op_refused("persistent id (PERSID)"),
        "Q": _op_refused("persistent id (BINPERSID)"),
        "R": _op_reduce,
        "S": _op_string,
        "T": _op_sized(4, "string"),
        "U": _op_sized(1, "string"),
        "V": _op_unicode_text,
        "X": _op_sized(4, "unicode"),
        "a": _op_append,
        "b": lambda u: u._build(),
        "c": _op_global_text,
        "d": _op_dict,
        "}": lambda u: u._push(u._record({}, 1)),
        "e": _op_appends,
        "g": _op_get_text,
        "h": _op_memo_bin(1, put=False),
        "i": _op_inst,
        "j": _op_memo_bin(4, put=False),
        "l": _op_list,
        "]": lambda u: u._push(u._record([], 1)),
        "o": _op_refused("OBJ: numpy pickles never use it"),
        "p": _op_put_text,
        "q": _op_memo_bin(1, put=True),
        "r": _op_memo_bin(4, put=True),
        "s": _op_setitem,
        "t": lambda u: u._tuple(u._pop_mark()),
        ")": lambda u: u._tuple([]),
        "u": lambda u: u._set_items(u._pop_mark()),
        "G": _op_fixed(8, ">d", "BINFLOAT"),
        "B": _op_sized(4, "bytes"),
        "C": _op_sized(1, "bytes"),
    }.items()
} | {
    0x80: _op_proto,
    0x81: _op_newobj,
    0x82: _op_refused("extension code (EXT1)"),
    0x83: _op_refused("extension code (EXT2)"),
    0x84: _op_refused("extension code (EXT4)"),
    0x85: _op_tuple_n(1),
    0x86: _op_tuple_n(2),
    0x87: _op_tuple_n(3),
    0x88: _push_const(True),
    0x89: _push_const(False),
    0x8A: _op_long_bin(1),
    0x8B: _op_long_bin(4),
    0x8C: _op_sized(1, "unicode"),
    0x8D: _op_sized(8, "unicode"),
    0x8E: _op_sized(8, "bytes"),
    0x8F: lambda u: u._push(u._record(set(), 1)),
    0x90: _op_additems,
    0x91: _op_frozenset,
    0x92: _op_newobj_ex,
    0x93: _op_stack_global,
    0x94: _op_memoize,
    0x95: _op_frame,
    0x96: _op_sized(8, "bytearray"),
    0x97: _op_refused("out-of-band buffer (NEXT_BUFFER)"),
    0x98: _op_refused("out-of-band buffer (READONLY_BUFFER)"),
}

# Kept for callers that subclass it by its old name (dancedata.io.smpl_model).
_RestrictedUnpickler = RestrictedUnpickler


# -- entry points ------------------------------------------------------------------------------
def _one_line(exc: BaseException) -> str:
    """The exception's message with its line breaks folded."""
    return " ".join(str(exc).split())


def loads_restricted(
    data: bytes, source: str | Path = "<bytes>", limits: PickleLimits = DEFAULT_LIMITS
) -> Any:
    """Unpickle ``data`` admitting only containers, numbers, strings, bytes and checked numpy
    arrays, dtypes and scalars.

    Raises :class:`UnsafePickleError` (``unsafe pickle: refused ...``) for anything outside
    that or over ``limits``, and :class:`InputError` (``unreadable pickle: ...``) for a
    truncated or malformed pickle; one line naming ``source`` either way.
    """
    try:
        return RestrictedUnpickler(io.BytesIO(data), limits=limits).load()
    except _Refused as exc:
        raise UnsafePickleError(f"unsafe pickle: {_one_line(exc)}", source) from None
    except _Malformed as exc:
        raise InputError(f"unreadable pickle: {_one_line(exc)}", source) from None
    except (MemoryError, OverflowError, RecursionError) as exc:
        raise InputError(
            f"unreadable pickle: it asks for more than can be built ({type(exc).__name__})", source
        ) from None
    except Exception as exc:  # UnicodeDecodeError, TypeError (unhashable key), ...: bad data
        raise InputError(
            f"unreadable pickle ({type(exc).__name__}: {_one_line(exc)[:200]})", source
        ) from None


def load_restricted(path: str | Path, limits: PickleLimits = DEFAULT_LIMITS) -> Any:
    """Read and unpickle a file with :func:`loads_restricted`; a file over
    ``limits.max_file_bytes`` is refused before it is read."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > limits.max_file_bytes:
            raise UnsafePickleError(
                f"unsafe pickle: refused a file of {size} bytes (at most "
                f"{limits.max_file_bytes} are read)",
                path,
            )
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    return loads_restricted(data, path, limits)
