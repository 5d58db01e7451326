"""A view of a store: its layout's arrays read through the reader and put side by side.

:func:`sequence_view` gives one sequence's view (frames, D) float32, as
``DanceStore.view``; :func:`view_parts` the whole-store arrays of a view, for the window
datasets and :mod:`dancedata.read.windows`, which slice them. The columns are assembled by
:func:`dancedata.compute.view_columns.stack_parts`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancedata.compute.smpl import SMPL_JOINTS
from dancedata.compute.view_columns import common_length, stack_parts
from dancedata.errors import StoreError
from dancedata.read.views.layouts import (
    MOTION_VIEWS,
    VIEWS,
    ViewSpec,
    check_view_names,
    spec_label,
    spec_names,
    spec_parts,
)

if TYPE_CHECKING:
    from dancedata.read.sequence_reader import _SequenceReader


def sequence_view(store: _SequenceReader, seq_id: str, name: ViewSpec) -> np.ndarray:
    """View ``name`` (a layout, an array path or a list: a view spec) of ``seq_id`` as float32
    (frames, D): motion parts run over the sequence's frames, audio parts over its audio
    frames (``audio_frames``); a spec mixing both is cut to the shorter."""
    check_view_names(name)
    require_view_arrays(store, name)
    parts: list[np.ndarray | None] = []
    for kind, array in spec_parts(name):
        if kind == "zeros6":
            parts.append(None)
            continue
        values = store.motion(seq_id, array) if kind == "motion" else store.audio(seq_id, array)
        parts.append(values.reshape(values.shape[0], -1).astype(np.float32))
    return stack_parts(parts, 0, common_length(parts))


def view_parts(store: _SequenceReader, name: ViewSpec) -> list[np.ndarray | None]:
    """The arrays of view spec ``name`` over the whole store, each as (rows, width) float32 (the
    reader's cached whole arrays reshaped, copied only when not float32); None for FACT's six
    zero columns. Motion parts are indexed by global motion frame, audio parts by music
    frame."""
    check_view_names(name)
    require_view_arrays(store, name)
    parts: list[np.ndarray | None] = []
    for kind, array in spec_parts(name):
        if kind == "zeros6":
            parts.append(None)
            continue
        values = store.whole_array(f"{kind}/{array}")
        values = values.reshape(values.shape[0], -1)
        parts.append(values if values.dtype == np.float32 else values.astype(np.float32))
    return parts


def require_view_arrays(store: _SequenceReader, name: ViewSpec) -> None:
    """A clear StoreError when a spec's arrays are absent (saying whether featurize can help:
    rotation views need joint rotations, which poses from video, or any source with positions
    only, do not have), or when a paper layout does not fit the store
    (:func:`require_view_fits`)."""
    missing = [
        f"{kind}/{array}"
        for kind, array in spec_parts(name)
        if kind != "zeros6" and not store.has_array(f"{kind}/{array}")
    ]
    if not missing:
        require_view_fits(store, name)
        return
    label = spec_label(name)
    message = f"view {label!r} needs {', '.join(missing)}, which version {store.version} lacks"
    names = spec_names(name)
    if not any(n in VIEWS for n in names):
        group = missing[0].split("/", 1)[0]
        held = [n for n in store.array_names() if n.startswith(f"{group}/")]
        message += (
            f" (its {group} arrays: {', '.join(held) or 'none'}; `dancedata featurize --help` "
            "lists the families and what each writes)"
        )
    elif any(n in MOTION_VIEWS for n in names) and not store.has_array("motion/axis_angle"):
        held = [n for n in store.array_names() if n.startswith("motion/")]
        message += (
            f": this store holds no joint rotations (sources: {', '.join(store.sources())}; "
            f"motion arrays: {', '.join(held) or 'none'}), so featurize cannot derive them; "
            "read the stored arrays with motion(seq_id, name) instead"
        )
    elif not any(n in MOTION_VIEWS for n in names) and not store.has_music:
        message += (
            f": this store has no music (sources: {', '.join(store.sources())}; 0 music "
            "tracks), so there are no audio features to compute; ingest the music with the "
            "motion (--music-dir, --music), or read motion only (audio=None)"
        )
    else:
        message += " (run `dancedata featurize`)"
    raise StoreError(message, store.path)


def _rig(store: _SequenceReader) -> tuple[str, list[str]]:
    skeleton = store.group_attrs("motion").get("skeleton") or {}
    joints = skeleton.get("joints") if isinstance(skeleton, dict) else None
    joints = [str(j) for j in joints] if isinstance(joints, list) else []
    name = skeleton.get("name") if isinstance(skeleton, dict) else None
    return str(name or "unnamed"), joints


def _is_smpl24(name: str, joints: list[str]) -> bool:
    return tuple(joints) == SMPL_JOINTS or (name == "smpl24" and len(joints) == 24)


def _row_width(store: _SequenceReader, path: str) -> int:
    return int(np.prod(store.zarr(path).shape[1:], dtype=np.int64))


def require_view_fits(store: _SequenceReader, name: ViewSpec) -> None:
    """StoreError with the reason when a paper layout of the spec does not fit the store,
    instead of a silently different width: the motion layouts (``fact_motion_225``,
    ``thesis_euler_75``) are defined on the 24-joint SMPL rig, and every layout's width is the
    number in its name (an audio array computed with other settings does not fit)."""
    for view in (n for n in spec_names(name) if n in VIEWS):
        parts = [p for p in VIEWS[view] if p[0] != "zeros6"]
        widths = {f"{k}/{a}": _row_width(store, f"{k}/{a}") for k, a in parts}
        width = sum(widths.values()) + (6 if ("zeros6", "") in VIEWS[view] else 0)
        if view in MOTION_VIEWS:
            rig, joints = _rig(store)
            if not _is_smpl24(rig, joints):
                own = " + ".join(f"{p} ({w})" for p, w in widths.items())
                raise StoreError(
                    f"view {view!r} is a layout of the 24-joint SMPL rig, but this store's rig "
                    f"{rig!r} has {len(joints)} joints (it would give {width} columns, not "
                    f"{view.rsplit('_', 1)[-1]}); read the arrays themselves instead, e.g. "
                    f"motion={[p for p in widths]!r} ({own})",
                    store.path,
                )
        declared = int(view.rsplit("_", 1)[-1])
        if width != declared:
            own = ", ".join(f"{p} {w}" for p, w in widths.items())
            raise StoreError(
                f"view {view!r} has {declared} columns by definition, but this store's arrays "
                f"give {width} ({own}): they were computed with other settings; read them as "
                f"array paths instead (e.g. {list(widths)!r})",
                store.path,
            )
