"""``dancedata export bvh``: BVH → store → BVH on the five real rigs through the CLI (same
hierarchy, channels within 1e-4 degrees), SMPL stores in a generated layout (checked against
the stored rotations and an independent FK), featurized stores, and clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from dancedata.cli import commands  # noqa: F401  (registers the commands)
from dancedata.cli.main import app
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dancedata.compute.smpl import SMPL_JOINTS, SMPL_PARENTS
from dancedata.errors import InputError, StoreError
from dancedata.export.bvh import BvhExportOptions, export_bvh
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.ingest.bvh import BvhIngestOptions, ingest_bvh
from dancedata.io.bvh import euler_degrees, local_translations, read_bvh
from dancedata.ops.bvh_clip import local_rotmats, world_positions
from dancedata.store.reader import _VersionReader
from dancedata.synth.aist import synth_aist
from tests.featurize.test_motion_families import (
    reference_smpl_positions,
    smpl_parts,
    write_npz_model,
)
from tests.helpers import run_cli
from tests.ingest.test_ingest_bvh import REAL

runner = CliRunner()


def cli(*args: str) -> dict:
    """Run a command through the Typer app in this process; its --json summary."""
    result = runner.invoke(app, [*args, "--json"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout[result.stdout.index("{") :])


# ----------------------------------------------------------------------------- real rigs


@pytest.mark.real_data
@pytest.mark.parametrize("name", sorted(REAL))
def test_real_rig_round_trip_through_the_cli(real_data: Path, tmp_path: Path, name: str) -> None:
    source = real_data / "bvh" / f"{name}.bvh"
    store, out = tmp_path / "store", tmp_path / "out.bvh"
    cli("ingest", "bvh", str(source), "--store", str(store), "--units", repr(REAL[name]), "-q")
    summary = cli("export", "bvh", str(store), name, str(out))
    assert summary["layout"] == "original" and summary["angles_from"] == "euler"

    a, b = read_bvh(source), read_bvh(out)  # the exported file opens in the reader again
    assert b.skeleton.same_hierarchy(a.skeleton, atol=1e-6)
    assert b.skeleton.channels == a.skeleton.channels
    assert b.n_frames == a.n_frames and b.frame_time_s == a.frame_time_s
    angle_error = np.abs(euler_degrees(b) - euler_degrees(a)).max()
    assert angle_error < 1e-4, angle_error
    length = np.abs(local_translations(a)).max()
    assert np.abs(local_translations(b) - local_translations(a)).max() < 1e-6 * length + 2e-6
    assert np.abs(world_positions(b) - world_positions(a)).max() < 1e-6 * length + 5e-5


@pytest.mark.real_data
def test_featurized_bvh_store_exports_the_same_rotations(real_data: Path, tmp_path) -> None:
    source = real_data / "bvh" / "01_01.bvh"
    store = tmp_path / "store"
    ingest_bvh(store, [source], BvhIngestOptions(units="0.056444", fps=30.0))
    featurize(store, FeaturizeOptions(audio=False))  # rewrites euler from axis_angle
    export_bvh(store, "01_01", tmp_path / "out.bvh", BvhExportOptions(units="m"))
    a, b = read_bvh(source), read_bvh(tmp_path / "out.bvh")
    ra = Rotation.from_matrix(local_rotmats(a)[::4].reshape(-1, 3, 3))
    rb = Rotation.from_matrix(local_rotmats(b).reshape(-1, 3, 3))
    assert (ra * rb.inv()).magnitude().max() < 5e-6
    np.testing.assert_allclose(b.skeleton.offsets, a.skeleton.offsets * 0.056444, atol=1e-6)


# ----------------------------------------------------------------------------- SMPL stores


def smpl_store(tmp_path: Path) -> Path:
    raw, store = tmp_path / "raw", tmp_path / "aist"
    synth_aist(raw, n_sequences=1, seed=5, workers=1)
    ingest_aist(store, raw, AistIngestOptions())
    return store


def test_smpl_store_exports_a_generated_layout(tmp_path: Path) -> None:
    store = smpl_store(tmp_path)
    reader = _VersionReader(store)
    seq = reader.table("sequences").to_pylist()[0]
    f0, f1 = seq["frame_start"], seq["frame_stop"]
    axis_angle = np.asarray(reader.array("motion/axis_angle")[f0:f1], dtype=np.float64)
    trans = np.asarray(reader.array("motion/trans")[f0:f1], dtype=np.float64)
    model = write_npz_model(tmp_path / "smpl.npz")

    out = tmp_path / "smpl.bvh"
    summary = cli("export", "bvh", str(store), seq["seq_id"], str(out), "--smpl-model", str(model),
                  "--rotation-order", "ZXY")  # fmt: skip
    assert summary["layout"] == "generated" and "smpl.npz" in summary["offsets_from"]
    clip = read_bvh(out)
    skel = clip.skeleton
    # BVH nests joints, so the file lists SMPL's joints depth first: map them back by name.
    idx = [skel.names.index(name) for name in SMPL_JOINTS]
    assert sorted(skel.names) == sorted(SMPL_JOINTS)
    assert [skel.parents[i] for i in idx] == [-1 if p < 0 else idx[p] for p in SMPL_PARENTS]
    assert skel.channels[0] == ("Xposition", "Yposition", "Zposition",
                                "Zrotation", "Xrotation", "Yrotation")  # fmt: skip
    assert all(c == ("Zrotation", "Xrotation", "Yrotation") for c in skel.channels[1:])
    assert clip.n_frames == f1 - f0 and clip.fps == pytest.approx(60.0)
    # Rotations as stored; positions (cm in the file) as an independent SMPL FK.
    stored = Rotation.from_rotvec(axis_angle.reshape(-1, 3))
    written = Rotation.from_matrix(local_rotmats(clip)[:, idx].reshape(-1, 3, 3))
    assert (stored * written.inv()).magnitude().max() < 1e-6
    expected = reference_smpl_positions(smpl_parts(), axis_angle, trans)
    assert np.abs(world_positions(clip)[:, idx] / 100.0 - expected).max() < 1e-6

    # Without a model: the built-in edge_smpl_offsets skeleton, named; the file's joints are
    # that skeleton's forward kinematics (root at the translation).
    from dancedata.ops.smpl_skeletons import smpl_skeleton

    summary = cli("export", "bvh", str(store), seq["seq_id"], str(tmp_path / "edge.bvh"))
    assert summary["offsets_from"].startswith("edge_smpl_offsets")
    builtin = read_bvh(tmp_path / "edge.bvh")
    assert builtin.n_frames == f1 - f0
    expected = smpl_skeleton(None).positions(axis_angle, trans)
    assert np.abs(world_positions(builtin)[:, idx] / 100.0 - expected).max() < 1e-6


@pytest.mark.slow
def test_export_errors_are_clear(tmp_path: Path) -> None:
    store = smpl_store(tmp_path)
    proc = run_cli("export", "bvh", str(store), "nope", str(tmp_path / "x.bvh"), check=False)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 1 and len(lines) == 1 and "no sequence 'nope'" in lines[0]
    with pytest.raises(InputError, match="XYZ"):
        export_bvh(store, "x", tmp_path / "x.bvh", BvhExportOptions(rotation_order="ZZY"))
    with pytest.raises(StoreError, match="no sequence"):
        export_bvh(store, "missing", tmp_path / "x.bvh")
