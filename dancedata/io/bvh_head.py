"""The head of a BVH file (HIERARCHY, MOTION, ``Frames:``, ``Frame Time:``) read with bounded
memory, and the reader's documented limits.

A BVH file is trusted for nothing: a 200 MB file on one line, a hierarchy nested 10,000 deep or a
``Frame Time`` of 5e-324 must end in one line naming the file and the problem, fast and without
gigabytes of memory. So the head is scanned word by word straight from the bytes (no list of
lines, no decoded copy of the file), every word and name has a maximum length, and the whole head
must lie in the first :data:`MAX_HEADER_BYTES` of the file. :func:`read_head` reads a file's head
in growing prefixes (1 MiB first), so a file that is not BVH fails after reading little of it.

Limits, far above any real rig (the five real files have at most 59 joints, 15 End Sites, chains
of at most 13 joints and 26-character names; production rigs with faces and fingers have a few
hundred joints):

* :data:`MAX_JOINTS` joints and :data:`MAX_END_SITES` End Sites in all;
* :data:`MAX_DEPTH` joints on the chain from the root to any joint (the root is depth 1);
* joint names of at most :data:`MAX_NAME_CHARS` characters, header words of at most
  :data:`MAX_WORD_BYTES` bytes, ``Frames:`` / ``Frame Time:`` lines of at most
  :data:`MAX_LINE_BYTES` bytes;
* the head (everything before the first frame row) within :data:`MAX_HEADER_BYTES`;
* ``Frame Time`` within :data:`FRAME_TIME_RANGE_S` seconds (see there).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn, Protocol, TypeVar

from dancedata.errors import InputError

__all__ = [
    "FPS_RANGE",
    "FRAME_TIME_RANGE_S",
    "MAX_DEPTH",
    "MAX_END_SITES",
    "MAX_HEADER_BYTES",
    "MAX_JOINTS",
    "MAX_LINE_BYTES",
    "MAX_NAME_CHARS",
    "MAX_WORD_BYTES",
    "HeadBytes",
    "NeedMore",
    "ReadsInto",
    "Words",
    "decode",
    "read_head",
    "shown",
]

MAX_JOINTS = 10_000
MAX_END_SITES = 10_000
MAX_DEPTH = 5_000
MAX_NAME_CHARS = 1_000
MAX_WORD_BYTES = 4_096
MAX_LINE_BYTES = 4_096
MAX_HEADER_BYTES = 64 * 2**20

#: Accepted ``Frame Time`` in seconds: 10,000 down to 0.1 frames per second. Mocap systems
#: export at most a few thousand frames per second and key-framed or single-pose files use
#: 1 s; the rest of the toolkit computes with the rate (audio features at sr = fps × 512 Hz,
#: jerk scaled by fps³ and stored as float32, measures of 60 / bpm × 4 × fps frames), which
#: stays finite and meaningful in this range and not for 5e-324 s (fps = inf) or 1e300 s.
FRAME_TIME_RANGE_S = (1e-4, 10.0)
#: The same range as frames per second (0.1 to 10,000), e.g. for a resampling target.
FPS_RANGE = (1.0 / FRAME_TIME_RANGE_S[1], 1.0 / FRAME_TIME_RANGE_S[0])

_FIRST_READ_BYTES = 2**20
_CHUNK_BYTES = 2**16
_T = TypeVar("_T")
_WORD = re.compile(rb"\S{1,%d}" % (MAX_WORD_BYTES + 1))
_NON_SPACE = re.compile(rb"\S")
_TEXT_WORD = re.compile(r"\S+")  # on decoded text: splits at Unicode whitespace like str.split
_MOTION_AT = re.compile(rb"(?i)[ \t]*MOTION[ \t]*\r?(?=\n|\Z)")
_MOTION_LINE = re.compile(rb"(?im)^[ \t]*MOTION[ \t]*\r?(?=\n|\Z)")


class ReadsInto(Protocol):
    """A binary file opened for reading (``open(path, "rb")``): all :func:`read_head` uses."""

    def readinto(self, buffer: memoryview, /) -> int | None: ...


class NeedMore(Exception):
    """The head goes on past the bytes read so far: read more of the file and parse again."""


def decode(raw: bytes | bytearray) -> str:
    """UTF-8, else Latin-1 (which decodes any bytes)."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def shown(text: str, limit: int = 40) -> str:
    """``repr(text)``, cut to ``limit`` characters with a note of the full length, so that an
    error message quoting the file stays one short line."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text):,} characters)"


class HeadBytes:
    """The first bytes of a BVH file, ``data``, of which at most :data:`MAX_HEADER_BYTES` are
    looked at; ``at_eof`` says whether ``data`` is the whole file."""

    def __init__(self, data: bytes | bytearray, at_eof: bool, path: str | Path | None) -> None:
        self.data = data
        self.end = min(len(data), MAX_HEADER_BYTES)
        self.complete = at_eof and len(data) <= MAX_HEADER_BYTES
        self.path = path

    def out_of_data(self, line: int) -> NoReturn:
        """Parsing needs bytes past ``end``: past the limit this is an error, otherwise the
        caller has to read more (:class:`NeedMore`)."""
        if len(self.data) > MAX_HEADER_BYTES:
            raise InputError(
                f"line {line}: no frame data within the first {MAX_HEADER_BYTES // 2**20} MiB "
                "(the most a BVH head may take): not a BVH file, or line breaks are missing",
                self.path,
            )
        raise NeedMore

    def is_blank(self, start: int) -> bool:
        """Nothing but ASCII whitespace from ``start`` (only asked of a complete file)."""
        return _NON_SPACE.search(self.data, start) is None


class Words:
    """Whitespace-separated words of the HIERARCHY, each with its 1-based line number, scanned
    lazily from the bytes. The stream ends at the first line holding only ``MOTION``
    (``motion_end`` is then the offset just after that word, ``last_line`` its line) or at the
    end of the file (``motion_end`` None, ``last_line`` the file's last line).

    Whole lines are split a chunk (up to _CHUNK_BYTES) at a time, each chunk decoded as UTF-8,
    else Latin-1, and split at Unicode whitespace; a line longer than a chunk is read one word
    at a time, so a file on one line costs no more than the words the parser asks for."""

    def __init__(self, head: HeadBytes, start: int) -> None:
        self.head = head
        self.data = head.data
        self.first = start  # where the file's text starts (after a byte order mark)
        self.scan = start  # bytes before this offset are consumed
        self.line = 1  # line of offset ``scan``
        self.line_start = start  # offset where that line begins
        self.items: list[tuple[str, int]] = []
        self.pos = 0
        self.whole_line = False  # items hold all the words up to the end of their last line
        self.motion: tuple[int, int] | None = None  # (end offset, line) of a MOTION line ahead
        self.done = False
        self.motion_end: int | None = None
        self.last_line = 1

    def _advance_to(self, offset: int) -> None:
        newlines = self.data.count(b"\n", self.scan, offset)
        if newlines:
            self.line += newlines
            self.line_start = self.data.rfind(b"\n", self.scan, offset) + 1
        self.scan = offset

    def _finish(self, motion_end: int | None, line: int) -> bool:
        self.done, self.motion_end, self.last_line = True, motion_end, line
        return False

    def _fill(self) -> bool:
        """Queue the words of the next chunk of whole lines (or of a very long line's next
        word); False when the words have ended. Blank space is skipped at C speed."""
        head, data = self.head, self.data
        while self.pos >= len(self.items):
            if self.done:
                return False
            if self.motion is not None:
                return self._finish(*self.motion)
            word = _NON_SPACE.search(data, self.scan, head.end)
            if word is None:
                if not head.complete:
                    head.out_of_data(self.line)
                self._advance_to(head.end)
                return self._finish(None, self.line)
            self._advance_to(word.start())
            limit = min(head.end, self.scan + _CHUNK_BYTES)
            if limit == head.end and head.complete:
                stop = limit
            else:
                stop = data.rfind(b"\n", self.scan, limit) + 1
                if stop == 0:
                    if limit == head.end:
                        head.out_of_data(self.line)  # the line goes on past the bytes read
                    self._one_word()
                    continue
            self._queue_lines(stop)
        return True

    def _queue_lines(self, stop: int) -> None:
        """Queue the words of data[scan:stop] (scan at a word, stop after a newline or at the
        end of the file), up to a MOTION line."""
        data, start = self.data, self.scan
        motion = _MOTION_AT.match(data, self.line_start, stop) or _MOTION_LINE.search(
            data, start, stop
        )
        if motion is not None:  # it starts at the start of its line
            stop = max(motion.start(), start)
            self.motion = (motion.end(), self.line + data.count(b"\n", start, stop))
        text = decode(data[start:stop])
        items: list[tuple[str, int]] = []
        if text.count("\n") * 4 > len(text):  # mostly blank lines: find the words instead
            line, counted = self.line, 0
            for match in _TEXT_WORD.finditer(text):
                line += text.count("\n", counted, match.start())
                counted = match.start()
                items.append((match.group(), line))
        else:
            for number, line_text in enumerate(text.split("\n"), start=self.line):
                items += [(word, number) for word in line_text.split()]
        if len(text) > MAX_WORD_BYTES:
            for word, number in items:
                self._check_word_length(word, number)
        self._advance_to(stop)
        self.items, self.pos, self.whole_line = items, 0, True

    def _one_word(self) -> None:
        """Queue the next word of a line longer than a chunk (``scan`` is at that word)."""
        head, data = self.head, self.data
        match = _WORD.match(data, self.scan, head.end)
        # scan is at a non-space byte before head.end, so at least that byte matches
        assert match is not None
        if match.end() == head.end and not head.complete:
            head.out_of_data(self.line)
        word = match.group()
        self._check_word_length(word, self.line)
        if word.upper() == b"MOTION":
            alone = _MOTION_AT.match(data, self.line_start, head.end)
            if alone is not None:
                if alone.end() == head.end and not head.complete:
                    head.out_of_data(self.line)
                self.motion = (alone.end(), self.line)
                self.items, self.pos = [], 0
                return
        self.scan = match.end()
        self.items = [(text, self.line) for text in decode(word).split()]
        self.pos, self.whole_line = 0, False

    def _check_word_length(self, word: bytes | str, line: int) -> None:
        if len(word) > MAX_WORD_BYTES:
            raise InputError(
                f"line {line}: a word of more than {MAX_WORD_BYTES:,} bytes "
                f"({word[:40]!r}...): not a BVH hierarchy",
                self.head.path,
            )

    def peek(self) -> tuple[str, int] | None:
        if self.pos < len(self.items):
            return self.items[self.pos]
        return self.items[self.pos] if self._fill() else None

    def next(self) -> tuple[str, int] | None:
        item = self.peek()
        self.pos += item is not None
        return item

    def rest_of_line(self, line: int, max_chars: int = MAX_NAME_CHARS) -> tuple[list[str], bool]:
        """Consume and return the remaining words on ``line``, and whether they were cut short
        because together (joined by spaces) they pass ``max_chars`` characters."""
        out: list[str] = []
        size = -1
        while True:
            if self.pos >= len(self.items) and (self.whole_line or not self._fill()):
                return out, False  # the queue held the rest of the line, or the words ended
            word, word_line = self.items[self.pos]
            if word_line != line:
                return out, False
            size += len(word) + 1
            if size > max_chars:
                return out, True
            out.append(word)
            self.pos += 1


def _grown(handle: ReadsInto, data: bytearray, size: int) -> bytearray:
    """``data`` followed by the file's next bytes, up to ``size`` bytes in all (fewer only at
    the end of the file); read in place, so growing costs no second copy of the new part."""
    out = bytearray(size)
    out[: len(data)] = data
    got = len(data)
    with memoryview(out) as view:
        while got < size:
            n = handle.readinto(view[got:])
            if not n:
                break
            got += n
    del out[got:]
    return out


def read_head(handle: ReadsInto, parse: Callable[[bytearray, bool], _T]) -> tuple[bytearray, _T]:
    """``parse(prefix, at_eof)`` on a growing prefix of ``handle`` (1 MiB, then 4× more, at
    most :data:`MAX_HEADER_BYTES` + 1 bytes, grown in place) until it no longer raises
    :class:`NeedMore`. Returns the prefix read and what ``parse`` returned."""
    want = _FIRST_READ_BYTES
    data = bytearray()
    while True:
        data = _grown(handle, data, want)
        try:
            return data, parse(data, len(data) < want)
        except NeedMore:
            want = min(want * 4, MAX_HEADER_BYTES + 1)
