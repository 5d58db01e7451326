"""PFC as an experiment metric (``metrics.names = ["pfc"]``) and in ``evaluate``'s pure layer:
the recorded value equals :func:`~dancedata.metrics.pfc.pfc` called directly on the
same SMPL-24 positions at 30 fps, and the frame rate and clip length are recorded."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.metrics.pfc import pfc
from dancedata.study.config import build_config
from tests.metrics.test_metrics_pfc import _dance, _z_to_y, edge_pfc
from tests.study.test_experiment_runner import smpl_npz, store  # noqa: F401  (module fixtures)


@pytest.mark.slow
def test_experiment_pfc_of_a_perfect_model_is_the_ground_truth_pfc(
    store: Path,  # noqa: F811
    smpl_npz: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    import dancedata
    from dancedata.compute.smpl_joints import smpl_joint_positions
    from dancedata.io.smpl_model import load_smpl_model
    from dancedata.study.runner import run_experiment

    ds = dancedata.open_store(store)
    measures = ds.measure_rows("train")
    seq_ids = list(dict.fromkeys(m["seq_id"] for m in measures))
    folder = tmp_path / "gen"
    folder.mkdir()
    for seq_id in seq_ids:  # the ground truth, as a perfect model would write it
        np.save(folder / f"{seq_id}.npy", ds.view(seq_id, "thesis_euler_75"))
    config = build_config(
        {
            "rows": ["even+transformer_motion"],
            "n_keyframes": [9],
            "split": {"eval": ["train"]},
            "metrics": {"names": ["pfc"], "smpl_model": str(smpl_npz)},
        }
    )
    output = run_experiment(
        config, store, generated={"even+transformer_motion": str(folder)}, out_dir=tmp_path / "o"
    )
    rows = [r for r in output.rows if r["metric"] == "pfc"]
    assert len(rows) == 1, output.skipped
    model = load_smpl_model(smpl_npz)
    direct = []
    for seq_id in seq_ids:
        spans = [(m["frame_start"], m["frame_stop"]) for m in measures if m["seq_id"] == seq_id]
        aa = ds.motion(seq_id, "axis_angle").astype(np.float64)
        trans = ds.motion(seq_id, "trans").astype(np.float64)
        joints = smpl_joint_positions(model, aa, trans)
        direct.append(np.concatenate([joints[a:b] for a, b in spans])[::2])
    expected = pfc(direct, fps=30.0, up_axis="y").value
    assert rows[0]["value"] == pytest.approx(expected, rel=1e-5)
    assert rows[0]["value"] > 0
    import json

    variant = json.loads(rows[0]["variant"])
    assert variant["fps"] == 30.0 and variant["frame_step"] == 2
    assert variant["clip_frames"] is None and variant["convention"] == "EDGE eval/eval_pfc.py"


def test_experiment_pfc_settings_are_checked() -> None:
    with pytest.raises(InputError, match="pfc_fps"):
        build_config({"rows": ["even+linear_slerp"], "metrics": {"pfc_fps": 25.0}})
    with pytest.raises(InputError, match="pfc_clip_frames"):
        build_config({"rows": ["even+linear_slerp"], "metrics": {"pfc_clip_frames": 2}})
    config = build_config({"rows": ["even+linear_slerp"], "metrics": {"names": ["pfc"]}})
    assert config.data["metrics"]["pfc_fps"] == 30.0


def test_evaluate_pure_layer_pfc_equals_edge_on_both_sides() -> None:
    """evaluate takes every second frame of 60 fps positions (y up) and gives EDGE's value on
    the same frames in its z-up frame; the ground truth is scored as pfc_gt."""
    from dancedata.study.scoring import EvalSequence, EvaluateParams, evaluate_sequences

    gen = [_z_to_y(_dance(s, 300)) for s in range(3)]
    gt = [_z_to_y(_dance(10 + s, 300)) for s in range(3)]
    seqs = [
        EvalSequence(seq_id=f"s{k}", music_id=None, n_frames=300, gt_positions=b, gen_positions=a)
        for k, (a, b) in enumerate(zip(gen, gt, strict=True))
    ]
    for clip in (None, 50):
        params = EvaluateParams(pfc_clip_frames=clip)
        by = {r.name: r for r in evaluate_sequences(seqs, params).results}
        for name, side in (("pfc", gen), ("pfc_gt", gt)):
            z_up = [_dance_back(p[::2]) for p in side]
            if clip is not None:
                z_up = [c[a : a + clip] for c in z_up for a in range(0, len(c) - clip + 1, clip)]
            assert by[name].value == pytest.approx(edge_pfc(z_up), rel=1e-9)
            assert by[name].convention["clip_frames"] == clip
            assert by[name].convention["fps"] == 30.0
            assert by[name].convention["frame_step"] == 2
    with pytest.raises(InputError, match="pfc_fps"):
        EvaluateParams(pfc_fps=7.0)


def _dance_back(p: np.ndarray) -> np.ndarray:
    """y up → z up, the inverse of ``_z_to_y``."""
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)
