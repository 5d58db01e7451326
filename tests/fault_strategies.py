"""Hypothesis strategies shared by the fault tests and the fuzz runner (fuzz/run.py).

* :func:`bvh_documents` draws a *valid* BVH file from a random rig: any tree shape, any subset
  and order of channels per joint (in any letter case), 0-2 End Sites anywhere, names with ``:``
  and ``.``, numbers written as ``1.``, ``+3``, ``.5``, ``1e-3`` ..., tabs, CRLF and the header
  spellings seen in the wild. It returns the text and what a correct reader must make of it.
* :func:`mutated_bvh` damages such a file (truncation, line deletion/duplication/swap, byte
  edits, glued numbers) so that the result may or may not still be valid.
* :func:`within` turns a hang into a failure (SIGALRM), for targets that must always return.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_NAME_CHARS = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_:.-"


class Hang(Exception):
    """A target ran past its time limit."""


@contextlib.contextmanager
def within(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` if the block runs longer than ``seconds`` (main thread, POSIX only;
    elsewhere the block just runs)."""
    if (
        not hasattr(signal, "setitimer")
        or threading.current_thread() is not threading.main_thread()
    ):
        yield
        return

    def _alarm(signum: int, frame: object) -> None:
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@dataclass(frozen=True)
class BvhDoc:
    """A generated BVH file and what reading it must give."""

    text: str
    names: tuple[str, ...]
    parents: tuple[int, ...]
    channels: tuple[tuple[str, ...], ...]
    offsets: np.ndarray  # (J, 3)
    end_sites: tuple[int, ...]  # End Site count per joint
    values: np.ndarray  # (F, C)
    frame_time: float


_finite = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False)


@st.composite
def number_text(draw: st.DrawFn) -> tuple[str, float]:
    """A number as BVH writers print it, and its value."""
    style = draw(st.sampled_from(["repr", "fixed", "sci", "int_dot", "plus_int", "dot_frac"]))
    if style in ("int_dot", "plus_int"):
        k = draw(st.integers(-9999, 9999))
        text = f"{k}." if style == "int_dot" else (f"+{k}" if k >= 0 else str(k))
        return text, float(k)
    if style == "dot_frac":
        digits = draw(st.integers(0, 99999))
        sign = draw(st.sampled_from(["", "-"]))
        text = f"{sign}.{digits:05d}"
        return text, float(text)
    x = draw(_finite)
    text = {"repr": repr(x), "fixed": f"{x:.6f}", "sci": f"{x:.5e}"}[style]
    return text, float(text)


@st.composite
def bvh_documents(draw: st.DrawFn, max_joints: int = 8, max_frames: int = 12) -> BvhDoc:
    """A valid BVH file from a random rig (see the module docstring)."""
    n = draw(st.integers(1, max_joints))
    parent_of = [-1] + [draw(st.integers(0, j - 1)) for j in range(1, n)]
    chans = [
        tuple(draw(st.lists(st.sampled_from(CHANNELS), unique=True, max_size=6))) for _ in range(n)
    ]
    if not any(chans):
        chans[0] = ("Zrotation", "Xrotation", "Yrotation")
    names = [f"{draw(st.text(_NAME_CHARS, min_size=1, max_size=8))}_{j}" for j in range(n)]
    ends = [draw(st.integers(0, 2)) for _ in range(n)]
    offsets = [[draw(number_text()) for _ in range(3)] for _ in range(n)]
    end_offsets = [[[draw(number_text()) for _ in range(3)] for _ in range(e)] for e in ends]
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    indent = draw(st.sampled_from(["  ", "\t", "    "]))
    sep = draw(st.sampled_from([" ", "\t", "  "]))

    def spell(channel: str) -> str:
        return draw(st.sampled_from([channel, channel.lower(), channel.upper()]))

    children = {j: [c for c in range(n) if parent_of[c] == j] for j in range(n)}
    order: list[int] = []  # file (depth-first) order
    lines: list[str] = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        pad = indent * depth
        keyword = "ROOT" if j == 0 else "JOINT"
        order.append(j)
        lines.append(f"{pad}{keyword} {names[j]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}{indent}OFFSET {sep.join(t for t, _ in offsets[j])}")
        if chans[j] or draw(st.booleans()):
            listed = " ".join(spell(c) for c in chans[j])
            lines.append(f"{pad}{indent}CHANNELS {len(chans[j])} {listed}".rstrip())
        for child in children[j]:
            emit(child, depth + 1)
        for end in end_offsets[j]:
            lines.append(f"{pad}{indent}End Site")
            lines.append(f"{pad}{indent}{{")
            lines.append(f"{pad}{indent}{indent}OFFSET {sep.join(t for t, _ in end)}")
            lines.append(f"{pad}{indent}}}")
        lines.append(f"{pad}}}")

    emit(0, 0)
    n_channels = sum(len(c) for c in chans)
    n_frames = draw(st.integers(0, max_frames))
    frame_time_text = draw(st.sampled_from(["0.0083333", "0.033333", ".04", "8.333333e-03"]))
    rows = [[draw(number_text()) for _ in range(n_channels)] for _ in range(n_frames)]
    lines.append("MOTION")
    lines.append(draw(st.sampled_from(["Frames: {}", "Frames:{}", "Frames:\t{}"])).format(n_frames))
    lines.append(draw(st.sampled_from(["Frame Time: {}", "Frame Time:{}"])).format(frame_time_text))
    # Motion columns follow the file (depth-first) joint order.
    starts = np.cumsum([0] + [len(c) for c in chans])
    for row in rows:
        lines.append(sep.join(row[starts[j] + k][0] for j in order for k in range(len(chans[j]))))
    text = eol.join(lines) + eol
    renumber = {old: new for new, old in enumerate(order)}
    values = np.array(
        [[row[starts[j] + k][1] for j in order for k in range(len(chans[j]))] for row in rows],
        dtype=np.float64,
    ).reshape(n_frames, n_channels)
    return BvhDoc(
        text=text,
        names=tuple(names[j] for j in order),
        parents=tuple(-1 if parent_of[j] < 0 else renumber[parent_of[j]] for j in order),
        channels=tuple(chans[j] for j in order),
        offsets=np.array([[v for _, v in offsets[j]] for j in order], dtype=np.float64),
        end_sites=tuple(ends[j] for j in order),
        values=values,
        frame_time=float(frame_time_text),
    )


@st.composite
def mutated_bvh(draw: st.DrawFn) -> bytes:
    """A generated valid BVH file, damaged 1-3 times (it may or may not stay valid)."""
    data = draw(bvh_documents()).text.encode()
    for _ in range(draw(st.integers(1, 3))):
        lines = data.split(b"\n")
        kind = draw(
            st.sampled_from(
                ["truncate", "del_line", "dup_line", "swap_lines", "byte", "glue", "insert"]
            )
        )
        if kind == "truncate":
            data = data[: draw(st.integers(0, len(data)))]
        elif kind in ("del_line", "dup_line") and lines:
            k = draw(st.integers(0, len(lines) - 1))
            lines[k : k + 1] = [] if kind == "del_line" else [lines[k], lines[k]]
            data = b"\n".join(lines)
        elif kind == "swap_lines" and len(lines) > 1:
            a, b = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[a], lines[b] = lines[b], lines[a]
            data = b"\n".join(lines)
        elif kind == "byte" and data:
            pos = draw(st.integers(0, len(data) - 1))
            data = data[:pos] + bytes([draw(st.integers(0, 255))]) + data[pos + 1 :]
        elif kind == "glue":
            data = data.replace(b" -", b"-", 1).replace(b"\t-", b"-", 1)
        else:
            pos = draw(st.integers(0, len(data)))
            piece = draw(st.sampled_from([b"{", b"}", b"\n", b" 1", b"nan", b"JOINT x\n", b"\x00"]))
            data = data[:pos] + piece + data[pos:]
    return data
