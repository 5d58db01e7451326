"""``dancedata ingest bvh`` on collections (issue 14, item 5): folders searched recursively with
``--glob``, ``--workers`` giving the same bytes as one process, resuming after a SIGKILL, rigs
whose joints carry position channels (OFFSETs compared only where the channels leave them
fixed), the rig-size check measuring the body and suggesting only units that pass, and
``--frames present`` for a MOTION block longer than ``Frames:`` declares."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dancedata.io.bvh import BvhClip, BvhSkeleton, read_bvh, write_bvh
from dancedata.ops.bvh_clip import world_positions
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store
from tests.helpers import run_cli

POS_ROT = ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
ROT = ("Zrotation", "Yrotation", "Xrotation")
# A small humanoid (cm): name, parent, bone (the rig's true offset from the parent).
RIG = [
    ("Hips", -1, (0.0, 0.0, 0.0)),
    ("Spine", 0, (0.0, 20.0, 0.0)),
    ("Neck", 1, (0.0, 40.0, 0.0)),
    ("Head", 2, (0.0, 12.0, 0.0)),
    ("LeftUpLeg", 0, (10.0, -5.0, 0.0)),
    ("LeftLeg", 4, (0.0, -42.0, 0.0)),
    ("LeftFoot", 5, (0.0, -40.0, 0.0)),
    ("RightUpLeg", 0, (-10.0, -5.0, 0.0)),
    ("RightLeg", 7, (0.0, -42.0, 0.0)),
    ("RightFoot", 8, (0.0, -40.0, 0.0)),
]


def one_line_error(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


def rig_clip(
    seed: int,
    n_frames: int = 40,
    *,
    positions_on_all: bool = False,
    offset_noise_cm: float = 0.0,
    head_offset_y: float = 12.0,
    scale: float = 1.0,
    root_at: tuple[float, float, float] = (0.0, 95.0, 0.0),
    reference_root: bool = False,
) -> BvhClip:
    """A dance-ish clip of :data:`RIG` (cm times ``scale``). With ``positions_on_all`` every
    joint above the feet has position channels holding its true bone, while its OFFSET holds the
    bone plus ``offset_noise_cm`` of seeded noise (as files that write each take's first pose
    there); the Head (rotation channels only) keeps the fixed OFFSET ``head_offset_y``. With
    ``reference_root`` a static joint at the origin is the root and the hips sit at
    ``root_at`` below it."""
    rng = np.random.default_rng(seed)
    names, parents, offsets, channels = [], [], [], []
    if reference_root:
        names.append("Reference")
        parents.append(-1)
        offsets.append((0.0, 0.0, 0.0))
        channels.append(POS_ROT)
    shift = len(names)
    for name, parent, bone in RIG:
        bone = np.array(bone)
        if name == "Head":
            bone = np.array([0.0, head_offset_y, 0.0])
        has_pos = parent < 0 or (positions_on_all and name != "Head")
        noise = rng.normal(0.0, offset_noise_cm, 3) if has_pos and offset_noise_cm else 0.0
        names.append(name)
        parents.append(-1 if parent < 0 and not shift else parent + shift if parent >= 0 else 0)
        offsets.append((bone + noise) * scale)
        channels.append(POS_ROT if has_pos else ROT)
    skeleton = BvhSkeleton(
        names=tuple(names),
        parents=tuple(parents),
        offsets=np.array(offsets),
        channels=tuple(channels),
        end_sites=tuple(
            np.array([[0.0, 8.0 * scale, 0.0]]) if n in ("Head",) else np.zeros((0, 3))
            for n in names
        ),
    )
    t = np.arange(n_frames) / 30.0
    values = np.zeros((n_frames, skeleton.n_channels))
    for j, name in enumerate(names):
        start = skeleton.channel_starts[j]
        for k, channel in enumerate(skeleton.channels[j]):
            column = start + k
            if channel.endswith("rotation"):
                amp = 0.0 if name == "Reference" else rng.uniform(5.0, 30.0)
                values[:, column] = amp * np.sin(2 * np.pi * rng.uniform(0.3, 1.5) * t)
            else:
                axis = "XYZ".index(channel[0])
                if name == "Reference":
                    values[:, column] = 0.0
                elif skeleton.parents[j] < 0 or name == "Hips":
                    travel = np.array([40.0 * t, 3.0 * np.sin(4 * t), 25.0 * t])[axis]
                    values[:, column] = (root_at[axis] + travel[:n_frames]) * scale
                else:
                    bone = dict((n, b) for n, _, b in RIG)[name]
                    values[:, column] = bone[axis] * scale
    return BvhClip(skeleton, 1.0 / 30.0, values)


def write_rig(path: Path, clip: BvhClip) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bvh(clip, path)
    return path


def data_checksums(store: Path, version: str = "v1") -> dict[str, str]:
    """checksums.json 'files' entries of a version (path → sha256)."""
    recorded = json.loads((store / "versions" / version / "checksums.json").read_text())
    return {path: entry["sha256"] for path, entry in recorded["files"].items()}


# ----------------------------------------------------------------------------- folders


@pytest.mark.slow
def test_folder_is_searched_recursively_with_glob_and_files_still_work(tmp_path: Path) -> None:
    root = tmp_path / "takes"
    write_rig(root / "a" / "take1.bvh", rig_clip(1))
    write_rig(root / "a" / "deep" / "take2.bvh", rig_clip(2))
    write_rig(root / "b" / "other3.bvh", rig_clip(3))
    (root / "b" / "notes.txt").write_text("not a BVH file\n")
    loose = write_rig(tmp_path / "loose" / "take9.bvh", rig_clip(9))

    store = tmp_path / "store"
    run_cli("ingest", "bvh", str(root), str(loose), "--store", str(store), "-q")
    reader = _VersionReader(store)
    rows = reader.table("sequences").to_pylist()
    # sorted by path below the folder (a/deep/... before a/take1...), then the file given
    assert [r["seq_id"] for r in rows] == ["take2", "take1", "other3", "take9"]
    clip = read_bvh(root / "a" / "deep" / "take2.bvh")
    got = np.asarray(reader.array("motion/positions")[0:40], dtype=np.float64)
    assert np.abs(got - world_positions(clip) * 0.01).max() < 1e-5

    only = tmp_path / "only"
    run_cli("ingest", "bvh", str(root), "--glob", "take*.bvh", "--store", str(only), "-q")
    assert [r["seq_id"] for r in _VersionReader(only).table("sequences").to_pylist()] == [
        "take2",
        "take1",
    ]
    line = one_line_error(
        run_cli(
            "ingest",
            "bvh",
            str(root),
            "--glob",
            "*.fbx",
            "--store",
            str(tmp_path / "x"),
            "-q",
            check=False,
        )  # fmt: skip
    )
    assert str(root) in line and "*.fbx" in line


# ----------------------------------------------------------------------------- parallel, resume


@pytest.mark.slow
def test_two_workers_write_the_same_bytes_as_one(tmp_path: Path) -> None:
    folder = tmp_path / "takes"
    for k in range(12):  # 2 read units of 8 files
        write_rig(folder / f"take{k:02d}.bvh", rig_clip(k, n_frames=30 + k))
    serial, parallel = tmp_path / "serial", tmp_path / "parallel"
    run_cli("ingest", "bvh", str(folder), "--store", str(serial), "-q")
    run_cli("ingest", "bvh", str(folder), "--store", str(parallel), "--workers", "2", "-q")
    a, b = data_checksums(serial), data_checksums(parallel)
    data = [p for p in a if p.startswith("data.zarr/") or p.endswith(".parquet")]
    assert len(data) > 10 and {p: a[p] for p in data} == {p: b[p] for p in data}
    counts = _VersionReader(parallel).manifest["counts"]
    assert counts["units"] == 2 and counts["sequences"] == 12


@pytest.mark.slow
def test_a_killed_ingest_resumes_with_the_units_it_finished(tmp_path: Path) -> None:
    _kill_and_resume(tmp_path, workers=1)


@pytest.mark.slow
def test_a_killed_parallel_ingest_resumes_to_the_serial_bytes(tmp_path: Path) -> None:
    """SIGKILL a --workers 2 run (its worker processes too) once a read task has finished,
    resume it with --workers 2: the finished tasks are not read again, and the store holds the
    serial run's bytes."""
    _kill_and_resume(tmp_path, workers=2)


def _kill_and_resume(tmp_path: Path, workers: int) -> None:
    folder = tmp_path / "takes"
    for k in range(48):  # 6 read units
        write_rig(folder / f"take{k:02d}.bvh", rig_clip(k, n_frames=1500))
    reference = tmp_path / "reference"
    run_cli("ingest", "bvh", str(folder), "--store", str(reference), "-q")

    store = tmp_path / "store"
    layout = StoreLayout(store)
    parallel = ["--workers", str(workers)] if workers > 1 else []
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "dancedata.cli",
            "ingest",
            "bvh",
            str(folder),
            "--store",
            str(store),
            "-q",
            *parallel,
        ],  # fmt: skip
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 300
    markers: list[Path] = []
    while proc.poll() is None and time.monotonic() < deadline:
        markers = [m for t in layout.temp_dirs() for m in t.glob(".build/units/bvh/[!.]*.json")]
        if markers:
            break
        time.sleep(0.005)
    assert proc.poll() is None and markers, "the ingest finished before a unit could be seen"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert layout.temp_dirs(), "the killed run should have left its build behind"
    assert not list((store / "versions").glob("v*"))

    out = run_cli("ingest", "bvh", str(folder), "--store", str(store), *parallel).stdout
    assert "v1" in out
    counts = _VersionReader(store).manifest["counts"]
    assert counts["units"] == 6 and 1 <= counts["resumed_units"] < 6, counts
    assert _same_data(store, reference)  # arrays and tables byte for byte
    assert validate_store(store) == [] and layout.temp_dirs() == []


def _same_data(a: Path, b: Path) -> bool:
    x, y = data_checksums(a), data_checksums(b)
    keys = [p for p in x if p.startswith("data.zarr/") or p.endswith(".parquet")]
    return {p: x[p] for p in keys} == {p: y.get(p) for p in keys}


# ----------------------------------------------------------------------------- position channels


@pytest.mark.slow
def test_one_rig_with_position_channels_goes_into_one_store(tmp_path: Path) -> None:
    first = write_rig(tmp_path / "in" / "first.bvh", rig_clip(1, positions_on_all=True,
                                                             offset_noise_cm=3.0))  # fmt: skip
    second = write_rig(tmp_path / "in" / "second.bvh", rig_clip(2, positions_on_all=True,
                                                               offset_noise_cm=3.0))  # fmt: skip
    a, b = read_bvh(first).skeleton, read_bvh(second).skeleton
    assert np.abs(a.offsets - b.offsets).max() > 0.5  # the OFFSETs really differ (cm)

    store = tmp_path / "store"
    run_cli("ingest", "bvh", str(first), str(second), "--store", str(store), "-q")
    reader = _VersionReader(store)
    assert [r["seq_id"] for r in reader.table("sequences").to_pylist()] == ["first", "second"]
    got = np.asarray(reader.array("motion/positions")[40:80], dtype=np.float64)
    assert np.abs(got - world_positions(read_bvh(second)) * 0.01).max() < 1e-5

    # The second take exported from the store (OFFSETs of the first) moves exactly as its file.
    out = tmp_path / "second_out.bvh"
    run_cli("export", "bvh", str(store), "second", str(out))
    back = world_positions(read_bvh(out))
    assert np.abs(back - world_positions(read_bvh(second))).max() < 1e-3  # cm


@pytest.mark.slow
def test_a_real_difference_in_a_fixed_offset_is_still_refused(tmp_path: Path) -> None:
    first = write_rig(tmp_path / "first.bvh", rig_clip(1, positions_on_all=True))
    taller = write_rig(
        tmp_path / "taller.bvh", rig_clip(2, positions_on_all=True, head_offset_y=15.0)
    )
    line = one_line_error(
        run_cli(
            "ingest",
            "bvh",
            str(first),
            str(taller),
            "--store",
            str(tmp_path / "s"),
            "-q",
            check=False,
        )  # fmt: skip
    )
    assert str(first) in line and str(taller) in line and "'Head'" in line, line
    assert "3 cm" in line


# ----------------------------------------------------------------------------- rig size


@pytest.mark.slow
def test_a_static_reference_root_is_not_measured(tmp_path: Path) -> None:
    # Hips 6 m from a static reference joint at the origin: joints span > 6 m in every frame.
    path = write_rig(
        tmp_path / "ref.bvh", rig_clip(4, reference_root=True, root_at=(600.0, 95.0, 0.0))
    )
    store = tmp_path / "store"
    run_cli("ingest", "bvh", str(path), "--store", str(store), "-q")
    size = _VersionReader(store).manifest["counts"]["files"]["ref"]["rig_size_m"]
    assert 1.5 < size < 2.0  # the body: head end to feet, not origin to the hips


def _suggested_units(line: str) -> list[str]:
    return re.findall(r"--units (\S+) \(", line)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scale", "given", "right"),
    [(10.0, "cm", "mm"), (1 / 2.54, "mm", "in"), (0.01, "cm", "m"), (0.01, "mm", "m")],
)
def test_size_error_suggests_only_units_that_pass(
    tmp_path: Path, scale: float, given: str, right: str
) -> None:
    path = write_rig(tmp_path / "take.bvh", rig_clip(5, scale=scale))
    line = one_line_error(
        run_cli(
            "ingest",
            "bvh",
            str(path),
            "--units",
            given,
            "--store",
            str(tmp_path / "s"),
            "-q",
            check=False,
        )  # fmt: skip
    )
    suggested = _suggested_units(line)
    assert right in suggested and given not in suggested, line
    for k, unit in enumerate(suggested):  # every suggestion passes the check
        run_cli("ingest", "bvh", str(path), "--units", unit, "--store",
                str(tmp_path / f"ok{k}"), "-q")  # fmt: skip


@pytest.mark.slow
def test_no_named_unit_fits_suggests_a_number(tmp_path: Path) -> None:
    path = write_rig(tmp_path / "tiny.bvh", rig_clip(6, scale=1e-3))
    line = one_line_error(
        run_cli("ingest", "bvh", str(path), "--store", str(tmp_path / "s"), "-q", check=False)
    )
    assert _suggested_units(line) == [] and "metres per unit" in line
    number = re.search(r"--units ([0-9.e+]+) makes it", line)
    assert number is not None, line
    run_cli("ingest", "bvh", str(path), "--units", number.group(1), "--store",
            str(tmp_path / "ok"), "-q")  # fmt: skip


# ----------------------------------------------------------------------------- --frames


@pytest.mark.slow
def test_frames_present_reads_the_rows_the_block_holds(tmp_path: Path) -> None:
    good = write_rig(tmp_path / "good.bvh", rig_clip(7, n_frames=12))
    text = good.read_text()
    declared = text.replace("Frames: 12", "Frames: 9")
    assert declared != text
    path = tmp_path / "long.bvh"
    path.write_text(declared)

    line = one_line_error(
        run_cli("ingest", "bvh", str(path), "--store", str(tmp_path / "s"), "-q", check=False)
    )
    assert str(path) in line and "12" in line and "9" in line and "--frames present" in line

    store = tmp_path / "store"
    run_cli("ingest", "bvh", str(path), "--frames", "present", "--store", str(store), "-q")
    reader = _VersionReader(store)
    assert reader.manifest["config"]["frames"] == "present"
    files = reader.manifest["counts"]["files"]["long"]
    assert files["source_frames"] == files["frames"] == 12 and files["declared_frames"] == 9
    got = np.asarray(reader.array("motion/positions")[:], dtype=np.float64)
    assert np.abs(got - world_positions(read_bvh(good)) * 0.01).max() < 1e-5
    bad = one_line_error(
        run_cli(
            "ingest",
            "bvh",
            str(path),
            "--frames",
            "all",
            "--store",
            str(tmp_path / "t"),
            "-q",
            check=False,
        )  # fmt: skip
    )
    assert "--frames" in bad


# ----------------------------------------------------------------------------- featurize, export

REAL_UNITS = {
    "01_01": 0.056444,
    "AV_8Walk_Meredith_HVHA_Rep1": 0.0254,
    "freya_edit": 0.01,
    "test_freebvh": 0.01,
    "test_mocapbank": 0.01,
}


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.parametrize("name", sorted(REAL_UNITS))
def test_export_after_featurize_writes_the_source_channels(
    real_data: Path, tmp_path: Path, name: str
) -> None:
    """featurize keeps the ingested Euler channels (the file's triples and branch), so the
    exported channels stay within the documented 7e-6 degrees of the file's (float32 radians),
    near gimbal lock and where the file winds past 180 degrees alike."""
    from dancedata.export.bvh import BvhExportOptions, export_bvh
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.ingest.bvh import BvhIngestOptions, ingest_bvh
    from dancedata.io.bvh import euler_degrees

    source = real_data / "bvh" / f"{name}.bvh"
    store = tmp_path / "store"
    ingest_bvh(store, [source], BvhIngestOptions(units=repr(REAL_UNITS[name])))
    featurize(store, FeaturizeOptions(audio=False))
    ingested = np.asarray(_VersionReader(store, "v1").array("motion/euler")[:])
    featurized = np.asarray(_VersionReader(store, "v2").array("motion/euler")[:])
    assert featurized.tobytes() == ingested.tobytes()
    out = tmp_path / "out.bvh"
    assert export_bvh(store, name, out, BvhExportOptions()).angles_from == "euler"
    error = np.abs(euler_degrees(read_bvh(out)) - euler_degrees(read_bvh(source))).max()
    assert error < 7.5e-6, error
