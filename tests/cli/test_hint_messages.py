"""Hints that lead the right way (issue 23, item 1): each message by its exact text, and the
misleading hint it replaced is gone. Real stores, real BVH files, the real CLI."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dancedata.compute.bvh_units import LengthUnit, best_convention, size_warning
from tests.helpers import run_cli


def _error_line(proc) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


# ----------------------------------------------------------------------------- BVH units


def test_best_convention_is_the_most_plausible_of_the_usual_ones() -> None:
    # 25.49 file units (CMU 01_01): CMU's 0.056444 gives 1.44 m, inches 0.647 m, dm 2.55 m
    assert best_convention(25.49)[0] == "0.056444"
    assert best_convention(55.73)[0] == "in"  # PyMO's walk: 1.42 m in inches
    assert best_convention(176.1)[0] == "cm"
    assert best_convention(1.7)[0] == "m" and best_convention(1700.0)[0] == "mm"
    assert best_convention(1.7, exclude=1.0) is None  # only metres fits, and it is excluded
    assert best_convention(0.0) is None and best_convention(1e9) is None
    # inside the usual 1-2.5 m: no warning; outside it (inside the hard bounds): a warning
    assert size_warning(1.7, LengthUnit("cm", 0.01)) is None
    assert size_warning(0.5573, LengthUnit("cm", 0.01)) == (
        "the body measures 0.557 m with --units cm, small for a person (usually 1-2.5 m): "
        "if that is wrong, --units in (inches) makes it 1.42 m"
    )


@pytest.mark.slow
@pytest.mark.real_data
def test_cmu_file_in_cm_suggests_the_cmu_convention(real_data: Path, tmp_path: Path) -> None:
    path = real_data / "bvh" / "01_01.bvh"
    line = _error_line(
        run_cli("ingest", "bvh", str(path), "--store", str(tmp_path / "s"), "--units", "cm",
                "-q", check=False)
    )  # fmt: skip
    assert line == (
        f"error: {path}: the body measures 25.49 file units = 0.255 m with --units cm, outside "
        "a plausible 0.3-3 m: of the usual conventions, --units 0.056444 (CMU cgspeed BVH, "
        "1/0.45 in) makes it 1.44 m; or pass metres per file unit as a number; --no-size-check "
        "skips this check"
    )
    assert "--units dm" not in line and "--units in" not in line


@pytest.mark.slow
@pytest.mark.real_data
def test_inch_walk_under_cm_warns_and_info_shows_the_rig(real_data: Path, tmp_path: Path) -> None:
    path = real_data / "bvh" / "AV_8Walk_Meredith_HVHA_Rep1.bvh"
    store = tmp_path / "s"
    proc = run_cli("ingest", "bvh", str(path), "--store", str(store), "-q")
    assert proc.stderr.splitlines() == [
        f"warning: {path}: the body measures 0.557 m with --units cm, small for a person "
        "(usually 1-2.5 m): if that is wrong, --units in (inches) makes it 1.42 m"
    ]
    info = run_cli("info", str(store)).stdout.splitlines()
    assert (
        "rig       0.56 m (body size: the largest side of a frame's bounding box); unusual for "
        "a person (1-2.5 m): check --units"
    ) in info
    assert "music     missing for 1 sequence" in info
    summary = json.loads(run_cli("info", str(store), "--json").stdout)
    assert summary["rig_size_m"]["sequences"] == 1
    assert summary["rig_size_m"]["min"] == pytest.approx(0.5573, abs=1e-3)
    # in inches: a usual size, no warning, and info shows it plainly
    good = tmp_path / "good"
    proc = run_cli("ingest", "bvh", str(path), "--store", str(good), "--units", "in", "-q")
    assert proc.stderr == ""
    info = run_cli("info", str(good)).stdout.splitlines()
    assert "rig       1.42 m (body size: the largest side of a frame's bounding box)" in info


# ----------------------------------------------------------------------------- store messages


@pytest.fixture(scope="module")
def aist_store(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("hints")
    run_cli("synth", "aist", str(root / "raw"), "--sequences", "2", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "store"), "-q")
    run_cli("featurize", str(root / "store"), "--stems", "none", "--no-audio", "-q")
    return root / "store"


@pytest.mark.slow
def test_unknown_sequence_lists_close_ids_in_render_and_plot(aist_store: Path, tmp_path) -> None:
    import dancedata

    ids = dancedata.open_store(aist_store).seq_ids()
    wrong = ids[0][:-1] + "9"  # one character off
    for command, out in (("render", "r.mp4"), ("plot", "p.png")):
        line = _error_line(
            run_cli(command, str(aist_store), wrong, str(tmp_path / out), check=False)
        )
        assert line.startswith(f"error: {aist_store}: no sequence '{wrong}' in version v2 (")
        assert line.endswith(f"(2 sequences; closest: {ids[0]}, {ids[1]})") or line.endswith(
            f"(2 sequences; closest: {ids[0]})"
        ), line
    line = _error_line(run_cli("plot", str(aist_store), "nope", str(tmp_path / "p.png"),
                               check=False))  # fmt: skip
    assert line == (
        f"error: {aist_store}: no sequence 'nope' in version v2 (2 sequences: {ids[0]}, {ids[1]})"
    )


@pytest.mark.slow
def test_array_name_off_by_a_letter_names_the_right_one(aist_store: Path) -> None:
    import dancedata
    from dancedata.errors import StoreError

    store = dancedata.open_store(aist_store)
    seq = store.seq_ids()[0]
    with pytest.raises(StoreError) as err:
        store.motion(seq, "rotmats")
    assert str(err.value).endswith(
        "version v2 has no array 'motion/rotmats' (did you mean 'motion/rotmat'?)"
    )
    assert "run featurize" not in str(err.value)
    with pytest.raises(StoreError, match=r"has no array 'motion/zzz' \(run featurize\?\)"):
        store.motion(seq, "zzz")


def test_missing_path_and_folder_that_is_not_a_store_differ(tmp_path: Path) -> None:
    missing, folder = tmp_path / "nowhere", tmp_path / "folder"
    folder.mkdir()
    assert _error_line(run_cli("info", str(missing), check=False)) == (
        f"error: {missing}: not a dancedata store (no such directory)"
    )
    assert _error_line(run_cli("info", str(folder), check=False)) == (
        f"error: {folder}: not a dancedata store (the directory has no store.json)"
    )


@pytest.mark.slow
@pytest.mark.real_data
def test_plot_of_a_sequence_without_music_says_so(real_data: Path, tmp_path: Path) -> None:
    """A featurized BVH store without music: the onset panel says there is no music instead of
    asking to run featurize (which ran)."""
    pytest.importorskip("matplotlib")
    from dancedata.viz.plot import sequence_figure

    store = tmp_path / "s"
    bvh = real_data / "bvh" / "01_01.bvh"
    run_cli("ingest", "bvh", str(bvh), "--store", str(store), "--units", "0.056444", "-q")
    run_cli("featurize", str(store), "-q")
    fig = sequence_figure(store, "01_01")
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert "no music for this sequence: no onset envelope" in texts
    assert not any("featurize" in t for t in texts), texts


# ----------------------------------------------------------------------------- missing music


def test_video_without_an_audio_track_says_no_music_was_stored(tmp_path: Path) -> None:
    pytest.importorskip("av")
    from tests.ingest.test_ingest_video import generated

    video, poses = generated(tmp_path, 30.0, 40)
    store = tmp_path / "s"
    proc = run_cli("ingest", "video", str(video), "--poses", str(poses), "--store", str(store),
                   "-q")  # fmt: skip
    assert proc.stderr.splitlines() == [
        f"warning: {video}: the video has no audio track, so no music is stored for it "
        "(--music FILE gives it music)"
    ]
    assert proc.stdout.strip() == "ingest video: wrote version v1"


@pytest.mark.slow
def test_allow_missing_music_reads_no_music_headers(tmp_path: Path) -> None:
    import shutil

    raw = tmp_path / "raw"
    run_cli("synth", "aist", str(raw), "--sequences", "2", "--seed", "0", "-q")
    shutil.rmtree(raw / "wav")
    proc = run_cli("ingest", "aist", str(raw), "--store", str(tmp_path / "s"),
                   "--allow-missing-music")  # fmt: skip
    assert "read music headers" not in proc.stderr, proc.stderr
    assert "checksums: " in proc.stderr  # the other steps still report
