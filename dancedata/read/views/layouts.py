"""Every derived layout by name (CONTRACT.md §3: views, not stored copies), and view specs.

Layouts come from the papers' modules (:mod:`dancedata.read.views.fact`,
:mod:`dancedata.read.views.thesis`); adding one is an entry there and its name in
:data:`MOTION_VIEWS` or :data:`AUDIO_VIEWS` here.

A **view spec** (what the window datasets' ``motion=`` / ``audio=`` take) is a layout name, an
array path (``motion/quat``, ``audio/stft_frames``: any array a family wrote) or a list of
those; its parts are the layouts' parts and the arrays, side by side in the order given.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from dancedata.errors import StoreError
from dancedata.read.views.fact import FACT_VIEWS
from dancedata.read.views.thesis import THESIS_VIEWS

# Name → ordered parts (kind, array); kind "zeros6" is FACT's six zero columns (no array).
VIEWS: dict[str, list[tuple[str, str]]] = {**FACT_VIEWS, **THESIS_VIEWS}
MOTION_VIEWS = ("fact_motion_225", "thesis_euler_75")
AUDIO_VIEWS = ("fact_audio_35", "thesis_audio_22", "thesis_stems_88")


ViewSpec = str | Sequence[str]
"""A layout name, an array path (``motion/<name>``, ``audio/<name>``) or a list of them."""

# An array path: a group and one or more name segments of safe characters (never '..', '/').
_ARRAY_PATH = re.compile(r"(motion|audio)(/[A-Za-z0-9_]+)+")


def is_array_path(name: str) -> bool:
    """Whether ``name`` is a well-formed array path under ``motion/`` or ``audio/``."""
    return bool(_ARRAY_PATH.fullmatch(name))


def spec_names(spec: ViewSpec) -> tuple[str, ...]:
    """The names of a view spec, in order (a single name as a 1-tuple)."""
    names = (spec,) if isinstance(spec, str) else tuple(spec)
    if not names or not all(isinstance(n, str) for n in names):
        raise StoreError(f"a view spec is a view name, an array path or a list of them: {spec!r}")
    return names


def spec_label(spec: ViewSpec) -> str:
    """How errors and records name a spec: its names joined by '+'."""
    return "+".join(spec_names(spec))


def spec_parts(spec: ViewSpec) -> list[tuple[str, str]]:
    """The ordered parts (kind, array) of a spec: each layout's parts, each array path as
    (group, rest). StoreError naming the known views for anything else."""
    parts: list[tuple[str, str]] = []
    for name in spec_names(spec):
        if name in VIEWS:
            parts += VIEWS[name]
        elif is_array_path(name):
            group, rest = name.split("/", 1)
            parts.append((group, rest))
        else:
            raise StoreError(
                f"unknown view {name!r}; known: {sorted(VIEWS)}, or an array path such as "
                "motion/quat or audio/mfcc (any array of the store)"
            )
    return parts


def check_view_names(*specs: ViewSpec | None) -> None:
    """StoreError naming the known views when a spec (None skipped) has an unknown name."""
    for spec in specs:
        if spec is not None:
            spec_parts(spec)
