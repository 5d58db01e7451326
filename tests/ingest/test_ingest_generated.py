"""``ingest generated``: a model's output folder, in every layout ``evaluate --generated`` reads,
into a store shaped like a reference (a real synthetic AIST++ store: synth, ingest, featurize).
The store's arrays are the files' motion (checked against the reference it was written from,
and smoothing against scipy's filtfilt called directly), its tables the reference's by seq_id,
and validate, render, export bvh, featurize and evaluate (store against store) run on it.
Hostile inputs give one error line, exit 1, and nothing outside the store."""

from __future__ import annotations

import json
import os
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, filtfilt
from scipy.spatial.transform import Rotation

import dancedata
from dancedata.errors import InputError
from dancedata.ingest.generated import GeneratedIngestOptions, ingest_generated
from dancedata.metrics.evaluate_inputs import fact225_rows
from tests.helpers import run_cli

FPS = 60.0


@pytest.fixture(scope="module")
def ref(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("generated-ref")
    raw, store = root / "raw", root / "ref"
    run_cli("synth", "aist", str(raw), "--sequences", "2", "--seed", "3", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    run_cli("featurize", str(store), "-q", "--stems", "none", "--motion-families",
            "rotations,positions")  # fmt: skip
    return store


def _motion(ref: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    ds = dancedata.open_store(ref)
    return {
        s: (
            np.asarray(ds.motion(s, "axis_angle"), np.float64),
            np.asarray(ds.motion(s, "trans"), np.float64),
            np.asarray(ds.motion(s, "positions"), np.float64),
        )
        for s in ds.seq_ids()
    }


def write_layout(folder: Path, motion: dict, layout: str) -> None:
    """One file per sequence in ``layout``, as the generators write them."""
    folder.mkdir(parents=True, exist_ok=True)
    for s, (aa, trans, pos) in motion.items():
        if layout == "fact_npy":  # mint outputs/*.npy
            np.save(folder / f"{s}.npy", fact225_rows(aa, trans))
        elif layout == "smpl_pkl":  # Bailando / AIST++ style pickle
            with open(folder / f"{s}.pkl", "wb") as fh:
                pickle.dump({"smpl_poses": aa.reshape(len(aa), 72), "smpl_trans": trans}, fh)
        elif layout == "edge_pkl":  # EDGE: <epoch>_<name>.pkl with full_pose
            with open(folder / f"e12_{s}.pkl", "wb") as fh:
                pickle.dump({"smpl_poses": aa, "smpl_trans": trans, "full_pose": pos}, fh)
        elif layout == "quat_npz":  # a model trained on motion/quat
            quat = Rotation.from_rotvec(aa.reshape(-1, 3)).as_quat()[:, [3, 0, 1, 2]]
            np.savez(folder / f"{s}.npz", quat=2.0 * quat.reshape(len(aa), 24, 4), trans=trans)
        elif layout == "bailando_npy":  # np.save of {"pred_position": (F, 72)}
            np.save(folder / f"{s}.npy", {"pred_position": pos.reshape(len(pos), 72)})
        elif layout == "positions_npy":
            np.save(folder / f"{s}.npy", pos)
        else:
            raise ValueError(layout)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ra, rb = Rotation.from_rotvec(a.reshape(-1, 3)), Rotation.from_rotvec(b.reshape(-1, 3))
    return np.degrees((ra * rb.inv()).magnitude())


@pytest.mark.slow
@pytest.mark.parametrize(
    "layout", ["fact_npy", "smpl_pkl", "edge_pkl", "quat_npz", "bailando_npy", "positions_npy"]
)
def test_every_layout_comes_back_as_the_reference(ref: Path, tmp_path: Path, layout: str) -> None:
    motion = _motion(ref)
    write_layout(tmp_path / "gen", motion, layout)
    (tmp_path / "gen" / "README.txt").write_text("not motion")  # other files are ignored
    store = tmp_path / "store"
    result = ingest_generated(store, tmp_path / "gen", GeneratedIngestOptions(like=ref))
    assert result.created and result.counts["ignored_files"] == 1
    gen, gt = dancedata.open_store(store), dancedata.open_store(ref)
    assert sorted(gen.seq_ids()) == sorted(motion)
    positions_only = layout in ("bailando_npy", "positions_npy")
    for s, (aa, trans, pos) in motion.items():
        row, ref_row = gen.sequence(s), gt.sequence(s)
        assert row["source"] == "generated" and row["n_frames"] == len(aa)
        for column in ("genre", "situation", "dancer", "choreo", "music_id", "bpm", "fps"):
            assert row[column] == ref_row[column], column
        if positions_only:
            assert gen.array_names() == ["motion/positions"]
            np.testing.assert_allclose(gen.motion(s, "positions"), pos, atol=1e-6)
        else:
            assert _angle_deg(np.asarray(gen.motion(s, "axis_angle")), aa).max() < 1e-3
            np.testing.assert_allclose(gen.motion(s, "trans"), trans, atol=1e-6)
    assert gen.group_attrs("motion")["skeleton"] == gt.group_attrs("motion")["skeleton"]
    assert gen.group_attrs("motion")["fps"] == FPS
    # the music rows of the reference (same tracks, same files), splits restricted to the store
    ref_music = {m["music_id"]: m for m in gt.music.to_pylist()}
    for m in gen.music.to_pylist():
        assert m["path"] == ref_music[m["music_id"]]["path"]
        assert m["sha256"] == ref_music[m["music_id"]]["sha256"]
    assert sorted(map(str, gen.splits.to_pylist()), key=str) == sorted(
        map(str, gt.splits.to_pylist()), key=str
    )
    manifest = gen.manifest
    assert manifest["config"]["like"]["version"] == gt.version
    assert manifest["counts"]["layouts"] == {
        {
            "fact_npy": "fact225",
            "smpl_pkl": "smpl",
            "edge_pkl": "smpl",
            "quat_npz": "rotations",
        }.get(layout, "positions"): 2
    }
    run_cli("validate", str(store))


def _flip(aa: np.ndarray, spans: list[tuple[int, int]]) -> np.ndarray:
    out = aa.copy()
    half = Rotation.from_rotvec([0.0, np.pi, 0.0])
    for a, b in spans:
        out[a:b, 0] = (half * Rotation.from_rotvec(aa[a:b, 0])).as_rotvec()
    return out


@pytest.mark.slow
def test_cli_end_to_end_smoothed_and_hip_repaired(ref: Path, tmp_path: Path) -> None:
    motion = _motion(ref)
    first = sorted(motion)[0]
    spans = [(40, 52), (200, 203)]
    flipped = {s: (_flip(m[0], spans) if s == first else m[0], *m[1:]) for s, m in motion.items()}
    write_layout(tmp_path / "gen", flipped, "smpl_pkl")
    store = tmp_path / "gen-store"
    args = ["ingest", "generated", str(tmp_path / "gen"), "--store", str(store), "--like", str(ref)]
    proc = run_cli(*args, "--smooth-cutoff", "6", "--smooth-order", "2", "--repair-hip-flips")
    assert "ingest generated: wrote version v1" in proc.stdout
    assert f"{first}: 2 root flip(s) above 90° per frame repaired, 15 frame(s)" in proc.stdout
    assert "hip flips: 2 run(s), 15 frame(s) turned back in 1 sequence(s)" in proc.stdout
    gen = dancedata.open_store(store)
    flips = gen.manifest["counts"]["hip_flips"]
    assert flips["per_sequence"][first]["runs"] == [list(s) for s in spans]
    assert flips["frames"] == 15 and gen.sequence(first)["hip_flip_frames"] == 15
    smoothing = gen.manifest["config"]["postprocess"]["smoothing"]
    assert smoothing["cutoff_hz"] == 6.0 and smoothing["order"] == 2
    # translation: scipy's filtfilt of the same Butterworth, called directly
    b, a = butter(2, 6.0, fs=FPS)
    for s, (aa, trans, _) in motion.items():
        np.testing.assert_allclose(gen.motion(s, "trans"), filtfilt(b, a, trans, axis=0), atol=1e-5)
        # rotations: the flips are gone (the smoothed motion stays near the original)
        inner = slice(10, -10)
        assert np.median(_angle_deg(np.asarray(gen.motion(s, "axis_angle"))[inner], aa[inner])) < 2
        assert _angle_deg(np.asarray(gen.motion(s, "axis_angle"))[:, 0], aa[:, 0]).max() < 20
    run_cli("validate", str(store))
    out = tmp_path / "out"
    out.mkdir()
    bvh = run_cli("export", "bvh", str(store), first, str(out / "a.bvh"), "--json")
    assert json.loads(bvh.stdout)["frames"] == len(motion[first][0])
    from dancedata.io.bvh import read_bvh

    assert read_bvh(out / "a.bvh").n_frames == len(motion[first][0])
    run_cli("render", str(store), first, str(out / "r.mp4"), "--stop", "12", "-q")
    assert (out / "r.mp4").stat().st_size > 1000
    run_cli("plot", str(store), first, str(out / "p.png"))
    evaluated = run_cli(
        "evaluate", str(ref), "--generated", str(store), "--split", "train",
        "--out", str(out / "ev"), "--json",
    )  # fmt: skip
    record = json.loads(evaluated.stdout)
    assert record["n_scored"] >= 1
    mse = next(m for m in record["results"] if m["metric"] == "mse")
    assert mse["value"] is not None and 0 < mse["value"] < 1e-2
    # the same command again writes nothing
    again = run_cli(*args, "--smooth-cutoff", "6", "--repair-hip-flips", "-q")
    assert again.returncode == 0
    assert dancedata.open_store(store).version == "v1"


@pytest.mark.slow
def test_positions_store_is_scored_on_positions(ref: Path, tmp_path: Path) -> None:
    write_layout(tmp_path / "gen", _motion(ref), "positions_npy")
    store = tmp_path / "pos-store"
    run_cli("ingest", "generated", str(tmp_path / "gen"), "--store", str(store), "--like", str(ref))
    record = json.loads(
        run_cli(
            "evaluate", str(ref), "--generated", str(store), "--split", "train",
            "--out", str(tmp_path / "ev"), "--json",
        ).stdout
    )  # fmt: skip
    values = {m["metric"]: m["value"] for m in record["results"]}
    assert values.get("mse") is None and values["bas_mint"] is not None
    proc = run_cli("export", "bvh", str(store), sorted(_motion(ref))[0], str(tmp_path / "x.bvh"),
                   check=False)  # fmt: skip
    assert proc.returncode == 1 and "axis_angle" in proc.stderr
    proc = run_cli(
        "ingest", "generated", str(tmp_path / "gen"), "--store", str(tmp_path / "s2"),
        "--like", str(ref), "--repair-hip-flips", check=False,
    )  # fmt: skip
    assert proc.returncode == 1 and "positions only" in proc.stderr


@pytest.mark.slow
def test_generated_fps_is_resampled_to_the_reference(ref: Path, tmp_path: Path) -> None:
    motion = _motion(ref)
    half = {s: (aa[::2], t[::2], p[::2]) for s, (aa, t, p) in motion.items()}  # 30 fps files
    write_layout(tmp_path / "gen", half, "smpl_pkl")
    store = tmp_path / "store"
    options = GeneratedIngestOptions(like=ref, generated_fps=30.0)
    result = ingest_generated(store, tmp_path / "gen", options)
    assert result.counts["resampled"] == 2
    gen = dancedata.open_store(store)
    for s, (_, trans, _) in motion.items():
        stored = np.asarray(gen.motion(s, "trans"))
        frames = len(stored)
        assert frames in (2 * len(half[s][0]) - 1, 2 * len(half[s][0]))
        # the 30 fps frames fall on the even 60 fps frames
        np.testing.assert_allclose(stored[::2], trans[:frames:2], atol=1e-5)


# -- hostile and wrong inputs ---------------------------------------------------------------


def _refused(tmp_path: Path, ref: Path, gen: Path, *extra: str, json_too: bool = False) -> str:
    """Run the ingest expecting exit 1 with one error line (and, ``json_too``, one JSON object
    under --json); nothing written beside the store."""
    before = sorted(p for p in tmp_path.rglob("*") if "store" not in p.parts)
    store = tmp_path / "store"
    error = ""
    for json_mode in (False, True) if json_too else (False,):
        argv = ["ingest", "generated", str(gen), "--store", str(store), "--like", str(ref)]
        proc = run_cli(*argv, *extra, *(["--json"] if json_mode else []), check=False)
        assert proc.returncode == 1, proc.stdout + proc.stderr
        assert "Traceback" not in proc.stderr + proc.stdout
        if json_mode:
            record = json.loads(proc.stdout)
            assert record["error"] in error and record["exit_code"] == 1
        else:
            lines = [line for line in proc.stderr.splitlines() if line.startswith("error")]
            assert len(lines) == 1, proc.stderr
            error = lines[0]
    after = sorted(p for p in tmp_path.rglob("*") if "store" not in p.parts)
    assert after == before
    assert not (store / "versions").is_dir() or not any(
        p.name.startswith("v") for p in (store / "versions").iterdir()
    )
    return error


@pytest.mark.slow
def test_hostile_inputs_one_error_and_nothing_written(ref: Path, tmp_path: Path) -> None:
    motion = _motion(ref)
    first = sorted(motion)[0]
    n = len(motion[first][0])
    gen = tmp_path / "gen"
    gen.mkdir()
    # a name that is no valid sequence id (a path-like name)
    np.save(gen / "..evil.npy", np.zeros((n, 225)))
    error = _refused(tmp_path, ref, gen, json_too=True)
    assert "..evil.npy" in error and "not a plain name" in error
    os.unlink(gen / "..evil.npy")
    # a name the reference does not hold: refused, or skipped and recorded
    write_layout(gen, motion, "fact_npy")
    np.save(gen / "gXX_unknown.npy", np.zeros((10, 225)))
    assert "no sequence 'gXX_unknown' in the reference" in _refused(tmp_path, ref, gen)
    store = tmp_path / "store-skip"
    result = ingest_generated(store, gen, GeneratedIngestOptions(like=ref, on_error="skip"))
    assert [Path(s["path"]).name for s in result.skipped] == ["gXX_unknown.npy"]
    assert dancedata.open_store(store).manifest["skipped"][0]["error"].startswith("no sequence")
    os.unlink(gen / "gXX_unknown.npy")
    # a huge declared .npy (a sparse file)
    with (gen / f"{first}.npy").open("wb") as fh:
        np.lib.format.write_array_header_1_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (5_000_000, 225)}
        )
        fh.truncate(fh.tell() + 5_000_000 * 225 * 8)
    assert "at most" in _refused(tmp_path, ref, gen, json_too=True)  # refused before hashing
    # a declared size far beyond the file's frames, in a small file
    with (gen / f"{first}.npy").open("wb") as fh:
        np.lib.format.write_array_header_1_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (5_000_000, 225)}
        )
        fh.write(bytes(4096))
    assert "frames declared" in _refused(tmp_path, ref, gen)
    # a file of the wrong shape
    np.save(gen / f"{first}.npy", np.zeros((n, 7)))
    assert "unknown generated-motion layout" in _refused(tmp_path, ref, gen)
    # joints that do not fit the reference skeleton
    np.save(gen / f"{first}.npy", np.zeros((n, 17, 3)))
    assert "17 joints" in _refused(tmp_path, ref, gen)
    # an .npz bomb claiming more than it holds
    with zipfile.ZipFile(gen / f"{first}.npz", "w") as zf, zf.open("quat.npy", "w") as member:
        np.lib.format.write_array_header_1_0(
            member, {"descr": "<f8", "fortran_order": False, "shape": (10**7, 24, 4)}
        )
    os.unlink(gen / f"{first}.npy")
    assert "claims" in _refused(tmp_path, ref, gen)
    os.unlink(gen / f"{first}.npz")
    # a symbolic link is not followed
    write_layout(gen, motion, "fact_npy")
    os.unlink(gen / f"{first}.npy")
    os.symlink(tmp_path / "elsewhere.npy", gen / f"{first}.npy")
    assert "not a regular file" in _refused(tmp_path, ref, gen)
    os.unlink(gen / f"{first}.npy")
    # the reference itself as the output store
    with pytest.raises(InputError, match="reference store"):
        ingest_generated(ref, gen, GeneratedIngestOptions(like=ref))
    # settings out of range
    assert "smooth-cutoff" in _refused(tmp_path, ref, gen, "--smooth-cutoff", "45")
