"""Choose one dancer among the people OpenPose found in each frame, and follow them.

Pure compute: ragged per-frame detections in (:class:`dancedata.io.openpose.OpenPoseFrames` or the
same arrays), one (F, J, 2) track out. Pixels throughout; frames are video frames.

How identity is kept
--------------------
1. Every person with at least one joint of confidence > ``min_conf`` is a *detection*, with a
   bounding box over those joints.
2. A bounding-box tracker links detections from frame to frame into *tracklets*: each tracklet
   predicts its joints and box with constant velocity; the cost of a detection is
   ``(1 - IoU(predicted box, box)) + distance / box diagonal``, where the distance is the median
   displacement of the joints seen in both (the box-centre displacement when fewer than two are
   shared), so a limb flickering in and out of detection does not break the track. Pairs beyond
   ``max_dist`` box diagonals are never linked, and each frame's assignment is the minimum total
   cost (Hungarian). A tracklet survives up to ``max_lost`` frames without a detection. Velocity
   is what keeps two dancers apart when they cross paths.
3. Identity labels come from OpenPose's ``person_id`` when every detection carries one
   (OpenPose run with ``--tracking``); otherwise from the tracklets (``method="bbox"``).
4. The default dancer is the label with the **largest mean bounding-box area** over the frames it
   is detected in, among labels detected in at least ``min_coverage`` (default half) as many frames
   as the most-detected label: the biggest person who is there most of the time; the coverage
   floor stops a large, short-lived false detection from winning. ``select="frames"`` picks the
   most-detected label instead (ties: larger mean area). ``person`` overrides the choice.
5. Identity switches. With person ids: a frame where the followed id's detection belongs to a
   different tracklet from its previous detection while that body is still being tracked (the
   id jumped to another body; see :func:`_follow_ids`). With tracklets:
   when the followed tracklet is lost, the tracker re-links to the tracklet that starts next
   (within ``relink_gap`` frames) nearest to where the dancer was last seen; identity is not
   verified across such a hop, so each is counted as a switch. Switch frames are reported.

Missing people or frames and joints with confidence ≤ ``min_conf`` become NaN with ``mask`` False
and confidence 0. :func:`fill_gaps` then optionally interpolates short gaps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.optimize import linear_sum_assignment

from dancedata.errors import InputError

_NO_LINK = 1e9


@dataclass(frozen=True)
class TrackedPose:
    """One dancer followed through the frames.

    Attributes:
        coords: (F, J, 2) float32 pixels; NaN where not known.
        conf: (F, J) float32 detector confidence; 0 where not detected.
        mask: (F, J) bool, True where ``coords`` holds a value (detected or gap-filled).
        filled: (F, J) bool, True where the value was interpolated by :func:`fill_gaps`.
        source_row: (F,) int64 row of the followed detection in the ragged input, -1 if none.
        label: (F,) int64 identity label followed in each frame (person id or tracklet), -1 if
            none; differs from ``chosen`` after a re-link.
        method: "person_id" or "bbox": where identities came from.
        chosen: the label chosen (person id, or tracklet number by first appearance).
        selection: how it was chosen ("area", "frames", or "override").
        identity_switches: frames at which the followed identity switched body (see module doc).
        n_labels: number of distinct identity labels seen.
    """

    coords: np.ndarray
    conf: np.ndarray
    mask: np.ndarray
    filled: np.ndarray
    source_row: np.ndarray
    label: np.ndarray
    method: str
    chosen: int
    selection: str
    identity_switches: tuple[int, ...] = field(default_factory=tuple)
    n_labels: int = 0

    @property
    def n_switches(self) -> int:
        return len(self.identity_switches)

    def report(self) -> dict:
        """JSON-ready summary for a manifest."""
        detected = self.mask & ~self.filled
        return {
            "method": self.method,
            "chosen": int(self.chosen),
            "selection": self.selection,
            "n_labels": int(self.n_labels),
            "identity_switches": len(self.identity_switches),
            "switch_frames": [int(f) for f in self.identity_switches],
            "frames_with_dancer": int((self.source_row >= 0).sum()),
            "frames": int(self.source_row.shape[0]),
            "joints_detected_fraction": float(detected.mean()) if detected.size else 0.0,
            "joints_filled": int(self.filled.sum()),
            "frames_filled": int(self.filled.any(axis=1).sum()),
        }


# ----------------------------------------------------------------------------- boxes


def bounding_boxes(keypoints: np.ndarray, min_conf: float = 0.0) -> np.ndarray:
    """(P, J, 3) x, y, c → (P, 4) boxes x0, y0, x1, y1 in pixels over joints with c > min_conf.

    Rows with no such joint get NaN.
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    ok = (kp[..., 2] > min_conf) & np.isfinite(kp[..., 0]) & np.isfinite(kp[..., 1])
    x = np.where(ok, kp[..., 0], np.nan)
    y = np.where(ok, kp[..., 1], np.nan)
    boxes = np.full((kp.shape[0], 4), np.nan)
    has = ok.any(axis=1)
    if has.any():
        boxes[has] = np.stack(
            [
                np.nanmin(x[has], 1),
                np.nanmin(y[has], 1),
                np.nanmax(x[has], 1),
                np.nanmax(y[has], 1),
            ],
            axis=1,
        )
    return boxes


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 4) × (M, 4) boxes → (N, M) intersection over union (0 for degenerate boxes)."""
    a = np.asarray(a, dtype=np.float64)[:, None, :]
    b = np.asarray(b, dtype=np.float64)[None, :, :]
    iw = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0, None)
    ih = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0, None)
    inter = iw * ih
    area_a = (a[..., 2] - a[..., 0]) * (a[..., 3] - a[..., 1])
    area_b = (b[..., 2] - b[..., 0]) * (b[..., 3] - b[..., 1])
    union = area_a + area_b - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def _centre(boxes: np.ndarray) -> np.ndarray:
    return np.stack([(boxes[..., 0] + boxes[..., 2]) / 2, (boxes[..., 1] + boxes[..., 3]) / 2], -1)


def _diag(boxes: np.ndarray) -> np.ndarray:
    return np.hypot(boxes[..., 2] - boxes[..., 0], boxes[..., 3] - boxes[..., 1])


def link_cost(
    pred_xy: np.ndarray,
    pred_ok: np.ndarray,
    pred_box: np.ndarray,
    det_xy: np.ndarray,
    det_ok: np.ndarray,
    det_box: np.ndarray,
    max_dist: float,
    min_diag: float = 20.0,
    min_shared: int = 2,
) -> np.ndarray:
    """Cost of linking N predicted people to M detections: (N, M), ``_NO_LINK`` beyond the gate.

    distance = median over the joints seen in both of the joint displacement, or the box-centre
    displacement when fewer than ``min_shared`` joints are shared, divided by the larger of the
    two box diagonals (at least ``min_diag`` pixels). cost = distance + (1 - IoU of the boxes).
    Joints make the distance immune to a limb flickering in and out of detection, which moves
    the box but not the body. Pairs with distance > ``max_dist`` are never linked.
    """
    shared = pred_ok[:, None, :] & det_ok[None, :, :]
    disp = np.linalg.norm(pred_xy[:, None] - det_xy[None, :], axis=-1)
    disp = np.where(shared, disp, np.nan)
    n_shared = shared.sum(axis=-1)
    with np.errstate(all="ignore"):
        joint_dist = np.nanmedian(np.where(n_shared[..., None] > 0, disp, 0.0), axis=-1)
    centre_dist = np.linalg.norm(_centre(pred_box)[:, None] - _centre(det_box)[None, :], axis=-1)
    dist = np.where(n_shared >= min_shared, joint_dist, centre_dist)
    scale = np.maximum(np.maximum(_diag(pred_box)[:, None], _diag(det_box)[None, :]), min_diag)
    dist = dist / scale
    cost = dist + (1.0 - box_iou(pred_box, det_box))
    return np.where(dist <= max_dist, cost, _NO_LINK)


# ----------------------------------------------------------------------------- tracker


def track_people(
    keypoints: np.ndarray,
    frame_offsets: np.ndarray,
    min_conf: float = 0.0,
    max_lost: int = 10,
    max_dist: float = 0.5,
) -> np.ndarray:
    """Link per-frame detections into tracklets; returns (P,) int64 tracklet per row (-1: none).

    Args:
        keypoints: (P, J, 3) x, y (pixels), confidence of all rows.
        frame_offsets: (F + 1,) rows of frame f are ``frame_offsets[f]:frame_offsets[f + 1]``.
        min_conf: joints with confidence ≤ this are not seen; rows with no seen joint are skipped.
        max_lost: frames a tracklet may go undetected and still be continued.
        max_dist: link gate in box diagonals (see :func:`link_cost`).

    Each tracklet predicts its joints and box with a constant velocity per frame (smoothed over
    its last steps); each frame's links minimise the total :func:`link_cost` (Hungarian).
    Tracklets are numbered in order of first appearance (ties left to right by box centre).
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    seen = (kp[..., 2] > min_conf) & np.isfinite(kp[..., :2]).all(axis=-1)
    boxes = bounding_boxes(kp, min_conf)
    n_frames = len(frame_offsets) - 1
    labels = np.full(kp.shape[0], -1, dtype=np.int64)
    last_xy: list[np.ndarray] = []
    last_ok: list[np.ndarray] = []
    last_box: list[np.ndarray] = []
    last_frame: list[int] = []
    vel_xy: list[np.ndarray] = []
    vel_box: list[np.ndarray] = []
    steps: list[int] = []
    for f in range(n_frames):
        lo, hi = int(frame_offsets[f]), int(frame_offsets[f + 1])
        rows = [r for r in range(lo, hi) if seen[r].any()]
        rows.sort(key=lambda r: (boxes[r, 0] + boxes[r, 2]) / 2)
        if not rows:
            continue
        matched: set[int] = set()
        active = [t for t in range(len(last_box)) if f - last_frame[t] <= max_lost + 1]
        if active:
            dt = np.array([f - last_frame[t] for t in active], dtype=np.float64)
            pairs = list(zip(active, dt, strict=True))
            pred_xy = np.stack([last_xy[t] + vel_xy[t] * d for t, d in pairs])
            pred_ok = np.stack([last_ok[t] for t in active])
            pred_box = np.stack([last_box[t] + np.tile(vel_box[t] * d, 2) for t, d in pairs])
            cost = link_cost(
                pred_xy, pred_ok, pred_box, kp[rows, :, :2], seen[rows], boxes[rows], max_dist
            )
            for a, d in zip(*linear_sum_assignment(cost), strict=True):
                if cost[a, d] >= _NO_LINK:
                    continue
                t, r, gap = active[a], rows[d], dt[a]
                both = last_ok[t] & seen[r]
                step = np.where(both[:, None], (kp[r, :, :2] - last_xy[t]) / gap, vel_xy[t])
                box_step = (_centre(boxes[r]) - _centre(last_box[t])) / gap
                keep = 0.5 if steps[t] else 0.0  # the first step sets the velocity outright
                vel_xy[t] = keep * vel_xy[t] + (1.0 - keep) * step
                vel_xy[t][~seen[r]] = 0.0
                vel_box[t] = keep * vel_box[t] + (1.0 - keep) * box_step
                steps[t] += 1
                last_xy[t] = np.where(seen[r][:, None], kp[r, :, :2], 0.0)
                last_ok[t], last_box[t], last_frame[t] = seen[r].copy(), boxes[r].copy(), f
                labels[r] = t
                matched.add(r)
        for r in rows:
            if r in matched:
                continue
            labels[r] = len(last_box)
            last_xy.append(np.where(seen[r][:, None], kp[r, :, :2], 0.0))
            last_ok.append(seen[r].copy())
            last_box.append(boxes[r].copy())
            last_frame.append(f)
            vel_xy.append(np.zeros((kp.shape[1], 2)))
            vel_box.append(np.zeros(2))
            steps.append(0)
    return labels


# ----------------------------------------------------------------------------- selection


def _label_stats(labels: np.ndarray, areas: np.ndarray) -> dict[int, tuple[int, float]]:
    stats: dict[int, tuple[int, float]] = {}
    for lab in np.unique(labels[labels >= 0]):
        sel = labels == lab
        stats[int(lab)] = (int(sel.sum()), float(areas[sel].mean()))
    return stats


def choose_label(
    labels: np.ndarray,
    areas: np.ndarray,
    select: Literal["area", "frames"] = "area",
    min_coverage: float = 0.5,
) -> int:
    """Pick the dancer's label: see rule 4 of the module docstring.

    ``labels`` and ``areas`` (pixels²) are per detection row; each label appears at most once
    per frame, so its row count is its number of detected frames.
    """
    stats = _label_stats(labels, areas)
    if not stats:
        raise InputError("no person with any detected joint in any frame")
    if select == "frames":
        return max(stats, key=lambda k: (stats[k][0], stats[k][1], -k))
    if select != "area":
        raise InputError(f"unknown selection rule {select!r}; use 'area' or 'frames'")
    most = max(n for n, _ in stats.values())
    eligible = [k for k, (n, _) in stats.items() if n >= min_coverage * most]
    return max(eligible, key=lambda k: (stats[k][1], stats[k][0], -k))


# ----------------------------------------------------------------------------- following


def _rows_by_frame(frame_of_row: np.ndarray, keep: np.ndarray, n_frames: int) -> np.ndarray:
    """(F,) row per frame among rows where ``keep`` (highest index wins ties; callers dedupe)."""
    out = np.full(n_frames, -1, dtype=np.int64)
    rows = np.flatnonzero(keep)
    out[frame_of_row[rows]] = rows
    return out


def _follow_ids(
    ids: np.ndarray,
    tracklets: np.ndarray,
    conf_mean: np.ndarray,
    frame_of_row: np.ndarray,
    chosen: int,
    n_frames: int,
) -> tuple[np.ndarray, list[int]]:
    """Rows of person id ``chosen`` per frame, and the frames where it switched body.

    The id switched body at frame f when its tracklet changes there and either the new tracklet
    was already running before f (the id moved onto someone else) or the old one is still
    detected at f (someone else carries on the old body). A tracklet that simply ends and a new
    one that starts (the person was lost longer than the tracker waits) is not a switch.
    """
    rows = np.full(n_frames, -1, dtype=np.int64)
    for r in np.flatnonzero((ids == chosen) & (tracklets >= 0)):
        f = frame_of_row[r]
        if rows[f] < 0 or conf_mean[r] > conf_mean[rows[f]]:  # duplicate id: keep the surer one
            rows[f] = r
    valid = np.flatnonzero(tracklets >= 0)
    first: dict[int, int] = {}
    for r in valid:
        first.setdefault(int(tracklets[r]), int(frame_of_row[r]))
    detected = {(int(tracklets[r]), int(frame_of_row[r])) for r in valid}
    switches: list[int] = []
    previous = -1
    for f in range(n_frames):
        if rows[f] < 0:
            continue
        t = int(tracklets[rows[f]])
        if previous >= 0 and t != previous and (first[t] < f or (previous, f) in detected):
            switches.append(f)
        previous = t
    return rows, switches


def _follow_tracklets(
    tracklets: np.ndarray,
    boxes: np.ndarray,
    frame_of_row: np.ndarray,
    chosen: int,
    n_frames: int,
    relink_gap: int,
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Follow ``chosen`` forward and backward, hopping to the next tracklet when it ends.

    The hop goes to the tracklet that starts within ``relink_gap`` frames after the end (or ends
    within it before the start, going backward) with the smallest frames-gap + centre distance
    in box diagonals. There is no distance limit: the hop is reported as an identity switch.
    """
    valid = tracklets >= 0
    first: dict[int, int] = {}
    last: dict[int, int] = {}
    for r in np.flatnonzero(valid):
        t, f = int(tracklets[r]), int(frame_of_row[r])
        first[t] = min(first.get(t, f), f)
        last[t] = max(last.get(t, f), f)
    per_frame = {t: _rows_by_frame(frame_of_row, tracklets == t, n_frames) for t in first}

    def hop(current: int, forward: bool) -> int | None:
        edge = last[current] if forward else first[current]
        box = boxes[per_frame[current][edge]]
        best: tuple[float, int] | None = None
        for t in first:
            start = first[t] if forward else last[t]
            gap = start - edge if forward else edge - start
            if t == current or gap <= 0 or gap > relink_gap:
                continue
            cand = boxes[per_frame[t][start]]
            scale = max(float(_diag(box)), 20.0)
            dist = float(np.linalg.norm(_centre(cand) - _centre(box)) / scale)
            key = (gap + dist, t)
            if best is None or key < best:
                best = key
        return None if best is None else best[1]

    rows = np.full(n_frames, -1, dtype=np.int64)
    label = np.full(n_frames, -1, dtype=np.int64)
    switches: list[int] = []
    for forward in (True, False):
        current = chosen
        while True:
            lo, hi = first[current], last[current]
            span = per_frame[current][lo : hi + 1]
            take = (span >= 0) & (rows[lo : hi + 1] < 0)
            rows[lo : hi + 1][take] = span[take]
            label[lo : hi + 1][take] = current
            nxt = hop(current, forward)
            if nxt is None:
                break
            switches.append(first[nxt] if forward else lo)
            current = nxt
    return rows, label, sorted(switches)


def track_dancer(
    keypoints: np.ndarray,
    person_ids: np.ndarray,
    frame_offsets: np.ndarray,
    person: int | None = None,
    by: Literal["auto", "person_id", "bbox"] = "auto",
    select: Literal["area", "frames"] = "area",
    min_conf: float = 0.0,
    max_lost: int = 10,
    max_dist: float = 0.5,
    relink_gap: int = 25,
    min_coverage: float = 0.5,
) -> TrackedPose:
    """Follow one dancer through ragged per-frame detections (module docstring: the rules).

    Args:
        keypoints: (P, J, 3) x, y (pixels), confidence; all people of all frames concatenated.
        person_ids: (P,) OpenPose person ids, -1 when untracked.
        frame_offsets: (F + 1,) people of frame f are rows ``frame_offsets[f]:frame_offsets[f+1]``.
        person: override the choice: a person id (``method="person_id"``) or a tracklet number
            (``method="bbox"``; tracklets are numbered by first appearance, left to right).
        by: identity source; "auto" uses person ids when every detection has one (≥ 0).
        select: default choice rule, "area" (largest mean box area) or "frames" (most detected).
        min_conf: joints with confidence ≤ this count as undetected.
        max_lost: frames a tracklet may be unseen and continue.
        max_dist: link gate in box diagonals.
        relink_gap: with ``bbox``, the most frames between a lost tracklet and a re-link.
        min_coverage: with ``select="area"``, the fraction of the most-detected label's frame
            count a label needs to be eligible.
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    ids = np.asarray(person_ids, dtype=np.int64)
    offsets = np.asarray(frame_offsets, dtype=np.int64)
    n_frames = len(offsets) - 1
    n_joints = kp.shape[1]
    frame_of_row = np.repeat(np.arange(n_frames, dtype=np.int64), np.diff(offsets))
    boxes = bounding_boxes(kp, min_conf)
    has_box = np.isfinite(boxes).all(axis=1)
    if not has_box.any():
        raise InputError("no person with any detected joint in any frame")
    areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    tracklets = track_people(kp, offsets, min_conf=min_conf, max_lost=max_lost, max_dist=max_dist)

    if by == "auto":
        by = "person_id" if (ids[has_box] >= 0).all() else "bbox"
    if by not in ("person_id", "bbox"):
        raise InputError(f"unknown identity source {by!r}; use 'auto', 'person_id' or 'bbox'")
    labels = np.where(has_box, ids if by == "person_id" else tracklets, -1)
    if by == "person_id" and not (ids[has_box] >= 0).any():
        raise InputError("no person ids in the input (all -1); track by 'bbox' instead")

    known = set(int(v) for v in np.unique(labels[labels >= 0]))
    if person is not None:
        if int(person) not in known:
            kind = "person id" if by == "person_id" else "tracklet"
            raise InputError(f"{kind} {person} not found; present: {sorted(known)}")
        chosen, selection = int(person), "override"
    else:
        chosen, selection = choose_label(labels, areas, select, min_coverage), select

    conf_rows = np.where(kp[..., 2] > min_conf, kp[..., 2], 0.0)
    if by == "person_id":
        rows, switches = _follow_ids(
            labels, tracklets, conf_rows.mean(axis=1), frame_of_row, chosen, n_frames
        )
        label = np.where(rows >= 0, chosen, -1)
    else:
        rows, label, switches = _follow_tracklets(
            tracklets, boxes, frame_of_row, chosen, n_frames, relink_gap
        )

    coords = np.full((n_frames, n_joints, 2), np.nan, dtype=np.float32)
    conf = np.zeros((n_frames, n_joints), dtype=np.float32)
    have = rows >= 0
    sel = kp[rows[have]]
    joint_ok = (sel[..., 2] > min_conf) & np.isfinite(sel[..., :2]).all(axis=-1)
    coords[have] = np.where(joint_ok[..., None], sel[..., :2], np.nan)
    conf[have] = np.where(joint_ok, sel[..., 2], 0.0)
    mask = np.asarray(np.isfinite(coords).all(axis=-1))
    return TrackedPose(
        coords=coords,
        conf=conf,
        mask=mask,
        filled=np.zeros_like(mask),
        source_row=rows,
        label=label,
        method=by,
        chosen=chosen,
        selection=selection,
        identity_switches=tuple(int(s) for s in switches),
        n_labels=len(known),
    )


def track_openpose(frames, **kwargs) -> TrackedPose:
    """:func:`track_dancer` on an :class:`~dancedata.io.openpose.OpenPoseFrames`; errors name
    its folder."""
    try:
        return track_dancer(frames.keypoints, frames.person_ids, frames.frame_offsets, **kwargs)
    except InputError as exc:
        if exc.path is None:
            raise InputError(exc.problem, frames.folder) from None
        raise


# ----------------------------------------------------------------------------- gap filling


def fill_gaps(
    coords: np.ndarray, mask: np.ndarray, max_gap: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linearly interpolate each joint across runs of ≤ ``max_gap`` missing frames.

    Args:
        coords: (F, J, D) values (pixels or metres), anything where ``mask`` is False.
        mask: (F, J) True where known.
        max_gap: longest run of missing frames to fill; longer runs, and runs at the start or
            end (no value on one side), stay missing.

    Returns:
        (coords, mask, filled): copies with filled values; ``filled`` marks the new ones.
    """
    values = np.array(coords, dtype=np.float64, copy=True)
    known = np.asarray(mask, dtype=bool)
    filled = np.zeros_like(known)
    if max_gap < 1:
        return values.astype(np.asarray(coords).dtype), known.copy(), filled
    n_frames = values.shape[0]
    frames = np.arange(n_frames)
    for j in range(known.shape[1]):
        idx = np.flatnonzero(known[:, j])
        if idx.size < 2:
            continue
        gaps = np.diff(idx) - 1
        for k in np.flatnonzero((gaps >= 1) & (gaps <= max_gap)):
            a, b = idx[k], idx[k + 1]
            w = ((frames[a + 1 : b] - a) / (b - a))[:, None]
            values[a + 1 : b, j] = (1 - w) * values[a, j] + w * values[b, j]
            filled[a + 1 : b, j] = True
    out = values.astype(np.asarray(coords).dtype)
    return out, known | filled, filled


def fill_tracked_gaps(pose: TrackedPose, max_gap: int) -> TrackedPose:
    """:func:`fill_gaps` applied to a :class:`TrackedPose` (confidence of filled joints stays 0)."""
    coords, mask, filled = fill_gaps(pose.coords, pose.mask, max_gap)
    return TrackedPose(
        coords=coords,
        conf=pose.conf,
        mask=mask,
        filled=pose.filled | filled,
        source_row=pose.source_row,
        label=pose.label,
        method=pose.method,
        chosen=pose.chosen,
        selection=pose.selection,
        identity_switches=pose.identity_switches,
        n_labels=pose.n_labels,
    )
