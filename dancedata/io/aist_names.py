"""AIST++ naming conventions: sequence names, genres, and the tempo of every music id.

A sequence name such as ``gBR_sBM_cAll_d04_mBR0_ch01`` carries genre (gBR), situation (sBM basic,
sFM advanced/freestyle), camera (cAll), dancer (d04), music id (mBR0) and choreography (ch01).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from dancedata.errors import InputError

GENRES: dict[str, str] = {
    "gBR": "Break",
    "gPO": "Pop",
    "gLO": "Lock",
    "gMH": "Middle Hip-hop",
    "gLH": "LA-style Hip-hop",
    "gHO": "House",
    "gWA": "Waack",
    "gKR": "Krump",
    "gJS": "Street Jazz",
    "gJB": "Ballet Jazz",
}
SITUATIONS: dict[str, str] = {"sBM": "basic", "sFM": "advanced"}
# The music ids held out for crossmodal val/test in the official split.
HELD_OUT_MUSIC_IDS: tuple[str, ...] = (
    "mBR0",
    "mPO1",
    "mLO2",
    "mMH3",
    "mLH4",
    "mHO5",
    "mWA0",
    "mKR2",
    "mJS3",
    "mJB5",
)

_SEQ_RE = re.compile(
    r"^(?P<genre>g[A-Z]{2})_(?P<situation>s[A-Z]{2})_(?P<camera>c[A-Za-z0-9]+)_"
    r"(?P<dancer>d\d{2})_(?P<music_id>m[A-Z]{2}\d)_(?P<choreo>ch\d{2})$"
)
_MUSIC_RE = re.compile(r"^m(?P<genre>[A-Z]{2})(?P<k>\d)$")


@dataclass(frozen=True)
class SequenceName:
    """The parts of an AIST++ sequence name."""

    seq_id: str
    genre: str
    situation: str
    camera: str
    dancer: str
    music_id: str
    choreo: str


def parse_sequence_name(name: str) -> SequenceName:
    """Split an AIST++ sequence name into its parts; InputError if it does not follow the
    convention or names an unknown genre."""
    match = _SEQ_RE.match(name)
    if not match:
        raise InputError(
            "not an AIST++ sequence name (expected e.g. gBR_sBM_cAll_d04_mBR0_ch01)", name
        )
    parts = match.groupdict()
    if parts["genre"] not in GENRES:
        raise InputError(f"unknown genre {parts['genre']!r}", name)
    if parts["music_id"][1:3] != parts["genre"][1:3]:
        raise InputError(f"music id {parts['music_id']} does not belong to genre", name)
    return SequenceName(seq_id=name, **parts)


def music_bpm(music_id: str) -> float:
    """Tempo of an AIST music id in BPM: 80 + 10k, except House (mHO), which is 110 + 5k."""
    match = _MUSIC_RE.match(music_id)
    if not match or f"g{match.group('genre')}" not in GENRES:
        raise InputError("not an AIST music id (expected e.g. mBR0)", music_id)
    k = int(match.group("k"))
    if k > 5:
        raise InputError("AIST music ids run from 0 to 5", music_id)
    return float(110 + 5 * k if match.group("genre") == "HO" else 80 + 10 * k)


def music_genre(music_id: str) -> str:
    """``mBR0`` → ``gBR``."""
    return "g" + music_id[1:3]
