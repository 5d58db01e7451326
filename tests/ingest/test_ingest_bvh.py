"""``dancedata ingest bvh``: the five real rigs against independent references (per-channel
rotation matrices, a 4x4 FK chain), units and their sanity check, resampling, smoothing, one
skeleton per store, appending, and pairing with music (then featurize and segment)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from dancedata.errors import InputError
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.bvh import BvhIngestOptions, ingest_bvh
from dancedata.io.bvh import BvhClip, BvhSkeleton, read_bvh, write_bvh
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store
from tests.helpers import run_cli

# file → metres per file unit (CMU cgspeed uses 1/0.45 inch; PyMO's walk is in inches)
REAL = {
    "01_01": 0.056444,
    "AV_8Walk_Meredith_HVHA_Rep1": 0.0254,
    "freya_edit": 0.01,
    "test_freebvh": 0.01,
    "test_mocapbank": 0.01,
}


def elementary(axis: str, degrees: np.ndarray) -> np.ndarray:
    """(F, 3, 3) rotation about one axis, written out."""
    a = np.radians(degrees)
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    rows = {
        "X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return np.moveaxis(np.array(rows), -1, 0)


def reference(clip: BvhClip, metres: float) -> dict[str, np.ndarray]:
    """Local rotations and world positions (metres) by walking each joint's channels in file
    order and chaining 4x4 transforms."""
    skel, values = clip.skeleton, clip.values
    n = clip.n_frames
    local_rot = np.zeros((n, skel.n_joints, 3, 3))
    world = np.zeros((n, skel.n_joints, 4, 4))
    for j in range(skel.n_joints):
        rot = np.broadcast_to(np.eye(3), (n, 3, 3))
        offset = np.broadcast_to(skel.offsets[j], (n, 3)).copy()
        for k, channel in enumerate(skel.channels[j]):
            column = values[:, skel.channel_starts[j] + k]
            if channel.endswith("rotation"):
                rot = rot @ elementary(channel[0], column)
            else:
                offset[:, "XYZ".index(channel[0])] = column
        local_rot[:, j] = rot
        local = np.zeros((n, 4, 4))
        local[:, :3, :3], local[:, :3, 3], local[:, 3, 3] = rot, offset * metres, 1.0
        parent = skel.parents[j]
        world[:, j] = local if parent < 0 else world[:, parent] @ local
    return {"rotmats": local_rot, "positions": world[:, :, :3, 3]}


def ingest(store: Path, *paths: Path, **options):
    return ingest_bvh(store, list(paths), BvhIngestOptions(**options))


def arrays(store: Path, version: str | None = None) -> dict[str, np.ndarray]:
    reader = _VersionReader(store, version)
    return {
        name.split("/")[1]: np.asarray(reader.array(name)[:], dtype=np.float64)
        for name in reader.array_names()
        if name.startswith("motion/")
    }


def one_line_error(proc) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


def synthetic_bvh(path: Path, fps: float, euler_deg: np.ndarray, n_joints: int = 3) -> Path:
    """A chain of ``n_joints`` joints (ZXY channels, root with positions) 50 cm apart, every
    joint turning by ``euler_deg`` (F, 3) in ZXY order."""
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")]
    channels += [("Zrotation", "Xrotation", "Yrotation")] * (n_joints - 1)
    offsets = np.array([[0.0, 90.0, 0.0]] + [[0.0, 50.0, 0.0]] * (n_joints - 1))
    skel = BvhSkeleton(
        tuple(f"j{i}" for i in range(n_joints)),
        tuple(range(-1, n_joints - 1)),
        offsets,
        tuple(channels),
        end_sites=tuple([np.zeros((0, 3))] * (n_joints - 1) + [np.array([[0.0, 80.0, 0.0]])]),
    )
    n = euler_deg.shape[0]
    values = np.concatenate([np.tile([0.0, 90.0, 0.0], (n, 1))] + [euler_deg] * n_joints, axis=1)
    write_bvh(BvhClip(skel, 1.0 / fps, values), path)
    return path


# ----------------------------------------------------------------------------- real rigs


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.parametrize("name", sorted(REAL))
def test_real_rig_arrays_match_independent_references(
    real_data: Path, tmp_path: Path, name: str
) -> None:
    path = real_data / "bvh" / f"{name}.bvh"
    metres = REAL[name]
    store = tmp_path / "store"
    result = ingest(store, path, units=repr(metres))
    clip = read_bvh(path)
    skel = clip.skeleton
    ref = reference(clip, metres)
    got = arrays(store)
    reader = _VersionReader(store)
    attrs = reader.group_attrs("motion")

    # Skeleton attrs: everything export needs, lengths in metres.
    sk = attrs["skeleton"]
    assert sk["joints"] == list(skel.names) and sk["parents"] == list(skel.parents)
    np.testing.assert_allclose(sk["offsets"], skel.offsets * metres, atol=1e-12)
    assert sk["channels"] == [list(c) for c in skel.channels]
    for j, chans in enumerate(skel.channels):
        rotation_axes = "".join(c[0] for c in chans if c.endswith("rotation"))
        assert sk["euler_orders"][j].startswith(rotation_axes)
        assert len(sk["end_sites"][j]) == len(skel.end_sites[j])
    assert (
        attrs["euler_orders"] == sk["euler_orders"] == reader.array("motion/euler").attrs["order"]
    )
    assert attrs["fps"] == round(clip.fps) and attrs["source"] == "bvh"

    # euler: the file's angles (radians) in each joint's order; axis_angle: the same rotations.
    for j, chans in enumerate(skel.channels):
        for k, channel in enumerate(chans):
            if channel.endswith("rotation"):
                axis = sk["euler_orders"][j].index(channel[0])
                want = np.radians(clip.values[:, skel.channel_starts[j] + k])
                assert np.abs(got["euler"][:, j, axis] - want).max() < 5e-7
    rotations = Rotation.from_rotvec(got["axis_angle"].reshape(-1, 3))
    expected = Rotation.from_matrix(ref["rotmats"].reshape(-1, 3, 3))
    assert (rotations * expected.inv()).magnitude().max() < 2e-6  # radians

    # trans and positions (metres) against the channels and the 4x4 chain.
    root = [skel.channel_starts[0] + k for k, c in enumerate(skel.channels[0]) if "position" in c]
    np.testing.assert_allclose(got["trans"], clip.values[:, root] * metres, rtol=1e-6, atol=1e-7)
    fk_error = np.abs(got["positions"] - ref["positions"]).max()
    assert fk_error < 1e-5, fk_error
    assert ("local_translations" in got) == bool(skel.has_position_channels[1:].any())

    assert result.counts["files"][name]["source_frames"] == clip.n_frames
    assert 1.0 < result.counts["files"][name]["rig_size_m"] < 2.0
    assert validate_store(store) == []


@pytest.mark.slow
@pytest.mark.real_data
def test_wrong_units_are_refused_with_a_suggestion(real_data: Path, tmp_path: Path) -> None:
    path = real_data / "bvh" / "01_01.bvh"
    store = tmp_path / "store"
    line = one_line_error(
        run_cli("ingest", "bvh", str(path), "--store", str(store), "-q", check=False)
    )
    assert str(path) in line and "--units" in line and "0.255 m" in line
    assert not store.exists() or not list((store / "versions").glob("v*"))
    result = ingest(store, path, check_size=False)  # the check can be switched off
    assert result.counts["files"]["01_01"]["rig_size_m"] == pytest.approx(0.2549, abs=1e-3)
    with pytest.raises(InputError, match="--units"):
        ingest(tmp_path / "s2", path, units="furlong")


# ----------------------------------------------------------------------------- resampling


@pytest.mark.real_data
def test_integer_ratio_decimates_exactly(real_data: Path, tmp_path: Path) -> None:
    path = real_data / "bvh" / "01_01.bvh"
    clip = read_bvh(path)
    store = tmp_path / "store"
    ingest(store, path, units="0.056444", fps=30.0)
    got = arrays(store)
    assert got["euler"].shape[0] == (clip.n_frames - 1) // 4 + 1 == 688
    ref = reference(BvhClip(clip.skeleton, clip.frame_time_s, clip.values[::4]), 0.056444)
    assert np.abs(got["positions"] - ref["positions"]).max() < 1e-5
    reader = _VersionReader(store)
    assert reader.group_attrs("motion")["fps"] == 30.0
    config = reader.manifest["config"]
    assert config["fps"] == 30.0 and config["units"] == "0.056444"
    row = reader.table("sequences").to_pylist()[0]
    assert row["fps"] == 30.0 and row["source_fps"] == 120.0 and row["n_frames"] == 688


@pytest.mark.real_data
def test_non_integer_ratio_slerps(real_data: Path, tmp_path: Path) -> None:
    path = real_data / "bvh" / "freya_edit.bvh"
    clip = read_bvh(path)
    store = tmp_path / "store"
    ingest(store, path, fps=60.0)
    got = arrays(store)
    n_out = math.floor((clip.n_frames - 1) * 60 / 125) + 1
    assert got["axis_angle"].shape[0] == n_out == 352
    ref = reference(clip, 0.01)["rotmats"]
    for i in (1, 7, 200, 351):
        position = i * 125 / 60
        left = int(position)
        frac = position - left
        for j in (0, 5, 30):
            pair = Rotation.from_matrix(ref[[left, min(left + 1, clip.n_frames - 1)], j])
            want = Slerp([0.0, 1.0], pair)([frac])
            have = Rotation.from_rotvec(got["axis_angle"][i, j][None])
            assert (have * want.inv()).magnitude().max() < 2e-6


# ----------------------------------------------------------------------------- smoothing


def test_smoothing_removes_fast_wobble(tmp_path: Path) -> None:
    fps = 120.0
    t = np.arange(480) / fps
    slow = 30.0 * np.sin(2 * np.pi * 1.0 * t)
    wobble = 4.0 * np.sin(2 * np.pi * 25.0 * t)
    euler = np.stack([slow + wobble, 0.5 * slow, np.zeros_like(t)], axis=1)
    path = synthetic_bvh(tmp_path / "wobble.bvh", fps, euler)
    ingest(tmp_path / "raw", path)
    ingest(tmp_path / "smooth", path, smooth_cutoff_hz=5.0, smooth_order=2)
    raw = np.degrees(arrays(tmp_path / "raw")["euler"][:, 1, 0])
    smooth = np.degrees(arrays(tmp_path / "smooth")["euler"][:, 1, 0])
    inner = slice(60, -60)  # away from the filter's edge effects
    assert np.abs(raw - slow)[inner].max() > 3.5
    assert np.abs(smooth - slow)[inner].max() < 0.6
    config = _VersionReader(tmp_path / "smooth").manifest["config"]["smooth"]
    assert config["cutoff_hz"] == 5.0 and config["order"] == 2 and "quaternions" in config["on"]
    with pytest.raises(InputError, match="wobble.bvh.*cutoff"):
        ingest(tmp_path / "bad", path, smooth_cutoff_hz=70.0)


# ----------------------------------------------------------------------------- one skeleton


def short_copy(real_data: Path, tmp_path: Path, frames: int = 90, name: str = "short") -> Path:
    clip = read_bvh(real_data / "bvh" / "test_mocapbank.bvh")
    out = tmp_path / f"{name}.bvh"
    write_bvh(BvhClip(clip.skeleton, clip.frame_time_s, clip.values[:frames]), out)
    return out


@pytest.mark.real_data
def test_one_skeleton_and_one_rate_per_store(real_data: Path, tmp_path: Path) -> None:
    mocap = real_data / "bvh" / "test_mocapbank.bvh"
    free = real_data / "bvh" / "test_freebvh.bvh"
    with pytest.raises(InputError, match="test_freebvh.bvh: different skeleton"):
        ingest(tmp_path / "a", mocap, free)
    result = ingest(tmp_path / "b", mocap, free, on_error="skip")
    assert result.counts["sequences"] == 1
    skipped = _VersionReader(tmp_path / "b").manifest["skipped"]
    assert skipped[0]["path"] == str(free) and "skeleton" in skipped[0]["error"]

    clip = read_bvh(mocap)  # the same rig at 60 fps
    fast = tmp_path / "fast.bvh"
    write_bvh(BvhClip(clip.skeleton, 1 / 60, clip.values), fast)
    with pytest.raises(InputError, match="--fps 30"):
        ingest(tmp_path / "c", mocap, fast)
    result = ingest(tmp_path / "c", mocap, fast, fps=30.0)
    assert [f["frames"] for f in result.counts["files"].values()] == [455, 228]


@pytest.mark.slow
@pytest.mark.real_data
def test_append_keeps_the_parent_sequences(real_data: Path, tmp_path: Path) -> None:
    store = tmp_path / "store"
    mocap = real_data / "bvh" / "test_mocapbank.bvh"
    first = ingest(store, mocap, genre="gBR")
    short = short_copy(real_data, tmp_path)
    second = ingest(store, short, append=True, genre="gPO")
    assert (first.version, second.version) == ("v1", "v2")
    v1, v2 = arrays(store, "v1"), arrays(store, "v2")
    for name in ("trans", "axis_angle", "euler", "positions"):
        assert v2[name].shape[0] == 455 + 90
        np.testing.assert_array_equal(v2[name][:455], v1[name])
        np.testing.assert_array_equal(v2[name][455:], v1[name][:90])
    rows = _VersionReader(store).table("sequences").to_pylist()
    assert [(r["seq_id"], r["frame_start"], r["genre"]) for r in rows] == [
        ("test_mocapbank", 0, "gBR"),
        ("short", 455, "gPO"),
    ]
    assert _VersionReader(store).manifest["parent"] == "v1"
    again = ingest(store, short, append=True, genre="gPO")  # already there: nothing to do
    assert (again.created, again.version) == (False, "v2")
    with pytest.raises(InputError, match="already in version v2"):
        ingest(store, short_copy(real_data, tmp_path / "..", 50, "short"), append=True)
    with pytest.raises(InputError, match="01_01.bvh: different skeleton"):
        ingest(store, real_data / "bvh" / "01_01.bvh", append=True, units="0.056444")
    assert validate_store(store) == []

    # Without --append the new version holds only the given files.
    ingest(store, real_data / "bvh" / "test_freebvh.bvh")
    assert [r["seq_id"] for r in _VersionReader(store).table("sequences").to_pylist()] == [
        "test_freebvh"
    ]


# ----------------------------------------------------------------------------- music


@pytest.mark.slow
@pytest.mark.real_data
def test_music_pairing_then_featurize_and_segment(real_data: Path, tmp_path: Path) -> None:
    mocap = real_data / "bvh" / "test_mocapbank.bvh"
    snare = real_data / "audio" / "snare-accelerate.ogg"
    store = tmp_path / "store"
    run_cli("ingest", "bvh", str(mocap), "--store", str(store), "--music", str(snare),
            "--bpm", "120", "--genre", "gBR", "-q")  # fmt: skip
    reader = _VersionReader(store)
    seq = reader.table("sequences").to_pylist()[0]
    music = reader.table("music").to_pylist()
    assert len(music) == 1 and seq["music_id"] == music[0]["music_id"] == "snare-accelerate"
    assert (seq["bpm"], seq["genre"], seq["fps"], seq["audio_offset"]) == (120.0, "gBR", 30.0, 0)
    assert music[0]["sr"] == 22050 and music[0]["duration_s"] == pytest.approx(30.0, abs=0.01)

    featurize(store, FeaturizeOptions(motion=False))
    segment(store, SegmentOptions())
    reader = _VersionReader(store)
    assert reader.group_attrs("audio")["sr"] == 30 * 512
    track = reader.table("music").to_pylist()[0]
    assert track["frame_stop"] - track["frame_start"] == pytest.approx(900, abs=2)
    measures = reader.table("measures").to_pylist()
    fpm = 60 / 120 * 4 * 30  # 60 frames per measure
    assert len(measures) == 455 // 60
    assert [(m["frame_start"], m["frame_stop"]) for m in measures[:2]] == [(0, 60), (60, 120)]
    assert all(m["frame_stop"] - m["frame_start"] == fpm for m in measures)
    assert validate_store(store) == []


@pytest.mark.real_data
def test_manifest_pairs_many_files(real_data: Path, tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    short_copy(real_data, data, 90, "a")
    short_copy(real_data, data, 120, "b")
    csv = data / "pairs.csv"
    snare = real_data / "audio" / "snare-accelerate.ogg"
    csv.write_text(f"bvh,music,bpm,genre,split\na.bvh,{snare},100,gHO,train\nb.bvh,,90,gKR,test\n")
    store = tmp_path / "store"
    ingest(store, manifest=csv)
    reader = _VersionReader(store)
    rows = {r["seq_id"]: r for r in reader.table("sequences").to_pylist()}
    assert rows["a"]["music_id"] == "snare-accelerate" and rows["b"]["music_id"] is None
    assert (rows["a"]["bpm"], rows["b"]["bpm"]) == (100.0, 90.0)
    assert (rows["a"]["genre"], rows["b"]["genre"]) == ("gHO", "gKR")
    splits = sorted(
        (s["scheme"], s["split"], s["seq_id"]) for s in reader.table("splits").to_pylist()
    )
    assert splits == [("custom", "test", "b"), ("custom", "train", "a")]
    assert validate_store(store) == []

    with pytest.raises(InputError, match="--music pairs exactly one"):
        ingest(tmp_path / "x", data / "a.bvh", data / "b.bvh", music=snare)
    bad = data / "bad.csv"
    bad.write_text("bvh,tempo\na.bvh,100\n")
    with pytest.raises(InputError, match="unknown manifest columns"):
        ingest(tmp_path / "y", manifest=bad)
