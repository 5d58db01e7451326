"""One figure per sequence: music, beats, measures, stems, NMFD, keyframes and joint angles.

    from dancedata.viz.plot import sequence_figure
    fig = sequence_figure("data/stores/aist-demo", "gBR_sBM_cAll_d01_mBR1_ch01")
    fig.savefig("seq.png")          # or .svg / .pdf

The figure is a bare :class:`matplotlib.figure.Figure` on the non-interactive Agg canvas: no
pyplot, no GUI backend, nothing global changed, so it works headless and in notebooks alike.

Every panel shares one x axis, **seconds from the sequence's first motion frame** (frame f at
f / fps s; the top axis shows motion frames). Vertical lines: measure boundaries (every
measure's first frame and the last one's end, from the ``measures`` table; grey, in every
panel; ``gid="measures"``) and tracked beats (``audio/beats``; red dashed, in the waveform and
onset panels; ``gid="beats"``). They are ``vlines`` LineCollections whose x data are exactly
frame / fps, so they can be read back from the figure.

Joint angles: the stored ``motion/euler`` of a few joints, in degrees, components labelled by
the stored axis order (principal branch, so ±180° wraps show as jumps). Stores without joint
rotations (video poses, an ingest-only AIST++ version) get the interior knee and elbow angles
from their positions instead (:mod:`dancedata.viz.joint_angles`). Panels whose data the version
lacks are left out, and the title says what is missing.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dancedata.read.loader import DanceStore
from dancedata.viz.extras import require
from dancedata.viz.plot_data import DEFAULT_JOINTS, SequencePlotData, gather

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

STEM_COLOURS = {"drums": "#d62728", "bass": "#1f77b4", "vocals": "#2ca02c", "other": "#9467bd"}
NMFD_COLOURS = ("#8c564b", "#e377c2", "#17becf")
JOINT_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")
AXIS_STYLES = ("-", "--", ":")
MEASURE_STYLE = {"colors": "0.45", "linewidths": 0.9, "zorder": 1}
BEAT_STYLE = {"colors": "#d62728", "linewidths": 0.7, "linestyles": "dashed", "zorder": 1}
SAVE_FORMATS = (".png", ".svg", ".pdf")


def _vlines(ax: Axes, frames: np.ndarray | None, data: SequencePlotData, gid: str, **style: Any):
    """Full-height vertical lines at ``frames`` / fps (y in axes units, so any panel)."""
    if frames is None or len(frames) == 0:
        return None
    x = data.seconds(frames)
    lines = ax.vlines(x, 0.0, 1.0, transform=ax.get_xaxis_transform(), **style)
    lines.set_gid(gid)
    return lines


def _normalised(curve: np.ndarray) -> np.ndarray:
    """curve / max(curve) (zeros stay zeros), so curves of different scales share a panel."""
    curve = np.nan_to_num(np.asarray(curve, np.float64))
    peak = float(np.max(np.abs(curve))) if curve.size else 0.0
    return curve / peak if peak > 0 else curve


def _note(ax: Axes, text: str) -> None:
    ax.text(
        0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=8, color="0.4"
    )


def _panel_waveform(ax: Axes, d: SequencePlotData) -> None:
    if d.waveform is None:
        _note(ax, "no waveform: " + "; ".join(n for n in d.notes if "music" in n or "wave" in n))
    else:
        w = d.waveform
        ax.fill_between(w.times, w.lo, w.hi, color="#4c72b0", linewidth=0, step="mid")
        peak = max(float(np.abs(w.lo).max(initial=0)), float(np.abs(w.hi).max(initial=0)), 1e-6)
        ax.set_ylim(-1.05 * peak, 1.05 * peak)
    ax.set_ylabel("music\n(amplitude)")
    _vlines(ax, d.beat_frames, d, "beats", **BEAT_STYLE)


def _panel_onset(ax: Axes, d: SequencePlotData) -> None:
    if d.onset_env is None:
        if not d.audio_frames:  # featurize has nothing to compute the envelope from
            _note(ax, "no music for this sequence: no onset envelope")
        else:
            _note(ax, "no audio/onset_env (run `dancedata featurize`)")
    else:
        t = d.seconds(np.arange(d.onset_env.shape[0]))
        ax.plot(t, d.onset_env, color="k", linewidth=0.8, label="onset envelope")
        if d.onset_peak_frames is not None and len(d.onset_peak_frames):
            (peaks,) = ax.plot(
                d.seconds(d.onset_peak_frames),
                d.onset_env[d.onset_peak_frames],
                "o",
                color="#ff7f0e",
                markersize=3,
                label="onset peaks",
            )
            peaks.set_gid("onset_peaks")
    beats = _vlines(ax, d.beat_frames, d, "beats", **BEAT_STYLE)
    if beats is not None:
        beats.set_label("tracked beats")
    ax.set_ylabel("onset\nstrength")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.02), fontsize=7, frameon=False)


def _panel_stems(ax: Axes, d: SequencePlotData) -> None:
    for i, (stem, curve) in enumerate(d.stems.items()):
        t = d.seconds(np.arange(curve.shape[0]))
        ax.plot(t, _normalised(curve) + i, color=STEM_COLOURS.get(stem, "k"), linewidth=0.7)
    ax.set_yticks(np.arange(len(d.stems)) + 0.5, list(d.stems))
    ax.set_ylim(-0.05, max(1, len(d.stems)) + 0.05)
    ax.set_ylabel("stem onsets\n(each / its max)")


def _panel_nmfd(ax: Axes, d: SequencePlotData) -> None:
    assert d.nmfd is not None
    t = d.seconds(np.arange(d.nmfd.shape[0]))
    for c, name in enumerate(d.nmfd_components):
        colour = NMFD_COLOURS[c % len(NMFD_COLOURS)]
        ax.plot(t, _normalised(d.nmfd[:, c]) + c, color=colour, linewidth=0.7, label=name)
    ax.set_yticks(np.arange(len(d.nmfd_components)) + 0.5, list(d.nmfd_components))
    ax.set_ylim(-0.05, len(d.nmfd_components) + 0.05)
    ax.set_ylabel("NMFD drums\n(each / its max)")


def _panel_keyframes(ax: Axes, d: SequencePlotData) -> None:
    for i, track in enumerate(d.keyframes):
        (marks,) = ax.plot(
            d.seconds(track.frames),
            np.full(len(track.frames), i),
            "|",
            markersize=9,
            markeredgewidth=1.5,
            color=JOINT_COLOURS[i % 6],
        )
        marks.set_gid(f"keyframes:{track.label}")
    ax.set_yticks(np.arange(len(d.keyframes)), [t.label for t in d.keyframes], fontsize=7)
    ax.set_ylim(-0.7, len(d.keyframes) - 0.3)
    ax.set_ylabel("keyframes")


def _panel_joints(ax: Axes, d: SequencePlotData) -> None:
    t = d.seconds(np.arange(d.n_frames))
    # Column k of a scipy Euler triple is the angle about the k-th axis of the order string.
    order = d.euler_order if len(d.euler_order) == 3 else ""
    for j, (joint, angles) in enumerate(d.joint_angles_deg.items()):
        colour = JOINT_COLOURS[j % len(JOINT_COLOURS)]
        for axis in range(angles.shape[1]):
            label = f"{joint} {order[axis]}" if order else f"{joint} [{axis}]"
            ax.plot(
                t[: angles.shape[0]],
                angles[:, axis],
                color=colour,
                linewidth=0.7,
                linestyle=AXIS_STYLES[axis % 3],
                label=label,
            )
    ax.set_ylabel(f"joint Euler angles\n(deg, {d.euler_order or '?'})")
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.02), fontsize=6, frameon=False)


def frame_window(n_frames: int, start: int | None, stop: int | None) -> tuple[int, int]:
    """[start, stop) motion frames to show, defaulting to the whole sequence; an empty or
    out-of-range window is an InputError."""
    from dancedata.errors import InputError

    first = 0 if start is None else int(start)
    last = n_frames if stop is None else int(stop)
    if not 0 <= first < last <= n_frames:
        raise InputError(
            f"frame range [{first}, {last}) is not inside the sequence's {n_frames} frames"
        )
    return first, last


def _panel_interior(ax: Axes, d: SequencePlotData) -> None:
    t = d.seconds(np.arange(d.n_frames))
    for j, (joint, angles) in enumerate(d.interior_angles_deg.items()):
        ax.plot(
            t[: angles.shape[0]],
            angles,
            color=JOINT_COLOURS[j % len(JOINT_COLOURS)],
            linewidth=0.8,
            label=joint,
        )
    ax.set_ylabel(f"interior joint\nangle (deg)\n{d.interior_source}")
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.02), fontsize=6, frameon=False)


def figure_from_data(
    d: SequencePlotData,
    *,
    width: float = 12.0,
    dpi: float = 100,
    start: int | None = None,
    stop: int | None = None,
) -> Figure:
    """Draw gathered :class:`SequencePlotData` (see the module docstring for what is where);
    ``start``/``stop`` (motion frames) zoom the shared x axis to [start, stop). Every string
    is drawn literally (:func:`literal_text`): names from a store are data, never mathtext."""
    require("matplotlib", "plotting")
    with literal_text():
        fig = _draw(d, width, dpi, start, stop)
    make_literal(fig)
    return fig


def literal_text() -> Any:
    """A context in which matplotlib creates text with mathtext parsing off
    (``text.parse_math``), so ``$\\foo$`` in a genre, joint or sequence name is drawn as
    written instead of raising a parse error. Tick labels are made when the figure is drawn,
    so saving runs in it too."""
    import matplotlib

    return matplotlib.rc_context({"text.parse_math": False})


def make_literal(fig: Any) -> None:
    """Turn mathtext parsing off on every text artist already in ``fig``."""
    from matplotlib.text import Text

    for text in fig.findobj(Text):
        text.set_parse_math(False)


def _draw(d: SequencePlotData, width: float, dpi: float, start: int | None,
          stop: int | None) -> Figure:  # fmt: skip
    from matplotlib.figure import Figure

    panels: list[tuple[Any, float]] = [(_panel_waveform, 1.0), (_panel_onset, 1.2)]
    if d.stems:
        panels.append((_panel_stems, 1.3))
    if d.nmfd is not None:
        panels.append((_panel_nmfd, 1.1))
    if d.keyframes:
        panels.append((_panel_keyframes, max(0.7, 0.28 * len(d.keyframes))))
    if d.joint_angles_deg:
        panels.append((_panel_joints, 1.4))
    elif d.interior_angles_deg:
        panels.append((_panel_interior, 1.2))
    heights = [h for _, h in panels]
    fig = Figure(figsize=(width, 1.0 + 1.25 * sum(heights)), dpi=dpi, layout="constrained")
    axes = fig.subplots(len(panels), 1, sharex=True, gridspec_kw={"height_ratios": heights})
    axes = np.atleast_1d(axes)
    duration = d.n_frames / d.fps
    first, last = frame_window(d.n_frames, start, stop)
    for ax, (draw, _) in zip(axes, panels, strict=True):
        draw(ax, d)
        _vlines(ax, d.measure_bounds, d, "measures", **MEASURE_STYLE)
        ax.set_xlim(first / d.fps, last / d.fps)
        ax.tick_params(labelsize=7)
        ax.yaxis.label.set_size(8)
    fps = d.fps
    top = axes[0].secondary_xaxis("top", functions=(lambda s: s * fps, lambda f: f / fps))
    top.set_xlabel(f"motion frame (at {fps:g} fps)", fontsize=8)
    top.tick_params(labelsize=7)
    axes[-1].set_xlabel(
        f"time in sequence (s) = motion frame / {fps:g} fps; grey lines: measure boundaries",
        fontsize=8,
    )
    meta = d.meta
    bpm = f"{meta['bpm']:g} BPM" if meta.get("bpm") else "no BPM"
    title = (
        f"{d.seq_id}  ·  {meta.get('genre') or '?'}  ·  {bpm}  ·  {d.n_frames} frames "
        f"({duration:.1f} s)  ·  version {d.version}"
    )
    missing = [n for n in d.notes if not n.startswith("waveform")]
    if missing:  # what the store lacks, under the title
        title += "\n" + "; ".join(missing)
    fig.suptitle(title, fontsize=9)
    return fig


def sequence_figure(
    store: DanceStore | str | Path,
    seq_id: str,
    *,
    version: str | None = None,
    joints: tuple[str, ...] = DEFAULT_JOINTS,
    width: float = 12.0,
    dpi: float = 100,
    start: int | None = None,
    stop: int | None = None,
) -> Figure:
    """The sequence's figure (matplotlib Figure, Agg canvas). ``store`` is a path or an open
    :class:`~dancedata.read.loader.DanceStore`; ``joints`` names the joints of the angle panel
    (skeleton names; the most-varying joints when none match); ``start``/``stop`` show only
    motion frames [start, stop)."""
    require("matplotlib", "plotting")
    return figure_from_data(
        gather(store, seq_id, version=version, joints=joints),
        width=width,
        dpi=dpi,
        start=start,
        stop=stop,
    )


def check_figure_path(out: str | Path) -> Path:
    """``out`` as a Path when its suffix is a known format and its folder exists, else an
    InputError naming it (checked before any drawing)."""
    from dancedata.errors import InputError

    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in SAVE_FORMATS:
        raise InputError(
            f"unknown figure format {suffix!r}; use one of {', '.join(SAVE_FORMATS)}", out
        )
    if not out.parent.is_dir():
        raise InputError("output folder does not exist", out.parent)
    return out


def save_figure(fig: Figure, out: str | Path) -> Path:
    """Save as PNG, SVG or PDF (by suffix), written to a temporary file then renamed, so a
    failed save leaves nothing half-written."""
    import os

    out = check_figure_path(out)
    suffix = out.suffix.lower()
    tmp = out.with_name(f".{out.name}.tmp{os.getpid()}{suffix}")
    try:
        make_literal(fig)
        with literal_text():
            fig.savefig(tmp, format=suffix[1:])
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out
