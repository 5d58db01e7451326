"""The character set of a sequence id, checked at ingest and whenever a store is read.

A ``seq_id`` names files (``evaluate --generated DIR`` reads ``DIR/<seq_id>.npy``, exports write
``<seq_id>.bvh``), so it must never be able to act as a path or a pattern. The rule:

* 1 to :data:`MAX_SEQ_ID_BYTES` bytes of UTF-8 (so ``<seq_id>.npz`` fits a 255-byte file name);
* letters and digits of any script, ``_``, and the punctuation `` -.+,()@=#&~`` (space
  included), which AIST++ names (``gBR_sBM_cAll_d04_mBR0_ch01``), BVH take names
  (``Take 001 (2)``, ``dance-03.v2``) and video stems use;
* the first character a letter, digit or ``_`` (no leading dot, dash or space).

Refused, among others: ``/`` and ``\\``, ``..``, glob characters ``* ? [ ] { }``, ``$`` and
``%`` (mathtext, environment variables), quotes, ``< > | : ;``, control characters and
non-UTF-8 bytes.
"""

from __future__ import annotations

import re

from dancedata.errors import InputError

MAX_SEQ_ID_BYTES = 200
_ALLOWED = re.compile(r"[^\W][\w \-.+,()@=#&~]*")
SEQ_ID_RULE = (
    "1-200 bytes: letters, digits, _ and -.+,()@=#&~ or space, starting with a letter, digit or _"
)


def seq_id_problem(seq_id: object) -> str | None:
    """Why ``seq_id`` is not a valid sequence id (module docstring), or None when it is."""
    if not isinstance(seq_id, str):
        return f"seq_id {seq_id!r} is not a string"
    shown = repr(seq_id[:80])
    try:
        size = len(seq_id.encode("utf-8"))
    except UnicodeEncodeError:
        return f"seq_id {shown} is not valid UTF-8"
    if size == 0 or size > MAX_SEQ_ID_BYTES:
        return f"seq_id {shown} is {size} bytes ({SEQ_ID_RULE})"
    if _ALLOWED.fullmatch(seq_id) is None:
        return f"seq_id {shown} is not a plain name ({SEQ_ID_RULE})"
    return None


def check_seq_id(seq_id: object, path: object = None) -> str:
    """``seq_id`` itself when valid; InputError naming ``path`` otherwise."""
    problem = seq_id_problem(seq_id)
    if problem is not None:
        raise InputError(problem, path)  # type: ignore[arg-type]
    return seq_id  # type: ignore[return-value]
