"""dancedata plot / dancedata.viz.plot: what is drawn is where the store says it is.

Expected positions are read straight from the parquet tables and zarr arrays (pyarrow, zarr),
not through the loader the figure uses, and compared with the figure's own artists."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest
import zarr

from tests.helpers import importorskip_unless_ci, run_cli
from tests.viz_helpers import write_keyframes_table

importorskip_unless_ci("matplotlib")

from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from dancedata.viz.plot import sequence_figure  # noqa: E402
from dancedata.viz.plot_data import gather, peak_envelope  # noqa: E402

# slow: plots of the session's featurized store (offline stems, NMFD: built once, ~1 min)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def store(small_featurized_store):
    return small_featurized_store


def _raw(store, version="v3"):
    """Tables and the zarr group of a version, read without dancedata."""
    vdir = store / "versions" / version
    seqs = {r["seq_id"]: r for r in pq.read_table(vdir / "sequences.parquet").to_pylist()}
    music = {r["music_id"]: r for r in pq.read_table(vdir / "music.parquet").to_pylist()}
    return vdir, seqs, music, zarr.open_group(str(vdir / "data.zarr"), mode="r")


def _audio_rows(seq, music, group, name):
    track = music[seq["music_id"]]
    a0 = track["frame_start"] + seq["audio_offset"]
    n = min(seq["n_frames"], track["frame_stop"] - a0)
    return np.asarray(group[name][a0 : a0 + n])


def _vline_x(fig: Figure, gid: str) -> list[np.ndarray]:
    """x of every vertical line with ``gid``, one array per axes that has them."""
    found = []
    for ax in fig.axes:
        for coll in ax.collections:
            if isinstance(coll, LineCollection) and coll.get_gid() == gid:
                segments = coll.get_segments()
                xs = np.array([s[0, 0] for s in segments])
                assert all(np.isclose(s[0, 0], s[1, 0]) for s in segments)  # vertical
                found.append(xs)
    return found


def test_measure_and_beat_lines_are_at_the_stored_frames(store):
    vdir, seqs, music, group = _raw(store)
    measures = pq.read_table(vdir / "measures.parquet").to_pylist()
    for seq_id, seq in seqs.items():
        fps = seq["fps"]
        fig = sequence_figure(store, seq_id)
        rows = [m for m in measures if m["seq_id"] == seq_id]
        assert rows, "the fixture store must have measures"
        expected = sorted({m["frame_start"] for m in rows} | {m["frame_stop"] for m in rows})
        measure_lines = _vline_x(fig, "measures")
        assert len(measure_lines) == len(fig.axes) == 5  # every panel
        for xs in measure_lines:
            np.testing.assert_array_equal(np.round(xs * fps).astype(int), expected)
            np.testing.assert_allclose(xs, np.array(expected) / fps, rtol=0, atol=1e-12)
            # and the seconds agree with the measures table's own time column
            starts = {round(m["frame_start"] / fps, 9): m["time_start"] for m in rows}
            for x in xs:
                if round(x, 9) in starts:
                    assert x == pytest.approx(starts[round(x, 9)], abs=1e-9)
        beats = np.flatnonzero(_audio_rows(seq, music, group, "audio/beats"))
        assert beats.size > 3
        beat_lines = _vline_x(fig, "beats")
        assert len(beat_lines) == 2  # waveform and onset panels
        for xs in beat_lines:
            np.testing.assert_allclose(xs, beats / fps, rtol=0, atol=1e-12)


def test_curves_and_peaks_are_the_stored_arrays(store):
    vdir, seqs, music, group = _raw(store)
    seq_id, seq = next(iter(seqs.items()))
    fps = seq["fps"]
    fig = sequence_figure(store, seq_id)
    onset = _audio_rows(seq, music, group, "audio/onset_env")
    lines = [ln for ax in fig.axes for ln in ax.lines]
    onset_line = [ln for ln in lines if ln.get_label() == "onset envelope"]
    assert len(onset_line) == 1
    np.testing.assert_array_equal(onset_line[0].get_ydata(), onset)
    np.testing.assert_allclose(onset_line[0].get_xdata(), np.arange(onset.size) / fps)
    peaks = np.flatnonzero(_audio_rows(seq, music, group, "audio/onset_peaks"))
    (marks,) = [ln for ln in lines if ln.get_gid() == "onset_peaks"]
    np.testing.assert_allclose(marks.get_xdata(), peaks / fps)
    np.testing.assert_array_equal(marks.get_ydata(), onset[peaks])
    # NMFD panel: three curves, each the stored column over its own maximum (offset by c)
    acts = _audio_rows(seq, music, group, "audio/nmfd_drums")
    for c, name in enumerate(("kick", "snare", "hihat")):
        (line,) = [ln for ln in lines if ln.get_label() == name]
        np.testing.assert_allclose(line.get_ydata(), acts[:, c] / acts[:, c].max() + c, rtol=1e-6)


def test_waveform_is_the_decoded_music_over_the_sequence_span(store):
    import soundfile as sf

    _, seqs, music, _ = _raw(store)
    seq_id, seq = list(seqs.items())[1]
    track = music[seq["music_id"]]
    y, sr = sf.read(track["path"], dtype="float32")
    y = y if y.ndim == 1 else y.mean(axis=1)
    start = round(seq["audio_offset"] / seq["fps"] * sr)
    span = y[start : start + round(seq["n_frames"] / seq["fps"] * sr)]
    data = gather(store, seq_id, waveform_bins=500)
    assert data.waveform is not None and data.waveform.sr == sr
    edges = np.linspace(0, span.size, 501).astype(int)
    lo = np.array([span[a:b].min() for a, b in zip(edges[:-1], edges[1:], strict=True)])
    hi = np.array([span[a:b].max() for a, b in zip(edges[:-1], edges[1:], strict=True)])
    np.testing.assert_allclose(data.waveform.lo, lo, atol=1e-6)
    np.testing.assert_allclose(data.waveform.hi, hi, atol=1e-6)
    assert data.waveform.times[-1] < seq["n_frames"] / seq["fps"]


def test_peak_envelope_brute_force():
    rng = np.random.default_rng(3)
    y = rng.standard_normal(1003).astype(np.float32)
    times, lo, hi = peak_envelope(y, 100.0, 7)
    edges = np.linspace(0, 1003, 8).astype(int)
    for k in range(7):
        assert lo[k] == y[edges[k] : edges[k + 1]].min()
        assert hi[k] == y[edges[k] : edges[k + 1]].max()
        assert times[k] == pytest.approx((edges[k] + edges[k + 1]) / 2 / 100.0)


def test_keyframes_panel_draws_each_strategy_at_its_frames(store, tmp_path):
    # Without a keyframes table there is no keyframe panel, quietly.
    fig = sequence_figure(store, next(iter(_raw(store)[1])))
    assert not any(str(ln.get_gid()).startswith("keyframes") for ax in fig.axes for ln in ax.lines)
    # A copy of the store whose latest version has a keyframes table (docs/EXPERIMENTS.md §2.5).
    copy = tmp_path / "store"
    shutil.copytree(store, copy)
    vdir, seqs, _, _ = _raw(copy)
    rows = write_keyframes_table(vdir)
    seq_id, seq = next(iter(seqs.items()))
    fig = sequence_figure(copy, seq_id)
    drawn = {
        ln.get_gid(): ln.get_xdata()
        for ax in fig.axes
        for ln in ax.lines
        if str(ln.get_gid()).startswith("keyframes:")
    }
    assert set(drawn) == {"keyframes:even N=3", "keyframes:peaks:onset N=5"}
    for gid, strategy in (
        ("keyframes:even N=3", "even"),
        ("keyframes:peaks:onset N=5", "peaks:onset"),
    ):
        frames = sorted(
            {
                r["frame_in_sequence"]
                for r in rows
                if r["seq_id"] == seq_id and r["strategy"] == strategy
            }
        )
        np.testing.assert_allclose(drawn[gid], np.array(frames) / seq["fps"])


def test_joint_angles_are_the_stored_euler_in_degrees(store):
    vdir, seqs, _, group = _raw(store)
    seq_id, seq = next(iter(seqs.items()))
    fig = sequence_figure(store, seq_id, joints=("left_knee",))
    euler = np.asarray(group["motion/euler"][seq["frame_start"] : seq["frame_stop"]])
    joints = json.loads((vdir / "data.zarr" / "motion" / "zarr.json").read_text())
    names = joints["attributes"]["skeleton"]["joints"]
    j = names.index("left_knee")
    for axis, letter in enumerate("XYZ"):
        (line,) = [
            ln for ax in fig.axes for ln in ax.lines if ln.get_label() == f"left_knee {letter}"
        ]
        np.testing.assert_allclose(line.get_ydata(), np.degrees(euler[:, j, axis]), rtol=1e-6)


def test_cli_writes_png_svg_pdf_and_rejects_bad_input(store, tmp_path):
    from dancedata.viz.plot import save_figure

    seq_id = next(iter(_raw(store)[1]))
    proc = run_cli("plot", str(store), seq_id, str(tmp_path / "fig.png"))
    assert "wrote" in proc.stdout
    fig = sequence_figure(store, seq_id)
    for suffix in ("svg", "pdf"):
        save_figure(fig, tmp_path / f"fig.{suffix}")
    magic = {"png": b"\x89PNG\r\n", "svg": b"<?xml", "pdf": b"%PDF"}
    for suffix, head in magic.items():
        out = tmp_path / f"fig.{suffix}"
        assert out.read_bytes().startswith(head) and out.stat().st_size > 10_000
    assert seq_id in (tmp_path / "fig.svg").read_text()  # a real figure: it holds the title
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left behind
    bad = run_cli("plot", str(store), seq_id, str(tmp_path / "fig.gif"), check=False)
    assert bad.returncode == 1 and "unknown figure format" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and not (tmp_path / "fig.gif").exists()
    missing = run_cli("plot", str(store), "nope", str(tmp_path / "x.png"), check=False)
    assert missing.returncode == 1 and "no sequence 'nope'" in missing.stderr
    assert "Traceback" not in missing.stderr and not (tmp_path / "x.png").exists()


def test_older_version_without_features_still_plots(store, tmp_path):
    """v1 (ingest only): no audio features, measures or Euler angles; the figure says what is
    missing, and draws interior knee/elbow angles from motion/keypoints3d instead, checked
    against the law of cosines."""
    vdir, seqs, _, _ = _raw(store, "v1")
    seq_id, seq = next(iter(seqs.items()))
    data = gather(store, seq_id, version="v1")
    assert data.onset_env is None and data.measure_bounds is None and not data.joint_angles_deg
    assert any("featurize" in n for n in data.notes) and any("segment" in n for n in data.notes)
    assert data.interior_source == "motion/keypoints3d"
    group = zarr.open_group(str(vdir / "data.zarr"), mode="r")
    kp = np.asarray(group["motion/keypoints3d"][seq["frame_start"] : seq["frame_stop"]], float)
    names = dict(group["motion/keypoints3d"].attrs)["skeleton"]["joints"]
    for joint, (hip, ankle) in {
        "left_knee": ("left_hip", "left_ankle"),
        "right_elbow": ("right_shoulder", "right_wrist"),
    }.items():
        a, b, c = (kp[:, names.index(n)] for n in (hip, joint, ankle))
        ab, bc, ac = (np.linalg.norm(x - y, axis=1) for x, y in ((a, b), (b, c), (a, c)))
        expected = np.degrees(np.arccos((ab**2 + bc**2 - ac**2) / (2 * ab * bc)))
        np.testing.assert_allclose(data.interior_angles_deg[joint], expected, atol=1e-6)
        assert np.isnan(expected).any()  # the NaN frames of the twin stay NaN
    out = tmp_path / "v1.png"
    run_cli("plot", str(store), seq_id, str(out), "--version", "v1")
    assert out.stat().st_size > 5_000


def test_interior_angles_closed_form():
    from dancedata.viz.joint_angles import hinge_triples, interior_angles_deg

    pts = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 0], [2, 0]], [[0, 0], [0, 0], [1, 1]]])
    angles = interior_angles_deg(pts, [(0, 1, 2)])[:, 0]
    assert angles[0] == pytest.approx(90.0) and angles[1] == pytest.approx(180.0)
    assert np.isnan(angles[2])  # zero-length bone
    joints = ["hip", "LKnee", "ankle", "toe", "Elbow"]
    assert hinge_triples(joints, [-1, 0, 1, 2, -1]) == [("LKnee", 0, 1, 2)]


def test_no_interactive_backend_and_no_pyplot(store):
    """Even with MPLBACKEND naming a GUI backend, the figure never loads pyplot or a GUI
    toolkit: it lives on a plain canvas and saves through Agg."""
    import os

    code = (
        "import sys, io\n"
        "from dancedata.viz.plot import sequence_figure\n"
        f"fig = sequence_figure({str(store)!r}, {next(iter(_raw(store)[1]))!r})\n"
        "fig.savefig(io.BytesIO(), format='png')\n"
        "print('matplotlib.pyplot' in sys.modules, 'tkinter' in sys.modules,"
        " type(fig.canvas).__name__)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
        env={**os.environ, "MPLBACKEND": "TkAgg"},
    )
    assert proc.stdout.split() == ["False", "False", "FigureCanvasBase"]


def test_frame_range_zooms_the_shared_axis(store):
    from dancedata.errors import InputError

    seq_id, seq = next(iter(_raw(store)[1].items()))
    fig = sequence_figure(store, seq_id, start=100, stop=250)
    for ax in fig.axes:
        assert ax.get_xlim() == pytest.approx((100 / seq["fps"], 250 / seq["fps"]))
    for start, stop in ((250, 100), (0, seq["n_frames"] + 1), (-1, 10)):
        with pytest.raises(InputError, match="frame range"):
            sequence_figure(store, seq_id, start=start, stop=stop)
