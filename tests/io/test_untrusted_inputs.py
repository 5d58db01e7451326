"""The readers of names, configs, generated motion and pose files, called directly: each hostile
input of the corpus (tests/data/bad/hostile_inputs.py) refused by its own rule, quickly, and
each legitimate input still read as before."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.io.generated_motion import (
    find_generated_file,
    generated_frame_limit,
    read_generated_motion,
)
from dancedata.io.joints_csv import read_joints_csv
from dancedata.io.openpose import list_keypoint_files, read_openpose_folder
from dancedata.store.seq_ids import seq_id_problem
from dancedata.study.config import build_config, load_config
from tests.helpers import REPO

ROW = {"rows": ["even+linear_slerp"]}


# -- seq_id ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "seq_id",
    ["gBR_sBM_cAll_d04_mBR0_ch01", "Take 001 (2)", "dance-03.v2", "Tänzer_1", "a+b@c=d#e&f~g,h"],
)
def test_seq_ids_of_aist_bvh_and_video_names_are_plain(seq_id: str) -> None:
    assert seq_id_problem(seq_id) is None


@pytest.mark.parametrize(
    "seq_id",
    ["../x", "a/b", "a\\b", "take[12]", "t*", "t?", "{a}", "$\\foo$", "%HOME%", ".hidden", "..",
     "-rf", " x", "", "a" * 201, "ä" * 101, "take\udcff", "a\nb", "a'b", 'a"b', "a:b", 3],
)  # fmt: skip
def test_seq_ids_that_are_paths_patterns_or_code_are_refused(seq_id: object) -> None:
    assert seq_id_problem(seq_id) is not None


# -- generated files ---------------------------------------------------------------------------
def test_generated_files_are_matched_by_exact_name(tmp_path: Path) -> None:
    gen = tmp_path / "gen"
    gen.mkdir()
    np.save(gen / "x_take1.npy", np.zeros((4, 225)))  # what glob '*_take[12].npy' matches
    np.save(tmp_path / "outside.npy", np.zeros((4, 225)))
    assert find_generated_file(gen, "take[12]") is None
    assert find_generated_file(gen, "../outside") is None
    assert find_generated_file(gen, "take1") == gen / "x_take1.npy"  # EDGE's <epoch>_<name>
    np.save(gen / "take[12].npy", np.zeros((4, 225)))
    assert find_generated_file(gen, "take[12]") == gen / "take[12].npy"
    np.save(gen / "seq.pkl.npy", np.zeros((4, 225)))  # Bailando's np.save(<name>.pkl, ...)
    assert find_generated_file(gen, "seq") == gen / "seq.pkl.npy"
    np.save(gen / "2_take1.npy", np.zeros((4, 225)))
    with pytest.raises(InputError, match="several generated files"):
        find_generated_file(gen, "take1")


def test_bailando_npy_dict_is_read_by_the_restricted_unpickler(tmp_path: Path) -> None:
    positions = np.random.default_rng(0).normal(size=(90, 72))
    path = tmp_path / "seq.npy"
    np.save(path, {"pred_position": positions}, allow_pickle=True)  # Bailando's write2pkl
    motion = read_generated_motion(path, max_frames=1000)
    assert motion.layout == "positions"
    np.testing.assert_array_equal(motion.positions, positions.reshape(90, 24, 3))


def test_pickled_npy_that_is_not_a_dict_of_arrays_is_refused_unexecuted(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"

    class Boom:
        def __reduce__(self):  # noqa: ANN204
            return (os.system, (f"touch {marker}",))

    boxed = np.empty((), dtype=object)
    boxed[()] = {"pred_position": Boom()}
    np.save(tmp_path / "a.npy", boxed, allow_pickle=True)
    np.save(tmp_path / "b.npy", np.array([1, "x", None], dtype=object), allow_pickle=True)
    for name in ("a.npy", "b.npy"):
        with pytest.raises(InputError, match=r"np\.savez\(OUT"):  # names how to convert
            read_generated_motion(tmp_path / name, max_frames=1000)
    assert not marker.exists()


def test_declared_sizes_are_checked_before_loading(tmp_path: Path) -> None:
    sparse = tmp_path / "sparse.npy"
    with sparse.open("wb") as fh:  # 12 kB on disk, 1.08 GB declared
        np.lib.format.write_array_header_1_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (1_800_000, 75)}
        )
        fh.truncate(fh.tell() + 1_800_000 * 75 * 8)
    limit = generated_frame_limit(640)
    assert limit == 2 * 640 + 1200
    started = time.process_time()
    with pytest.raises(InputError, match="1800000 frames declared"):
        read_generated_motion(sparse, max_frames=limit)
    assert time.process_time() - started < 0.5
    members = tmp_path / "many.npz"
    buffer = tmp_path / "one.npy"
    np.save(buffer, np.zeros(1))
    with zipfile.ZipFile(members, "w") as zf:
        for k in range(2000):
            zf.writestr(f"m{k}.npy", buffer.read_bytes())
    with pytest.raises(InputError, match="2000 members") as info:
        read_generated_motion(members, max_frames=limit)
    assert len(str(info.value)) < 300
    # resampled: a 30 fps file for a 60 fps store needs half the frames, 120 fps twice
    assert generated_frame_limit(600, 120.0, 60.0) == 2 * 1200 + 1200


# -- configs -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("given", "match"),
    [
        ({"metrics": {"mse_wrap": "false"}}, r"metrics\.mse_wrap = 'false': must be true"),
        ({"keyframes": {"G": "six"}}, r"keyframes\.G = 'six': must be an integer"),
        ({"keyframes": {"G": True}}, r"keyframes\.G"),
        ({"keyframes": {"G": 10**9}}, r"keyframes\.G = 1000000000: must be in"),
        ({"n_keyframes": [3, "5"]}, r"n_keyframes"),
        ({"id": "/abs/path"}, r"\bid = '/abs/path': must be a plain name"),
        ({"id": "../../x"}, r"\bid"),
        ({"id": "a/b"}, r"\bid"),
        ({"metrics": {"geometric_frame_time": float("nan")}}, r"geometric_frame_time"),
        ({"keyframes": {"stem_weights": {"drums": -1.0}}}, r"stem_weights\.drums"),
        ({"generated": {"x": 3}}, r"generated"),
        ({"matrix": "x"}, r"matrix must be a table"),
        ({"split": {"eval": [["test"]]}}, r"split\.eval"),
    ],
)
def test_config_values_have_types_and_ranges(given: dict, match: str) -> None:
    with pytest.raises(InputError, match=match):
        build_config({**ROW, **given})


def test_config_nesting_size_and_lines_are_bounded(tmp_path: Path) -> None:
    deep = tmp_path / "deep.toml"
    deep.write_text('rows = ["even+linear_slerp"]\nx = ' + "[\n" * 50_000 + "]\n" * 50_000)
    with pytest.raises(InputError, match="nested too deeply"):
        load_config(deep)
    nested = {"a": {"b": {"c": {"d": {"e": {"f": {"g": {"h": {"i": {}}}}}}}}}}
    with pytest.raises(InputError, match="nested deeper than 8"):
        build_config({**ROW, **nested})
    dotted = tmp_path / "dotted.toml"
    dotted.write_text(f"[{'.'.join(['t'] * 50_000)}]\n")
    started = time.process_time()
    with pytest.raises(InputError, match="a line of"):
        load_config(dotted)
    assert time.process_time() - started < 0.5  # tomllib alone takes ~2.4 s on it
    huge = tmp_path / "huge.toml"
    with huge.open("w") as fh:
        fh.truncate(60 << 20)
    with pytest.raises(InputError, match="larger than"):
        load_config(huge)


def test_shipped_configs_still_load() -> None:
    for path in sorted((REPO / "experiments").glob("*.toml")):
        assert load_config(path).rows


# -- pose files --------------------------------------------------------------------------------
def _frame(value: str = "100.0") -> str:
    keypoints = ", ".join([value] + ["0.5"] * 74)
    return (
        f'{{"version": 1.3, "people": [{{"person_id": [-1], "pose_keypoints_2d": [{keypoints}]}}]}}'
    )


def _poses(folder: Path, n: int = 6) -> Path:
    folder.mkdir()
    for f in range(n):
        (folder / f"clip_{f:012d}_keypoints.json").write_text(_frame())
    return folder


def test_openpose_nesting_and_long_numbers_are_one_skippable_error(tmp_path: Path) -> None:
    poses = _poses(tmp_path / "poses")
    (poses / "clip_000000000002_keypoints.json").write_text("[" * 100_000 + "]" * 100_000)
    (poses / "clip_000000000003_keypoints.json").write_text(_frame("1" * 5000))
    (poses / "clip_000000000004_keypoints.json").write_text(_frame("1" * 5000 + ".5"))
    with pytest.raises(InputError, match="nested too deeply"):
        read_openpose_folder(poses)
    bad: list[tuple[str, str]] = []
    frames = read_openpose_folder(poses, on_bad_file=lambda p, why: bad.append((p.name, why)))
    assert [name[5:17] for name, _ in bad] == ["000000000002", "000000000003", "000000000004"]
    assert "5000 digits" in bad[1][1] and "5002 characters" in bad[2][1]
    assert frames.present.tolist() == [True, True, False, False, False, True]


def test_frame_numbers_are_bounded_before_arrays_are_sized(tmp_path: Path) -> None:
    poses = _poses(tmp_path / "poses", 12)
    (poses / "clip_000300000000_keypoints.json").write_text(_frame())
    with pytest.raises(InputError, match="frame number 300000000 is above"):
        list_keypoint_files(poses)
    (poses / "clip_000300000000_keypoints.json").unlink()
    (poses / "clip_000000100000_keypoints.json").write_text(_frame())
    with pytest.raises(InputError, match="frame numbers run to 100000 for 13 files"):
        list_keypoint_files(poses)
    csv = tmp_path / "clip.csv"
    header = "frame," + ",".join(f"{j}_{a}" for j in ("Nose", "Neck") for a in "xyz")
    csv.write_text(header + "\n" + "".join(f"{f},1,2,3,4,5,6\n" for f in (0, 1, 300_000_000)))
    with pytest.raises(InputError, match="frame number 300000000"):
        read_joints_csv(csv)
    csv.write_text(header + "\n" + "".join(f"{f},1,2,3,4,5,6\n" for f in (0, 1, 5)))
    assert read_joints_csv(csv).present.tolist() == [True, True, False, False, False, True]


def test_joint_csv_header_check_is_linear(tmp_path: Path) -> None:
    csv = tmp_path / "wide.csv"
    names = [f"j{k}" for k in range(1000)]
    csv.write_text(",".join(f"{j}_{a}" for j in names for a in "xyz") + "\n" + "0," * 2999 + "0\n")
    assert read_joints_csv(csv).joints == tuple(names)
    wide = tmp_path / "wider.csv"
    header = ",".join(f"j{k}_{a}" for k in range(100_000) for a in "xyz")
    wide.write_text(header + "\n" + ",".join(["0"] * 300_000) + "\n")  # 5 MB
    started = time.process_time()
    with pytest.raises(InputError, match="more than 1000 joints"):
        read_joints_csv(wide)
    assert time.process_time() - started < 5.0


# -- how the command ends ----------------------------------------------------------------------
@pytest.mark.slow
def test_the_command_runs_atexit_handlers_and_keeps_its_exit_code(tmp_path: Path) -> None:
    """``run`` ends with os._exit (no teardown, so no SIGABRT from native threads) after the
    atexit handlers: a handler's file is written, and the codes are 0, 1 and 2."""
    marker = tmp_path / "atexit-ran"
    code = (
        "import atexit, sys\n"
        f"atexit.register(lambda: open({str(marker)!r}, 'w').close())\n"
        "sys.argv = ['dancedata', *sys.argv[1:]]\n"
        "from dancedata.cli.main import run\n"
        "run()\n"
        "print('not reached')\n"
    )
    for argv, expected in (([ "--version"], 0), (["info", str(tmp_path / "nope")], 1),
                           (["info", "--bogus"], 2)):  # fmt: skip
        marker.unlink(missing_ok=True)
        proc = subprocess.run(
            [sys.executable, "-c", code, *argv, "--json"] if expected == 1 else
            [sys.executable, "-c", code, *argv],
            capture_output=True, text=True, timeout=120, cwd=REPO,
        )  # fmt: skip
        assert proc.returncode == expected, proc.stderr
        assert marker.exists() and "not reached" not in proc.stdout
        if expected == 1:
            assert json.loads(proc.stdout)["exit_code"] == 1


@pytest.mark.slow
def test_native_threads_alive_at_exit_never_turn_exit_1_into_sigabrt(tmp_path: Path) -> None:
    """pyarrow threads busy while the process ends: with interpreter teardown (``main`` +
    ``sys.exit``) 2 of 40 such runs died with SIGABRT 134 under load; ``run`` (the command)
    skips the teardown, so every run exits 1 with its JSON error."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = tmp_path / "t.parquet"
    pq.write_table(pa.table({"x": list(range(1000))}), table)
    code = (
        "import sys, threading\n"
        "import pyarrow as pa, pyarrow.parquet as pq\n"
        f"data = open({str(table)!r}, 'rb').read()\n"
        "def spin():\n"
        "    while True:\n"
        "        pq.read_table(pa.BufferReader(data), use_threads=True)\n"
        "for _ in range(4):\n"
        "    threading.Thread(target=spin, daemon=True).start()\n"
        f"sys.argv = ['dancedata', 'info', {str(tmp_path / 'nope')!r}, '--json']\n"
        "from dancedata.cli.main import run\n"
        "run()\n"
    )
    procs = []
    for _ in range(4):
        for _ in range(4):
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-c", code],
                    stdout=subprocess.PIPE,
                    stderr=subprocess.DEVNULL,
                    cwd=REPO,
                )  # fmt: skip
            )
        for proc in procs[-4:]:
            proc.wait(timeout=120)
    codes = [p.returncode for p in procs]
    assert codes == [1] * len(procs), codes
    assert all(json.loads(p.stdout.read())["exit_code"] == 1 for p in procs)
