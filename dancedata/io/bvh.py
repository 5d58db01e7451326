"""BVH motion capture: data model, reader and writer.

The reader is built for files found in the wild (see docs/FORMATS.md, "BVH edge cases"):

* the HIERARCHY is read by a small tokenizer with line numbers, iteratively (no recursion limit);
  every joint keeps its own channel list and order, a joint may carry 0-6 channels, any number of
  End Sites, and names such as ``mixamorig:Hips`` or ``Bip01.L``;
* the head (hierarchy, ``Frames:``, ``Frame Time:``) is scanned straight from the bytes of a
  growing prefix of the file, within documented limits (joints, End Sites, depth, name and line
  lengths, 64 MiB of head, Frame Time 1e-4 to 10 s; see :mod:`dancedata.io.bvh_head`), so a
  hostile file (200 MB on one line, a hierarchy 10,000 deep) fails at once with one line and
  bounded memory;
* the MOTION block is parsed by pyarrow's multi-threaded CSV reader after whitespace
  normalisation (tabs, CRLF, repeated blanks). Anything that path does not accept cleanly is
  re-read by a strict line-by-line parser, which either accepts the file or raises
  :class:`~dancedata.errors.InputError` naming the line: wrong channel count, glued numbers
  (``0.0-7.5``), non-finite values, a frame count that says more (truncated file) or less than
  is present. It reads a line lazily and at most one value past the channel count, so frame
  rows all on one line fail at once too.

Semantics: a channel list ``Zrotation Xrotation Yrotation`` means ``R = Rz @ Rx @ Ry``, i.e. scipy
intrinsic ``from_euler("ZXY", [z, x, y], degrees=True)``. Position channels, on the root or on any
other joint, *replace* that joint's OFFSET (the reading of bvhio, Blender and MotionBuilder).

Values are kept in file units (often centimetres or inches) and degrees; :func:`scale_clip`
converts lengths, e.g. to metres for a store.

This module parses and writes only (it imports nothing of dancedata above ``errors`` and
``io``): rotations, forward kinematics, export angles and resampling of a clip are in
:mod:`dancedata.ops.bvh_clip` (on the array functions of :mod:`dancedata.compute`).
"""

from __future__ import annotations

import io
import math
import os
import re
from array import array
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from dancedata.errors import InputError
from dancedata.io.bvh_head import (
    FRAME_TIME_RANGE_S,
    MAX_DEPTH,
    MAX_END_SITES,
    MAX_JOINTS,
    MAX_LINE_BYTES,
    MAX_NAME_CHARS,
    HeadBytes,
    Words,
    decode,
    read_head,
    shown,
)

__all__ = [
    "CHANNEL_NAMES",
    "BvhClip",
    "BvhSkeleton",
    "clip_from_arrays",
    "declared_frames",
    "euler_degrees",
    "euler_radians",
    "format_bvh",
    "local_translations",
    "make_skeleton",
    "parse_bvh",
    "read_bvh",
    "root_translation",
    "scale_clip",
    "values_from_arrays",
    "write_bvh",
]

CHANNEL_NAMES = (
    "Xposition",
    "Yposition",
    "Zposition",
    "Xrotation",
    "Yrotation",
    "Zrotation",
)
_CANONICAL = {name.lower(): name for name in CHANNEL_NAMES}
_AXIS = {"x": 0, "y": 1, "z": 2}

# A BVH number: optional sign, digits with an optional point (``1.``, ``.5``, ``+3``), optional
# exponent. Anything else, including two numbers glued together, is rejected.
# Possessive quantifiers: no backtracking, so a 10,000-digit word ending in "x" is refused in
# microseconds (the plain pattern took 5 s on it, quadratic in its length).
_NUMBER = re.compile(r"[+-]?+(?:[0-9]++\.?+[0-9]*+|\.[0-9]++)(?:[eE][+-]?+[0-9]++)?+")
_GLUE_SPLIT = re.compile(r"(?<=[0-9.])(?=[+-])")
_FRAMES_LINE = re.compile(r"(?i)^\s*frames\s*:\s*(\S*)\s*$")
_FRAME_TIME_LINE = re.compile(r"(?i)^\s*frame\s*time\s*:\s*(\S*)\s*$")
_MOTION_ALLOWED = b"0123456789+-.eE \t\r\n"
_BLANK_RUN = re.compile(rb"\s*")
_MAX_FRAME_DIGITS = 18
_MAX_ROW_CHARS_PER_VALUE = 64  # a longer first row sends the block to the strict path
_VALUE = re.compile(rb"\S+")
_STRUCTURE_WORDS = {"{", "}", "offset", "channels", "joint", "end", "root", "hierarchy", "motion"}


# --------------------------------------------------------------------------------------------
# Data model


@dataclass(frozen=True, eq=False)
class BvhSkeleton:
    """A BVH hierarchy.

    Joints are numbered in file (depth-first) order, so ``parents[j] < j`` and the root is 0.

    Attributes:
        names: joint names, unique.
        parents: parent index per joint, -1 for the root.
        offsets: (J, 3) float64 OFFSET of each joint from its parent, file units.
        channels: per joint, its channel names in file order (canonical spelling, e.g.
            ``("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")``).
        end_sites: per joint, a (K, 3) float64 array of End Site offsets (K may be 0 or > 1).
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[np.ndarray, ...] = field(default=())

    def __post_init__(self) -> None:
        n = len(self.names)
        offsets = np.asarray(self.offsets, dtype=np.float64).reshape(n, 3)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", tuple(int(p) for p in self.parents))
        object.__setattr__(self, "channels", tuple(tuple(c) for c in self.channels))
        ends = self.end_sites or tuple(np.zeros((0, 3)) for _ in range(n))
        ends = tuple(np.asarray(e, dtype=np.float64).reshape(-1, 3) for e in ends)
        object.__setattr__(self, "end_sites", ends)
        if not (len(self.parents) == len(self.channels) == len(self.end_sites) == n) or n == 0:
            raise ValueError("names, parents, channels and end_sites must have one entry per joint")
        if self.parents[0] != -1:
            raise ValueError("joint 0 must be the root (parent -1)")
        for j, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < j:
                raise ValueError(f"joint {j} ({self.names[j]!r}) has parent {p}; need 0 <= p < j")
        if len(set(self.names)) != n:
            raise ValueError("joint names must be unique")
        for name, chans in zip(self.names, self.channels, strict=True):
            if not name or any(c in name for c in "\r\n{}"):
                raise ValueError(f"joint name {name!r} cannot be written to BVH")
            if len(set(chans)) != len(chans) or any(c not in CHANNEL_NAMES for c in chans):
                raise ValueError(f"joint {name!r}: invalid channels {chans}")

    @property
    def n_joints(self) -> int:
        return len(self.names)

    @cached_property
    def n_channels(self) -> int:
        return sum(len(c) for c in self.channels)

    @cached_property
    def channel_starts(self) -> np.ndarray:
        """(J,) first column of each joint's channels in a frame row."""
        counts = np.array([len(c) for c in self.channels], dtype=np.int64)
        return np.concatenate([[0], np.cumsum(counts)[:-1]])

    @cached_property
    def rotation_orders(self) -> tuple[str, ...]:
        """Per joint, the scipy *intrinsic* Euler order of its rotation channels (3 upper-case
        letters). Axes a joint has no channel for are appended in X, Y, Z order; their angle is
        always 0, so they do not change the rotation."""
        orders = []
        for chans in self.channels:
            axes = [c[0] for c in chans if c.endswith("rotation")]
            axes += [a for a in "XYZ" if a not in axes]
            orders.append("".join(axes))
        return tuple(orders)

    @cached_property
    def _rotation_columns(self) -> np.ndarray:
        """(J, 3) column of each Euler angle (in rotation_orders order), -1 if absent."""
        cols = np.full((self.n_joints, 3), -1, dtype=np.int64)
        for j, chans in enumerate(self.channels):
            order = self.rotation_orders[j]
            for k, c in enumerate(chans):
                if c.endswith("rotation"):
                    cols[j, order.index(c[0])] = self.channel_starts[j] + k
        return cols

    @cached_property
    def _position_columns(self) -> np.ndarray:
        """(J, 3) column of each x/y/z position channel, -1 if absent."""
        cols = np.full((self.n_joints, 3), -1, dtype=np.int64)
        for j, chans in enumerate(self.channels):
            for k, c in enumerate(chans):
                if c.endswith("position"):
                    cols[j, _AXIS[c[0].lower()]] = self.channel_starts[j] + k
        return cols

    @property
    def has_position_channels(self) -> np.ndarray:
        """(J,) bool: the joint has at least one position channel."""
        return np.asarray((self._position_columns >= 0).any(axis=1))

    def same_hierarchy(self, other: BvhSkeleton, atol: float = 1e-6) -> bool:
        """Names, parents, channels, offsets and End Sites agree (lengths within ``atol``)."""
        return (
            self.names == other.names
            and self.parents == other.parents
            and self.channels == other.channels
            and np.allclose(self.offsets, other.offsets, rtol=0, atol=atol)
            and all(
                a.shape == b.shape and np.allclose(a, b, rtol=0, atol=atol)
                for a, b in zip(self.end_sites, other.end_sites, strict=True)
            )
        )


def make_skeleton(
    names: Sequence[str],
    parents: Sequence[int],
    offsets: np.ndarray,
    rotation_order: str = "ZYX",
    root_position: bool = True,
) -> BvhSkeleton:
    """A BVH skeleton for a rig that has no channel layout of its own (e.g. SMPL from a store):
    every joint gets three rotation channels in ``rotation_order`` (intrinsic, e.g. "ZXY" for
    ``Zrotation Xrotation Yrotation``), the root also X/Y/Z position channels. Joints must be
    ordered parents first (``parents[j] < j``)."""
    order = rotation_order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"rotation_order must be a permutation of XYZ, got {rotation_order!r}")
    rotation = tuple(f"{axis}rotation" for axis in order)
    position = ("Xposition", "Yposition", "Zposition")
    channels = tuple(
        (position + rotation) if (p < 0 and root_position) else rotation for p in parents
    )
    return BvhSkeleton(tuple(names), tuple(parents), np.asarray(offsets), channels)


@dataclass(frozen=True, eq=False)
class BvhClip:
    """A skeleton with its motion: ``values`` (F, C) float64, one row per frame, columns in joint
    order then each joint's channel order (positions in file units, rotations in degrees)."""

    skeleton: BvhSkeleton
    frame_time_s: float
    values: np.ndarray

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != self.skeleton.n_channels:
            raise ValueError(
                f"values must be (frames, {self.skeleton.n_channels}), got {values.shape}"
            )
        frame_time = float(self.frame_time_s)
        if not (math.isfinite(frame_time) and frame_time > 0):
            raise ValueError(f"frame time must be positive, got {self.frame_time_s}")
        object.__setattr__(self, "frame_time_s", frame_time)
        object.__setattr__(self, "values", values)

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def fps(self) -> float:
        """Frames per second exactly as the file states it (1 / Frame Time)."""
        return 1.0 / self.frame_time_s

    @property
    def nominal_fps(self) -> float:
        """``fps`` snapped to the nearest integer when within 0.1 % of it: BVH writers print the
        frame time with few digits (``.0083333`` is 120.0005 fps, ``0.008333`` is 120.005)."""
        fps = self.fps
        nearest = round(fps)
        return float(nearest) if nearest > 0 and abs(fps - nearest) <= 1e-3 * fps else fps


# --------------------------------------------------------------------------------------------
# Reader


@dataclass(frozen=True, eq=False)
class _Head:
    """What the head of a file says: the skeleton, the column permutation file → joint order
    (None when the CHANNELS lines are in joint order), the frame count and time, and where the
    frame rows start (byte offset into the file, line number)."""

    skeleton: BvhSkeleton
    column_order: np.ndarray | None
    n_frames: int
    frame_time_s: float
    data_start: int
    data_line: int


def read_bvh(path: str | Path, *, rows_present: bool = False) -> BvhClip:
    """Read a BVH file. Raises InputError (with the line number) on malformed input.

    ``rows_present``: keep every frame row the MOTION block holds, however many ``Frames:``
    declares (default: a count other than the declared one is an error naming both counts).

    The head is read in growing prefixes (see :mod:`dancedata.io.bvh_head`), so a file that is
    not BVH fails having read little of it; the frame rows are then read in one piece. The
    result is exactly :func:`parse_bvh` of the file's bytes."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            prefix, (head, mac) = read_head(
                handle, lambda data, at_eof: _file_head(data, at_eof, path)
            )
            if not handle.seekable():  # a pipe: the head is fine, parse the whole stream
                return parse_bvh(
                    bytes(prefix) + handle.read(), path=path, rows_present=rows_present
                )
            handle.seek(head.data_start)
            del prefix
            block = handle.read()
            if mac and b"\n" in block:  # not CR-only after all: parse it as parse_bvh would
                handle.seek(0)
                return parse_bvh(handle.read(), path=path, rows_present=rows_present)
    except OSError as exc:
        raise InputError(f"cannot read BVH file: {exc.strerror or exc}", path) from exc
    if mac:
        block = block.replace(b"\r", b"\n")
    return _clip(head, block, path, rows_present)


def declared_frames(path: str | Path) -> int:
    """The frame count the file's ``Frames:`` line declares (reads only the head)."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            _, (head, _) = read_head(handle, lambda data, at_eof: _file_head(data, at_eof, path))
    except OSError as exc:
        raise InputError(f"cannot read BVH file: {exc.strerror or exc}", path) from exc
    return head.n_frames


def _file_head(data: bytearray, at_eof: bool, path: Path) -> tuple[_Head, bool]:
    """The head parsed from a prefix of the file, and whether it has classic Mac line endings
    (CR, no LF: read with CR as LF, as :func:`parse_bvh` does; same length, same offsets)."""
    mac = b"\n" not in data and b"\r" in data
    if mac:
        data = data.replace(b"\r", b"\n")
    return _parse_head(HeadBytes(data, at_eof, path), path), mac


def parse_bvh(
    data: bytes | str, path: str | Path | None = None, *, rows_present: bool = False
) -> BvhClip:
    """Parse BVH content (bytes or text); ``path`` is only used in error messages;
    ``rows_present`` as for :func:`read_bvh`."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    data = bytes(data)
    if b"\n" not in data and b"\r" in data:  # classic Mac line endings
        data = data.replace(b"\r", b"\n")
    head = _parse_head(HeadBytes(data, True, path), path)
    return _clip(head, data[head.data_start :], path, rows_present)


def _clip(
    head: _Head, block: bytes, path: str | Path | None, rows_present: bool = False
) -> BvhClip:
    n_frames = None if rows_present else head.n_frames
    values = _parse_motion_values(block, head.skeleton.n_channels, n_frames, head.data_line, path)
    if head.column_order is not None:
        values = values[:, head.column_order]
    return BvhClip(skeleton=head.skeleton, frame_time_s=head.frame_time_s, values=values)


def _parse_head(src: HeadBytes, path: str | Path | None) -> _Head:
    """HIERARCHY, MOTION, Frames and Frame Time, from ``src`` (raises NeedMore when it is a
    prefix that ends too soon)."""
    start = 3 if src.data.startswith(b"\xef\xbb\xbf") else 0
    if src.complete and src.is_blank(start):
        raise InputError("empty file, not a BVH file", path)
    words = Words(src, start)
    skeleton, column_order = _parse_hierarchy(words, path)
    if words.motion_end is None:
        raise InputError(f"line {words.last_line}: file ends without a MOTION section", path)
    motion_line = words.last_line
    n_frames, frame_time, data_start, data_line = _parse_motion_header(
        src, words.motion_end, motion_line, path
    )
    if skeleton.n_channels == 0:
        raise InputError(f"line {motion_line}: the hierarchy declares no channels", path)
    return _Head(skeleton, column_order, n_frames, frame_time, data_start, data_line)


class _Joint:
    __slots__ = ("name", "parent", "line", "offset", "channels", "ends")

    def __init__(self, name: str, parent: int, line: int) -> None:
        self.name, self.parent, self.line = name, parent, line
        self.offset: list[float] | None = None
        self.channels: list[str] | None = None
        self.ends: list[list[float]] = []


def _parse_hierarchy(toks: Words, path: str | Path | None) -> tuple[BvhSkeleton, np.ndarray | None]:
    """Parse HIERARCHY ... (up to MOTION) from the word stream. Returns the skeleton and, when
    the CHANNELS declarations are not in joint order, the column permutation file → joint
    order. Refuses more than MAX_JOINTS joints, MAX_END_SITES End Sites, chains deeper than
    MAX_DEPTH joints and names longer than MAX_NAME_CHARS (see :mod:`dancedata.io.bvh_head`)."""

    def fail(line: int, problem: str) -> InputError:
        return InputError(f"line {line}: {problem}", path)

    first = toks.next()
    if first is None:
        raise InputError("no HIERARCHY found, not a BVH file", path)
    if first[0].upper() != "HIERARCHY":
        raise fail(first[1], f"expected HIERARCHY, found {shown(first[0])} (not a BVH file?)")
    root = toks.next()
    if root is None or root[0].upper() != "ROOT":
        line = root[1] if root else first[1]
        found = shown(root[0]) if root else "end of header"
        raise fail(line, f"expected ROOT, found {found}")

    joints: list[_Joint] = []
    declared: list[int] = []  # joint indices in the order their CHANNELS lines appear
    seen_names: dict[str, int] = {}
    n_end_sites = 0

    def open_joint(keyword_line: int, parent: int) -> int:
        if len(joints) >= MAX_JOINTS:
            raise fail(keyword_line, f"more than {MAX_JOINTS:,} joints (the reader's limit)")
        words, too_long = toks.rest_of_line(keyword_line)
        if too_long:
            raise fail(
                keyword_line,
                f"joint name longer than {MAX_NAME_CHARS:,} characters, starting "
                f"{' '.join(words)[:40]!r}... (line breaks missing?)",
            )
        brace_on_line = bool(words) and words[-1] == "{"
        if brace_on_line:
            words = words[:-1]
        name = " ".join(words)
        if not name:
            raise fail(keyword_line, "joint without a name")
        if "{" in name or "}" in name:
            raise fail(
                keyword_line, f"joint name {shown(name)} contains a brace (missing line break?)"
            )
        if name in seen_names:
            raise fail(
                keyword_line,
                f"duplicate joint name {shown(name)} (first on line {seen_names[name]})",
            )
        seen_names[name] = keyword_line
        joints.append(_Joint(name, parent, keyword_line))
        if not brace_on_line:
            expect_brace(keyword_line, f"joint {shown(name)}")
        return len(joints) - 1

    def expect_brace(line: int, what: str) -> None:
        tok = toks.next()
        if tok is None or tok[0] != "{":
            found = shown(tok[0]) if tok else "end of header"
            raise fail(tok[1] if tok else line, f"expected '{{' after {what}, found {found}")

    def read_numbers(line: int, count: int, what: str) -> list[float]:
        out: list[float] = []
        for _ in range(count):
            tok = toks.peek()
            if tok is None or tok[1] != line and _is_structure(tok[0]):
                raise fail(line, f"{what} needs {count} numbers, found {len(out)}")
            toks.next()
            out.append(_header_number(tok[0], tok[1], what, path))
        return out

    def read_channels(line: int, joint: _Joint) -> None:
        tok = toks.next()
        if tok is None or not re.fullmatch(r"[0-9]+", tok[0]):
            found = shown(tok[0]) if tok else "nothing"
            raise fail(line, f"CHANNELS needs a channel count, found {found}")
        if len(tok[0]) > 3 or int(tok[0]) > len(CHANNEL_NAMES):
            raise fail(
                line,
                f"CHANNELS declares {shown(tok[0], 12)} channels, a joint has at most "
                f"{len(CHANNEL_NAMES)}",
            )
        count = int(tok[0])
        names: list[str] = []
        for _ in range(count):
            nxt = toks.peek()
            if nxt is None or _is_structure(nxt[0]):
                raise fail(line, f"CHANNELS declares {count} channels but lists {len(names)}")
            toks.next()
            canonical = _CANONICAL.get(nxt[0].lower())
            if canonical is None:
                raise fail(
                    nxt[1],
                    f"unknown channel {shown(nxt[0])} (expected one of {', '.join(CHANNEL_NAMES)})",
                )
            if canonical in names:
                raise fail(
                    nxt[1], f"channel {canonical} listed twice for joint {shown(joint.name)}"
                )
            names.append(canonical)
        extra, more = toks.rest_of_line(line)
        if extra or more:
            listed = f"more than {count + len(extra)}" if more else f"{count + len(extra)}"
            raise fail(line, f"CHANNELS declares {count} channels but lists {listed}")
        joint.channels = names

    # Stack of open blocks: a joint index, or ("end", joint index, line) for an End Site. An
    # End Site holds no joint, so the joints on the stack are the chain from the root.
    stack: list = [open_joint(root[1], -1)]
    end_offset: list[float] | None = None
    while stack:
        top = stack[-1]
        in_end = isinstance(top, tuple)
        tok = toks.next()
        if tok is None:
            if in_end:
                raise fail(toks.last_line, f"End Site opened on line {top[2]} is never closed")
            j = joints[top]
            raise fail(
                toks.last_line,
                f"hierarchy ends before joint {shown(j.name)} (line {j.line}) is closed: "
                "missing '}'",
            )
        word, line = tok
        key = word.upper()
        if word == "}":
            stack.pop()
            if in_end:
                if end_offset is None:
                    raise fail(line, f"End Site opened on line {top[2]} has no OFFSET")
                joints[top[1]].ends.append(end_offset)
                end_offset = None
            else:
                j = joints[top]
                if j.offset is None:
                    raise fail(line, f"joint {shown(j.name)} (line {j.line}) has no OFFSET")
        elif key == "OFFSET":
            nums = read_numbers(line, 3, "OFFSET")
            if in_end:
                if end_offset is not None:
                    raise fail(line, "End Site has a second OFFSET")
                end_offset = nums
            else:
                if joints[top].offset is not None:
                    raise fail(line, f"joint {shown(joints[top].name)} has a second OFFSET")
                joints[top].offset = nums
        elif key == "CHANNELS" and not in_end:
            if joints[top].channels is not None:
                raise fail(line, f"joint {shown(joints[top].name)} has a second CHANNELS line")
            read_channels(line, joints[top])
            declared.append(top)
        elif key == "JOINT" and not in_end:
            if len(stack) >= MAX_DEPTH:
                raise fail(
                    line,
                    f"the hierarchy nests deeper than {MAX_DEPTH:,} joints (the reader's limit)",
                )
            stack.append(open_joint(line, top))
        elif key == "END" and not in_end:
            site = toks.next()
            if site is None or site[0].upper() != "SITE":
                raise fail(line, "expected 'End Site'")
            rest, more = toks.rest_of_line(site[1], max_chars=40)
            if more or rest and rest != ["{"]:
                raise fail(line, f"unexpected {shown(' '.join(rest))} after End Site")
            if not rest:
                expect_brace(line, "End Site")
            n_end_sites += 1
            if n_end_sites > MAX_END_SITES:
                raise fail(line, f"more than {MAX_END_SITES:,} End Sites (the reader's limit)")
            stack.append(("end", top, line))
        elif key == "ROOT":
            raise fail(line, "ROOT inside another joint (missing '}'?)")
        else:
            where = "End Site" if in_end else f"joint {shown(joints[top].name)}"
            raise fail(line, f"unexpected {shown(word)} in {where}")

    extra = toks.next()
    if extra is not None:
        if extra[0].upper() == "ROOT":
            raise fail(extra[1], "a second ROOT hierarchy is not supported")
        raise fail(extra[1], f"unexpected {shown(extra[0])} after the hierarchy (expected MOTION)")

    channels = [tuple(j.channels or ()) for j in joints]
    skeleton = BvhSkeleton(
        names=tuple(j.name for j in joints),
        parents=tuple(j.parent for j in joints),
        offsets=np.array([j.offset for j in joints], dtype=np.float64),
        channels=tuple(channels),
        end_sites=tuple(np.array(j.ends, dtype=np.float64).reshape(-1, 3) for j in joints),
    )
    with_channels = [j for j in range(len(joints)) if channels[j]]
    declared = [j for j in declared if channels[j]]
    if declared == with_channels:
        return skeleton, None
    # CHANNELS lines appear in another order than the joints: map joint-order columns to file.
    file_start, pos = {}, 0
    for j in declared:
        file_start[j] = pos
        pos += len(channels[j])
    order = np.concatenate(
        [np.arange(file_start[j], file_start[j] + len(channels[j])) for j in with_channels]
    )
    return skeleton, order


def _is_structure(token: str) -> bool:
    return token.lower() in _STRUCTURE_WORDS


def _header_number(token: str, line: int, what: str, path: str | Path | None) -> float:
    if _NUMBER.fullmatch(token):
        value = float(token)
        if math.isfinite(value):
            return value
    raise InputError(f"line {line}: {what}: {_number_problem(token)}", path)


def _number_problem(token: str) -> str:
    parts = _GLUE_SPLIT.split(token)
    if len(parts) > 1 and all(_NUMBER.fullmatch(p) for p in parts):
        return f"{shown(token)} looks like numbers glued together (missing space?)"
    if _NUMBER.fullmatch(token):
        return f"{shown(token)} is not a finite number"
    return f"{shown(token)} is not a number"


def _parse_motion_header(
    src: HeadBytes, pos: int, motion_line: int, path: str | Path | None
) -> tuple[int, float, int, int]:
    """Read the ``Frames:`` and ``Frame Time:`` lines after MOTION (blank lines allowed, either
    order). Returns (frames, frame time in seconds, byte offset of the data, its line number).
    Lines longer than MAX_LINE_BYTES are refused; the frame time must lie in
    FRAME_TIME_RANGE_S."""
    data, end = src.data, src.end
    line_no = motion_line
    frames: int | None = None
    frame_time: float | None = None
    # Invariant: pos is at the newline that ends line ``line_no`` (or at the end of data).
    while frames is None or frame_time is None:
        missing = "Frames" if frames is None else "Frame Time"
        if pos >= end:
            if not src.complete:
                src.out_of_data(line_no)
            raise InputError(f"line {line_no}: file ends before the {missing!r} line", path)
        start = pos + 1
        line_no += 1
        blank = _BLANK_RUN.match(data, start, end)
        assert blank is not None  # \s* matches, if only the empty string
        if blank.end() > start:  # skip blank lines in one step, counting them
            if blank.end() == end and not src.complete:
                src.out_of_data(line_no)
            skipped = data.count(b"\n", start, blank.end())
            if skipped:
                line_no += skipped
                start = data.rfind(b"\n", start, blank.end()) + 1
        nl = data.find(b"\n", start, min(end, start + MAX_LINE_BYTES + 1))
        if nl < 0:
            if end - start > MAX_LINE_BYTES:
                expected = "'Frames: N'" if frames is None else "'Frame Time: T'"
                raise InputError(
                    f"line {line_no}: expected {expected}, found a line of more than "
                    f"{MAX_LINE_BYTES:,} bytes (line breaks missing?)",
                    path,
                )
            if not src.complete:
                src.out_of_data(line_no)
        pos = end if nl < 0 else nl
        text = decode(data[start:pos])
        if not text.strip():
            continue
        m_frames = _FRAMES_LINE.match(text)
        m_time = _FRAME_TIME_LINE.match(text)
        if m_frames and frames is None:
            count = m_frames.group(1)
            if not re.fullmatch(r"[0-9]+", count):
                raise InputError(
                    f"line {line_no}: frame count {shown(count)} is not a whole number", path
                )
            if len(count) > _MAX_FRAME_DIGITS:
                raise InputError(
                    f"line {line_no}: frame count {shown(count, 20)} is not plausible (more "
                    f"than {_MAX_FRAME_DIGITS} digits)",
                    path,
                )
            frames = int(count)
        elif m_time and frame_time is None:
            frame_time = _frame_time(m_time.group(1), line_no, path)
        else:
            expected = "'Frames: N'" if frames is None else "'Frame Time: T'"
            raise InputError(
                f"line {line_no}: expected {expected}, found {shown(text.strip())}", path
            )
    return frames, frame_time, min(pos + 1, len(data)), line_no + 1


def _frame_time(token: str, line: int, path: str | Path | None) -> float:
    """The ``Frame Time`` in seconds, refused outside FRAME_TIME_RANGE_S."""
    value = float(token) if _NUMBER.fullmatch(token) else math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"line {line}: Frame Time {shown(token)} is not a positive number", path)
    low, high = FRAME_TIME_RANGE_S
    if not low <= value <= high:
        written = token if len(token) <= 24 else shown(token, 20)
        raise InputError(
            f"line {line}: Frame Time {written} s is outside the accepted {low:g} to {high:g} s "
            f"({1 / low:,.0f} to {1 / high:g} frames per second)",
            path,
        )
    return value


def _parse_motion_values(
    block: bytes, n_channels: int, n_frames: int | None, first_line: int, path: str | Path | None
) -> np.ndarray:
    """Frame rows → (n_frames, n_channels) float64; fast path first, strict path on doubt.
    ``n_frames`` None: as many rows as the block holds."""
    values = _parse_motion_fast(block, n_channels, n_frames)
    if values is not None:
        return values
    return _parse_motion_strict(block, n_channels, n_frames, first_line, path)


def _parse_motion_fast(block: bytes, n_channels: int, n_frames: int | None) -> np.ndarray | None:
    """pyarrow CSV on whitespace-normalised rows. Returns None whenever the result is not
    certainly right (odd characters, unequal rows, wrong frame count, non-finite values), and
    at once when the first row is far longer than a row of ``n_channels`` numbers can be
    (all rows on one line: the strict path names the line without copying the block)."""
    longest_row = n_channels * _MAX_ROW_CHARS_PER_VALUE + 4096
    if len(block) > longest_row and block.find(b"\n", 0, longest_row) < 0:
        return None
    if block.translate(None, _MOTION_ALLOWED):
        return None
    # Normalise to single spaces between numbers, one row per line; each pass only if needed.
    text = block
    if b"\t" in text or b"\r" in text:
        text = text.translate(bytes.maketrans(b"\t\r", b"  "))
    if b"  " in text:
        text = re.sub(rb" {2,}", b" ", text)
    if b"\n " in text:
        text = text.replace(b"\n ", b"\n")
    if b" \n" in text:
        text = text.replace(b" \n", b"\n")
    text = text.strip(b" \n")
    if not text:
        return np.zeros((0, n_channels)) if not n_frames else None
    if n_frames == 0:
        return None
    lines = text.count(b"\n") + 1  # rows, plus blank lines if any
    if n_frames is None:
        pass  # any count of rows
    elif lines < n_frames or (lines > n_frames and b"\n\n" not in text):
        return None  # the frame count is wrong: the strict path names the line

    import pyarrow as pa
    import pyarrow.csv as pacsv

    names = [f"c{i}" for i in range(n_channels)]
    try:
        table = pacsv.read_csv(
            io.BytesIO(text),
            read_options=pacsv.ReadOptions(column_names=names, block_size=1 << 22),
            parse_options=pacsv.ParseOptions(
                delimiter=" ", quote_char=False, escape_char=False, ignore_empty_lines=True
            ),
            convert_options=pacsv.ConvertOptions(
                column_types={n: pa.float64() for n in names},
                null_values=[],
                strings_can_be_null=False,
            ),
        )
    except (pa.ArrowInvalid, pa.ArrowException):
        return None
    if n_frames is None:
        n_frames = table.num_rows
    if table.num_rows != n_frames or table.num_columns != n_channels:
        return None
    if any(column.null_count for column in table.columns):
        return None
    values = np.empty((n_frames, n_channels), dtype=np.float64)
    row = 0
    for batch in table.to_batches():  # column-major batches → row-major block
        n = batch.num_rows
        values[row : row + n] = np.stack([c.to_numpy() for c in batch.columns], axis=1)
        row += n
    if not np.isfinite(values).all():
        return None
    return values


def _parse_motion_strict(
    block: bytes, n_channels: int, n_frames: int | None, first_line: int, path: str | Path | None
) -> np.ndarray:
    """Line-by-line parse that names the first offending line. Reads at most
    ``n_channels + 1`` values of a line, so a file whose rows are all on one line fails at
    once."""
    values = array("d")
    n_rows = 0
    line = first_line
    last_line = first_line - 1  # the Frame Time line until a frame is read
    pos, size = 0, len(block)
    while (first := _VALUE.search(block, pos)) is not None:
        line += block.count(b"\n", pos, first.start())
        eol = block.find(b"\n", first.start())
        eol = size if eol < 0 else eol
        last_line = line
        if n_rows == n_frames:
            present = n_rows + _count_rows(block, first.start())
            raise InputError(
                f"line {line}: the MOTION block holds {present} frame rows, 'Frames:' declares "
                f"{n_frames}; --frames present reads all {present} rows",
                path,
            )
        row: list[float] = []
        for match in _VALUE.finditer(block, first.start(), eol):
            if len(row) == n_channels:
                break
            text = match.group().decode("latin-1")
            if not _NUMBER.fullmatch(text) or not math.isfinite(value := float(text)):
                raise InputError(f"line {line}: {_number_problem(text)}", path)
            row.append(value)
        else:
            match = None
        if match is not None or len(row) != n_channels:
            raise InputError(
                f"line {line}: frame {n_rows + 1} has {_count_values(block, first.start(), eol)}"
                f" values, the hierarchy declares {n_channels} channels",
                path,
            )
        values.extend(row)
        n_rows += 1
        pos = eol
    if n_frames is None:
        n_frames = n_rows
    if n_rows < n_frames:
        raise InputError(
            f"line {last_line}: file ends after {n_rows} of {n_frames} "
            "frames (truncated, or wrong 'Frames:' count)",
            path,
        )
    return np.frombuffer(values, dtype=np.float64).reshape(n_frames, n_channels).copy()


def _count_rows(block: bytes, start: int) -> int:
    """Lines holding anything but white space in ``block[start:]``."""
    return sum(1 for line in block[start:].split(b"\n") if line.strip())


def _count_values(block: bytes, start: int, stop: int) -> str:
    """How many values a frame line holds, counted exactly up to 1 MiB of line."""
    if stop - start <= 2**20:
        return str(len(block[start:stop].split()))
    return f"more than {len(block[start : start + 2**20].split()) - 1}"


# --------------------------------------------------------------------------------------------
# Per-joint arrays


def euler_degrees(clip: BvhClip) -> np.ndarray:
    """(F, J, 3) Euler angles in degrees, in each joint's ``skeleton.rotation_orders`` order
    (so channels ``Zrotation Xrotation Yrotation`` give [z, x, y]); 0 for absent channels."""
    cols = clip.skeleton._rotation_columns
    padded = np.concatenate([clip.values, np.zeros((clip.n_frames, 1))], axis=1)
    return padded[:, cols]  # column -1 is the zero column


def euler_radians(clip: BvhClip) -> np.ndarray:
    """:func:`euler_degrees` in radians (the store's unit)."""
    return np.radians(euler_degrees(clip))


def local_translations(clip: BvhClip) -> np.ndarray:
    """(F, J, 3) translation of each joint from its parent, file units: the OFFSET, replaced
    axis by axis by the joint's position channels where it has them."""
    skel = clip.skeleton
    cols = skel._position_columns
    out = np.broadcast_to(skel.offsets, (clip.n_frames, skel.n_joints, 3)).copy()
    has = cols >= 0
    out[:, has] = clip.values[:, cols[has]]
    return out


def root_translation(clip: BvhClip) -> np.ndarray:
    """(F, 3) root position in file units (its position channels, else its OFFSET)."""
    return local_translations(clip)[:, 0]


def values_from_arrays(
    skeleton: BvhSkeleton, euler_deg: np.ndarray, translations: np.ndarray | None = None
) -> np.ndarray:
    """Inverse of :func:`euler_degrees` / :func:`local_translations`: build the (F, C) channel
    matrix. ``euler_deg`` is (F, J, 3) in ``skeleton.rotation_orders``; ``translations`` (F, J, 3)
    local translations, required when any joint has position channels. Angles of axes a joint
    has no channel for are dropped."""
    euler_deg = np.asarray(euler_deg, dtype=np.float64)
    n_frames = euler_deg.shape[0]
    if euler_deg.shape != (n_frames, skeleton.n_joints, 3):
        raise ValueError(f"euler_deg must be (F, {skeleton.n_joints}, 3), got {euler_deg.shape}")
    values = np.zeros((n_frames, skeleton.n_channels))
    rot = skeleton._rotation_columns
    has = rot >= 0
    values[:, rot[has]] = euler_deg[:, has]
    pos = skeleton._position_columns
    has = pos >= 0
    if has.any():
        if translations is None:
            raise ValueError("translations are required: the skeleton has position channels")
        translations = np.asarray(translations, dtype=np.float64)
        if translations.shape != (n_frames, skeleton.n_joints, 3):
            raise ValueError(f"translations must be (F, J, 3), got {translations.shape}")
        values[:, pos[has]] = translations[:, has]
    return values


def clip_from_arrays(
    skeleton: BvhSkeleton,
    frame_time_s: float,
    euler_deg: np.ndarray,
    translations: np.ndarray | None = None,
) -> BvhClip:
    """A clip from per-joint Euler angles (degrees) and local translations."""
    return BvhClip(skeleton, frame_time_s, values_from_arrays(skeleton, euler_deg, translations))


def scale_clip(clip: BvhClip, factor: float) -> BvhClip:
    """Multiply every length (offsets, End Sites, position channels) by ``factor``, e.g.
    0.01 for centimetres → metres. Angles are unchanged."""
    skel = clip.skeleton
    scaled = BvhSkeleton(
        names=skel.names,
        parents=skel.parents,
        offsets=skel.offsets * factor,
        channels=skel.channels,
        end_sites=tuple(e * factor for e in skel.end_sites),
    )
    values = clip.values.copy()
    pos = skel._position_columns
    values[:, pos[pos >= 0]] *= factor
    return BvhClip(scaled, clip.frame_time_s, values)


# --------------------------------------------------------------------------------------------
# Writer


def format_bvh(clip: BvhClip, precision: int = 6) -> str:
    """BVH text for ``clip``: tab-indented hierarchy, one frame per line, ``precision`` decimals
    (6 keeps angles within 5e-7 degrees). BVH nests joints, so they are written depth first,
    children in index order, End Sites after child joints; a skeleton whose order is not depth
    first (SMPL's, for one) reads back in that depth-first order."""
    skel = clip.skeleton
    children: list[list[int]] = [[] for _ in range(skel.n_joints)]
    for j, p in enumerate(skel.parents):
        if p >= 0:
            children[p].append(j)

    def num(x: float) -> str:
        return f"{x:.{precision}f}"

    out = ["HIERARCHY"]
    order: list[int] = []  # depth-first joint order = column order of the written file

    # Iterative depth-first walk over ("open", joint, depth), ("end", offset, depth) and
    # ("close", depth) items: children first, then the joint's End Sites, then its "}".
    todo: list[tuple] = [("open", 0, 0)]
    while todo:
        item = todo.pop()
        if item[0] == "close":
            out.append("\t" * item[1] + "}")
            continue
        if item[0] == "end":
            _, site, depth = item
            pad = "\t" * depth
            out += [f"{pad}End Site", pad + "{", f"{pad}\tOFFSET {' '.join(num(v) for v in site)}"]
            out.append(pad + "}")
            continue
        _, j, depth = item
        order.append(j)
        pad = "\t" * depth
        keyword = "ROOT" if skel.parents[j] < 0 else "JOINT"
        out += [f"{pad}{keyword} {skel.names[j]}", pad + "{"]
        out.append(f"{pad}\tOFFSET {' '.join(num(v) for v in skel.offsets[j])}")
        chans = skel.channels[j]
        out.append(f"{pad}\tCHANNELS {len(chans)}{''.join(' ' + c for c in chans)}")
        todo.append(("close", depth))
        todo.extend(("end", site, depth + 1) for site in skel.end_sites[j][::-1])
        todo.extend(("open", child, depth + 1) for child in reversed(children[j]))
    out.append("MOTION")
    out.append(f"Frames: {clip.n_frames}")
    out.append(f"Frame Time: {clip.frame_time_s!r}")

    columns = np.concatenate(
        [skel.channel_starts[j] + np.arange(len(skel.channels[j])) for j in order]
    ).astype(np.int64)
    rows = clip.values[:, columns]
    fmt = " ".join([f"%.{precision}f"] * rows.shape[1])
    text = "\n".join(out) + "\n"
    if len(rows):
        text += "\n".join(fmt % tuple(r) for r in rows.tolist()) + "\n"
    return text


def write_bvh(clip: BvhClip, path: str | Path, precision: int = 6) -> None:
    """Write ``clip`` to ``path`` atomically (temporary file, then rename)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        tmp.write_text(format_bvh(clip, precision), encoding="utf-8", newline="\n")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
