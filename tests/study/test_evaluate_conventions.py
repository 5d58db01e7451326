"""``dancedata evaluate --convention bailando``: one run gives a Bailando table row.

The reference is Bailando's own pipeline, transcribed in tests/metrics/test_metrics_reference.py
(``normalize``, ``calc_fid``, ``calculate_avg_distance``, ``calc_db``, ``BA``) and driven here
as ``utils/metrics_new.py`` and ``utils/beat_align_score.py`` drive them: generated positions cut
to their first N frames and made root-relative to their first frame, ground-truth features of
every sequence (whole, root-relative), both z-scored by the ground truth; BAS on the whole
generated sequence against Bailando's music beats (``audio/beats_bailando``) cut to its length.
Positions: the built-in edge_smpl_offsets skeleton (no model file).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import dancedata
from dancedata.metrics import motion_feature_matrix
from dancedata.metrics.beats import beat_frames
from dancedata.ops.smpl_skeletons import smpl_skeleton
from tests.helpers import run_cli
from tests.metrics.test_metrics_reference import (
    ref_bailando_ba,
    ref_bailando_calc_db,
    ref_bailando_calc_fid,
    ref_bailando_calculate_avg_distance,
    ref_bailando_get_mb_from_onehot,
    ref_bailando_normalize,
)

# slow: evaluate over a featurized 4-sequence store
pytestmark = pytest.mark.slow

CUT = 150  # frames of the cut (Bailando: 1200; the synthetic sequences are shorter)


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("conventions")
    run_cli("synth", "aist", str(root / "raw"), "--sequences", "4", "--seed", "2", "-q")
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "st"), "-q")
    run_cli("featurize", str(root / "st"), "--audio-families", "fact,bailando_beats", "-q")
    return root / "st"


def _generated(store: Path, folder: Path) -> dict[str, np.ndarray]:
    """Joint positions of the ground truth with rotation noise, one .npy per train sequence."""
    s = dancedata.open_store(store)
    rng = np.random.default_rng(5)
    rest = smpl_skeleton(None)
    folder.mkdir()
    out = {}
    for seq in s.seq_ids(split="train"):
        aa = s.motion(seq, "axis_angle").astype(np.float64)
        noisy = aa + rng.normal(scale=0.08, size=aa.shape)
        out[seq] = rest.positions(noisy, s.motion(seq, "trans").astype(np.float64))
        np.save(folder / f"{seq}.npy", out[seq])
    return out


def _bailando_reference(store: Path, generated: dict[str, np.ndarray]) -> dict[str, float]:
    s = dancedata.open_store(store)
    rest = smpl_skeleton(None)

    def zero_start(p: np.ndarray) -> np.ndarray:
        return p - p[:1, :1]  # roott = joint3d[:1, :3]; joint3d - tile(roott)

    gt = [
        zero_start(rest.positions(s.motion(q, "axis_angle"), s.motion(q, "trans")))
        for q in s.seq_ids()
    ]
    pred = [zero_start(p[:CUT]) for p in generated.values()]
    out = {}
    for kind, name in (("kinetic", "k"), ("geometric", "g")):
        f_gt, f_pred = motion_feature_matrix(gt, kind), motion_feature_matrix(pred, kind)
        gt_n, pred_n = ref_bailando_normalize(f_gt, f_pred)
        out[f"fid_{name}"] = ref_bailando_calc_fid(pred_n, gt_n)
        out[f"div_{name}"] = ref_bailando_calculate_avg_distance(pred_n)
    scores = []
    for seq, positions in generated.items():  # the whole sequence
        onehot = np.asarray(s.audio(seq, "beats_bailando")).reshape(-1)
        motion_beats, length = ref_bailando_calc_db(positions)
        scores.append(ref_bailando_ba(ref_bailando_get_mb_from_onehot(onehot, length),
                                      motion_beats))  # fmt: skip
    out["bas_bailando"] = float(np.mean(scores))
    assert beat_frames(onehot).size > 0
    return out


def test_bailando_convention_reproduces_bailandos_pipeline(
    store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("DANCEDATA_SMPL_MODEL", raising=False)
    generated = _generated(store, tmp_path / "gen")
    out = tmp_path / "res"
    proc = run_cli("evaluate", str(store), "--generated", str(tmp_path / "gen"), "--split",
                   "train", "--convention", "bailando", "--feature-max-frames", str(CUT),
                   "--out", str(out))  # fmt: skip
    record = json.loads((out / "results.json").read_text())
    params = record["config"]["params"]
    assert params["convention"] == "bailando"
    assert params["feature_max_frames"] == CUT  # given explicitly: it wins over the preset's 1200
    assert params["fid_reference"] == "all_gt" and params["fid_origin"] == "first_frame_root"
    assert params["fid_eps"] == 1e-5 and params["max_frames"] is None
    assert params["beat_source"] == "bailando"  # Bailando's BAS uses its own music beats
    results = {r["metric"]: r for r in record["results"]}
    want = _bailando_reference(store, generated)
    for metric, value in want.items():
        got = results[metric]["value"]
        bound = results[metric]["details"].get("sqrtm_error_bound", 0.0)
        assert abs(got - value) <= 1e-6 * max(1.0, abs(value)) + 2 * bound, (metric, got, value)
    assert results["fid_k"]["convention"]["feature_max_frames"] == CUT
    assert results["fid_k"]["n_frames"] == CUT * len(generated)
    # BAS is on the whole sequences, not the cut
    assert results["bas_bailando"]["n_frames"] == sum(len(p) for p in generated.values())
    assert results["bas_bailando"]["convention"]["music_beats"].startswith("audio/beats_bailando")
    # The output names the convention and prints the row in the paper's order.
    lines = proc.stdout.splitlines()
    assert any(line.startswith("convention bailando: Bailando") for line in lines)
    row = next(line for line in lines if line.startswith("bailando row: "))
    assert [cell.split()[0] for cell in row.removeprefix("bailando row: ").split("  ")] == [
        "FID_k", "FID_g", "Div_k", "Div_g", "BAS"]  # fmt: skip
    assert f"BAS {want['bas_bailando']:.4g}" in row


def test_an_unknown_convention_is_one_error_line(store: Path, tmp_path: Path) -> None:
    (tmp_path / "gen").mkdir()
    proc = run_cli("evaluate", str(store), "--generated", str(tmp_path / "gen"), "--split",
                   "train", "--convention", "nope", check=False)  # fmt: skip
    assert proc.returncode == 1
    assert "unknown evaluate convention 'nope'; known: bailando" in proc.stderr
