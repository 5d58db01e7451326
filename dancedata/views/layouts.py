"""Every derived layout by name (CONTRACT.md §3: views, not stored copies).

Layouts come from the papers' modules (:mod:`dancedata.views.fact`,
:mod:`dancedata.views.thesis`); adding one is an entry there and its name in
:data:`MOTION_VIEWS` or :data:`AUDIO_VIEWS` here.
"""

from __future__ import annotations

from dancedata.errors import StoreError
from dancedata.views.fact import FACT_VIEWS
from dancedata.views.thesis import THESIS_VIEWS

# Name → ordered parts (kind, array); kind "zeros6" is FACT's six zero columns (no array).
VIEWS: dict[str, list[tuple[str, str]]] = {**FACT_VIEWS, **THESIS_VIEWS}
MOTION_VIEWS = ("fact_motion_225", "thesis_euler_75")
AUDIO_VIEWS = ("fact_audio_35", "thesis_audio_22", "thesis_stems_88")


def check_view_names(*names: str | None) -> None:
    """StoreError naming the known views when a name (None skipped) is not one of them."""
    for name in names:
        if name is not None and name not in VIEWS:
            raise StoreError(f"unknown view {name!r}; known: {sorted(VIEWS)}")
