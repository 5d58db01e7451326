"""The frame numbers a pose file may name: checked before arrays are sized by them.

OpenPose file names (``<stem>_<frame:012d>_keypoints.json``) and the frame column of a joint
CSV place each detection at its frame number, and gaps become missing frames, so the arrays
are as long as the largest number. A file is refused (one line naming it) when

* a frame number is above :data:`MAX_FRAME_INDEX` (1,000,000 frames: 4.6 h at 60 fps), or
* the numbers span more than :data:`MAX_GAP_FACTOR` times as many frames as there are files /
  rows, plus :data:`FRAME_SLACK` (OpenPose writes a file for every frame, people or not; a
  lifter a row per frame; real gaps are a few frames).

So a folder of 12 files never allocates for frame 300,000,000.
"""

from __future__ import annotations

from pathlib import Path

from dancedata.errors import InputError

MAX_FRAME_INDEX = 1_000_000
MAX_GAP_FACTOR = 4
FRAME_SLACK = 10_000


def check_frame_span(largest: int, count: int, path: str | Path, what: str) -> None:
    """Refuse ``largest`` as the last frame number of ``count`` frames read from ``path``
    (``what`` names them: "files", "rows"), by the limits of the module docstring."""
    if largest > MAX_FRAME_INDEX:
        raise InputError(
            f"frame number {largest} is above the limit of {MAX_FRAME_INDEX} frames "
            "(4.6 h at 60 fps)",
            path,
        )
    span = largest + 1
    allowed = MAX_GAP_FACTOR * count + FRAME_SLACK
    if span > allowed:
        raise InputError(
            f"frame numbers run to {largest} for {count} {what}: more than "
            f"{MAX_GAP_FACTOR} x {count} + {FRAME_SLACK} frames of gaps",
            path,
        )
