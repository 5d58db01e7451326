"""Draw skeleton frames with OpenCV into numpy images (BGR uint8), fast enough for video.

A frame is laid out as: a header strip (:data:`HEADER_PX` pixels: sequence, time, measure and
beat, and a dot that lights on each tracked beat), one panel per sequence side by side, and a
timeline strip (:data:`TIMELINE_PX` pixels) at the bottom with a tick per measure boundary
(tall), per beat (short) and the play head. Bones join each joint to its parent; joints named
left (``left_*``, ``Left*``, ``L*``) are orange, right ones blue, others light grey.

Everything static (background, floor line, labels, the timeline ticks) is drawn once into a
background image; each frame copies it and draws the moving parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancedata.compute.smpl import COCO17_KEYPOINTS

__all__ = [
    "BACKGROUND",
    "EXTRA_BONES",
    "HEADER_PX",
    "TIMELINE_PX",
    "FrameLayout",
    "MusicTiming",
    "SkeletonStyle",
    "bone_pairs",
    "draw_skeleton",
    "joint_colours",
    "timing_at",
]

HEADER_PX = 28
TIMELINE_PX = 18
BACKGROUND = (32, 32, 32)  # BGR
FLOOR = (70, 70, 70)
TEXT = (235, 235, 235)
LEFT = (0, 150, 255)  # orange
RIGHT = (255, 170, 40)  # blue
CENTRE = (220, 220, 220)
BEAT_ON = (60, 220, 255)
MEASURE_TICK = (200, 200, 200)
BEAT_TICK = (120, 120, 120)
PLAYHEAD = (60, 60, 255)
FLASH_S = 0.12  # the beat dot stays lit this long after a beat


@dataclass(frozen=True)
class MusicTiming:
    """Measures and beats of one sequence, in frames of the sequence.

    Attributes:
        measure_starts, measure_stops: (M,) half-open frame ranges of the measures table.
        beat_frames: (B,) sorted frames where the tracked beats array is 1.
        beats_per_measure: from the segment config, or None.
    """

    measure_starts: np.ndarray
    measure_stops: np.ndarray
    beat_frames: np.ndarray
    beats_per_measure: int | None = None

    @classmethod
    def empty(cls) -> MusicTiming:
        none = np.zeros(0, dtype=np.int64)
        return cls(none, none, none, None)


def timing_at(timing: MusicTiming, frame: int) -> tuple[int, int, int | None]:
    """(measure index or -1, beat number within the measure (1-based, 0 before its first
    beat), frames since the last beat or None) at sequence frame ``frame``.

    The beat number counts the tracked beats in ``[measure start, frame]``."""
    m = int(np.searchsorted(timing.measure_starts, frame, side="right")) - 1
    if m >= 0 and frame >= timing.measure_stops[m]:
        m = -1
    last = int(np.searchsorted(timing.beat_frames, frame, side="right"))
    since = frame - int(timing.beat_frames[last - 1]) if last > 0 else None
    beat = 0
    if m >= 0:
        first = int(np.searchsorted(timing.beat_frames, timing.measure_starts[m], side="left"))
        beat = max(0, last - first)
    return m, beat, since


def _side(name: str) -> int:
    """-1 left, +1 right, 0 centre, from a joint name."""
    lower = name.lower()
    if (
        lower.startswith("left")
        or lower.startswith("l_")
        or (len(name) > 1 and name[0] == "L" and name[1].isupper())
    ):
        return -1
    if (
        lower.startswith("right")
        or lower.startswith("r_")
        or (len(name) > 1 and name[0] == "R" and name[1].isupper())
    ):
        return 1
    return 0


def joint_colours(joints: tuple[str, ...], n_joints: int) -> list[tuple[int, int, int]]:
    """BGR colour of each joint (and of the bone to its parent) by side."""
    names = joints if len(joints) == n_joints else ("",) * n_joints
    palette = {-1: LEFT, 1: RIGHT, 0: CENTRE}
    out = []
    for name in names:
        base = name.split(":")[-1]  # namespaced rigs: mixamorig:LeftArm
        out.append(palette[_side(base)])
    return out


@dataclass(frozen=True)
class FrameLayout:
    """Pixel rectangles (x0, y0, width, height) of the panels in a width × height frame."""

    width: int
    height: int
    n_panels: int

    def panel(self, k: int) -> tuple[int, int, int, int]:
        """The k-th panel, header and timeline excluded."""
        w = self.width // self.n_panels
        return (k * w, HEADER_PX, w, self.height - HEADER_PX - TIMELINE_PX)

    def drawing_area(self, k: int) -> tuple[int, int, int, int]:
        """The k-th panel less a label line at its top."""
        x0, y0, w, h = self.panel(k)
        return (x0, y0 + 16, w, h - 16)


def put_text(image: np.ndarray, text: str, origin: tuple[int, int], scale: float = 0.45) -> None:
    import cv2

    cv2.putText(image, text, origin, cv2.FONT_HERSHEY_SIMPLEX, scale, TEXT, 1, cv2.LINE_AA)


def draw_background(
    layout: FrameLayout,
    labels: list[str],
    floors: list[float | None],
    timing: MusicTiming,
    n_frames: int,
    frame_offset: int,
) -> np.ndarray:
    """The static image: panels with their labels and floor lines, the timeline ticks.

    ``floors``: per panel, the pixel row of the floor (None: no floor). The timeline spans the
    rendered frames ``[frame_offset, frame_offset + n_frames)`` of the sequence."""
    import cv2

    image = np.empty((layout.height, layout.width, 3), np.uint8)
    image[:] = BACKGROUND
    for k, (label, floor) in enumerate(zip(labels, floors, strict=True)):
        x0, y0, w, h = layout.panel(k)
        if k > 0:
            cv2.line(image, (x0, y0), (x0, y0 + h), FLOOR, 1)
        if floor is not None and y0 < floor < y0 + h:
            cv2.line(image, (x0 + 4, int(round(floor))), (x0 + w - 5, int(round(floor))), FLOOR, 1)
        put_text(image, label[: max(8, w // 8)], (x0 + 6, y0 + 12), 0.38)
    top = layout.height - TIMELINE_PX
    image[top:] = (20, 20, 20)
    scale = layout.width / max(n_frames, 1)
    for frames, colour, inset in (
        (timing.beat_frames, BEAT_TICK, 9),
        (np.concatenate([timing.measure_starts, timing.measure_stops[-1:]]), MEASURE_TICK, 2),
    ):
        for f in np.asarray(frames, dtype=np.int64):
            if frame_offset <= f <= frame_offset + n_frames:
                x = int(round((f - frame_offset) * scale))
                cv2.line(image, (x, top + inset), (x, layout.height - 2), colour, 1)
    return image


# Bones a kinematic tree leaves out but a viewer expects: COCO-17 parents both shoulders on the
# nose and each hip on its shoulder, so without these the torso has no shoulder or hip line.
EXTRA_BONES: dict[tuple[str, ...], tuple[tuple[int, int], ...]] = {
    COCO17_KEYPOINTS: ((5, 6), (11, 12)),  # left-right shoulder, left-right hip
}


@dataclass(frozen=True)
class SkeletonStyle:
    """What to draw for one skeleton, grouped by colour so that a frame is a few OpenCV calls.

    Attributes:
        bones: (B, 2) joint pairs: joint → parent, then :data:`EXTRA_BONES` of its skeleton.
        groups: per colour, (BGR colour, indices into ``bones``, joint indices of that colour).
    """

    bones: np.ndarray
    groups: tuple[tuple[tuple[int, int, int], np.ndarray, np.ndarray], ...]

    @classmethod
    def of(cls, parents: tuple[int, ...], joints: tuple[str, ...]) -> SkeletonStyle:
        """Bones and colours (:func:`joint_colours`) of a skeleton; an extra bone takes the
        centre colour."""
        n = len(parents)
        colours = joint_colours(joints, n)
        pairs = [(j, p) for j, p in enumerate(parents) if 0 <= p < n]
        bone_colours = [colours[j] for j, _ in pairs]
        for a, b in EXTRA_BONES.get(tuple(joints), ()):
            if max(a, b) < n:
                pairs.append((a, b))
                bone_colours.append(CENTRE)
        bones = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        groups = []
        for colour in dict.fromkeys([*bone_colours, *colours]):
            on_bones = np.array([i for i, c in enumerate(bone_colours) if c == colour], np.int64)
            on_joints = np.array([j for j, c in enumerate(colours) if c == colour], np.int64)
            groups.append((colour, on_bones, on_joints))
        return cls(bones, tuple(groups))


def bone_pairs(parents: tuple[int, ...], joints: tuple[str, ...]) -> np.ndarray:
    """(B, 2) joint pairs drawn as bones (:class:`SkeletonStyle`)."""
    return SkeletonStyle.of(parents, joints).bones


def draw_skeleton(
    image: np.ndarray,
    pixels: np.ndarray,
    style: SkeletonStyle,
    radius: int = 4,
    thickness: int = 2,
) -> None:
    """Bones and joint discs at ``pixels`` (J, 2); NaN joints and their bones are skipped.

    One ``cv2.polylines`` call per colour for the bones, and one per colour for the joints
    (a disc of ``radius`` is a zero-length anti-aliased line ``2 · radius`` thick)."""
    import cv2

    finite = np.isfinite(pixels).all(axis=1)
    points = np.zeros(pixels.shape[:1] + (2,), np.int32)
    points[finite] = np.rint(pixels[finite]).astype(np.int32)
    bones = style.bones
    drawn = finite[bones].all(axis=1) if bones.size else np.zeros(0, bool)
    for colour, on_bones, _ in style.groups:
        keep = on_bones[drawn[on_bones]] if on_bones.size else on_bones
        if keep.size:
            segments = points[bones[keep]]  # (n, 2, 2)
            cv2.polylines(image, list(segments), False, colour, thickness, cv2.LINE_AA)
    for colour, _, on_joints in style.groups:
        keep = on_joints[finite[on_joints]] if on_joints.size else on_joints
        if keep.size:
            dots = np.repeat(points[keep][:, None, :], 2, axis=1)  # (n, 2, 2): zero-length
            cv2.polylines(image, list(dots), False, colour, 2 * radius, cv2.LINE_AA)


def draw_header(
    image: np.ndarray,
    layout: FrameLayout,
    frame: int,
    n_total: int,
    fps: float,
    timing: MusicTiming,
    rendered_index: int,
    n_rendered: int,
) -> None:
    """Time, frame, measure and beat of sequence frame ``frame``, the beat dot, the play head."""
    import cv2

    measure, beat, since = timing_at(timing, frame)
    parts = [f"{frame / fps:6.2f} s", f"frame {frame}/{n_total}"]
    if timing.measure_starts.size:
        shown = f"{measure + 1}/{timing.measure_starts.size}" if measure >= 0 else "-"
        parts.append(f"measure {shown}")
    if timing.beat_frames.size:
        per = f"/{timing.beats_per_measure}" if timing.beats_per_measure else ""
        parts.append(f"beat {beat}{per}" if measure >= 0 and beat > 0 else "beat -")
    put_text(image, "   ".join(parts), (8, 19), 0.5)
    lit = since is not None and since <= FLASH_S * fps
    centre = (layout.width - 16, HEADER_PX // 2)
    cv2.circle(image, centre, 8, BEAT_ON if lit else FLOOR, -1, cv2.LINE_AA)
    x = int(round(rendered_index * layout.width / max(n_rendered, 1)))
    top = layout.height - TIMELINE_PX
    cv2.line(image, (x, top), (x, layout.height - 1), PLAYHEAD, 2)
