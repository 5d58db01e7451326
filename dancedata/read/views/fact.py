"""FACT's layouts (Li et al., "AI Choreographer", ICCV 2021; CONTRACT.md §3).

* ``fact_motion_225`` — 6 zeros, root translation (3, metres), 24 joint rotation matrices
  (216, row-major), per frame: the 225-d motion FACT trains on, whose first six columns are
  always zero in its released data.
* ``fact_audio_35`` — onset envelope (1), MFCC (20), chroma CENS (12), onset peaks (1, 0/1),
  beats (1, 0/1): the 35-d audio features of FACT's data pipeline.

A layout is an ordered list of parts ``(kind, array)``: ``kind`` is ``motion`` or ``audio``
(an array under that group) or ``zeros6`` (six zero columns, no array).
"""

from __future__ import annotations

FACT_VIEWS: dict[str, list[tuple[str, str]]] = {
    "fact_motion_225": [("zeros6", ""), ("motion", "trans"), ("motion", "rotmat")],
    "fact_audio_35": [
        ("audio", "onset_env"),
        ("audio", "mfcc"),
        ("audio", "chroma_cens"),
        ("audio", "onset_peaks"),
        ("audio", "beats"),
    ],
}
