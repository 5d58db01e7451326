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
