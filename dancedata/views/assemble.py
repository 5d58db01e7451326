"""A view of a store: its layout's arrays read through the reader and put side by side.

:func:`sequence_view` gives one sequence's view (frames, D) float32, as
``DanceStore.view``; :func:`view_parts` the whole-store arrays of a view, for the window
datasets and :mod:`dancedata.windows`, which slice them. The columns are assembled by
:func:`dancedata.compute.view_columns.stack_parts`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancedata.compute.view_columns import common_length, stack_parts
from dancedata.errors import StoreError
from dancedata.views.layouts import MOTION_VIEWS, VIEWS, check_view_names

if TYPE_CHECKING:
    from dancedata.sequence_reader import SequenceReader


def sequence_view(store: SequenceReader, seq_id: str, name: str) -> np.ndarray:
    """View ``name`` of ``seq_id`` as float32 (frames, D): motion views run over the sequence's
    frames, audio views over its audio frames (``audio_frames``); a view mixing both would be
    cut to the shorter."""
    if name not in VIEWS:
        raise StoreError(f"unknown view {name!r}; known: {sorted(VIEWS)}")
    require_view_arrays(store, name)
    parts: list[np.ndarray | None] = []
    for kind, array in VIEWS[name]:
        if kind == "zeros6":
            parts.append(None)
            continue
        values = store.motion(seq_id, array) if kind == "motion" else store.audio(seq_id, array)
        parts.append(values.reshape(values.shape[0], -1).astype(np.float32))
    return stack_parts(parts, 0, common_length(parts))


def view_parts(store: SequenceReader, name: str) -> list[np.ndarray | None]:
    """The arrays of view ``name`` over the whole store, each as (rows, width) float32 (the
    reader's cached whole arrays reshaped, copied only when not float32); None for FACT's six
    zero columns. Motion parts are indexed by global motion frame, audio parts by music
    frame."""
    check_view_names(name)
    require_view_arrays(store, name)
    parts: list[np.ndarray | None] = []
    for kind, array in VIEWS[name]:
        if kind == "zeros6":
            parts.append(None)
            continue
        values = store.whole_array(f"{kind}/{array}")
        values = values.reshape(values.shape[0], -1)
        parts.append(values if values.dtype == np.float32 else values.astype(np.float32))
    return parts


def require_view_arrays(store: SequenceReader, name: str) -> None:
    """A clear StoreError when a view's arrays are absent, saying whether featurize can help:
    rotation views need joint rotations, which poses from video (or any source with positions
    only) do not have."""
    missing = [
        f"{kind}/{array}"
        for kind, array in VIEWS[name]
        if kind != "zeros6" and not store.has_array(f"{kind}/{array}")
    ]
    if not missing:
        return
    message = f"view {name!r} needs {', '.join(missing)}, which version {store.version} lacks"
    if name in MOTION_VIEWS and not store.has_array("motion/axis_angle"):
        held = [n for n in store.array_names() if n.startswith("motion/")]
        message += (
            f": this store holds no joint rotations (sources: {', '.join(store.sources())}; "
            f"motion arrays: {', '.join(held) or 'none'}), so featurize cannot derive them; "
            "read the stored arrays with motion(seq_id, name) instead"
        )
    elif name not in MOTION_VIEWS and not store.has_music:
        message += (
            f": this store has no music (sources: {', '.join(store.sources())}; 0 music "
            "tracks), so there are no audio features to compute; ingest the music with the "
            "motion (--music-dir, --music), or read motion only (audio=None)"
        )
    else:
        message += " (run `dancedata featurize`)"
    raise StoreError(message, store.path)
