"""Multimodality (mm_k, mm_g) against brute force: FACT's / Bailando's
``calculate_avg_distance`` (a double loop over pairs) within each music piece's generations,
features z-scored by the ground truth's mean and std + 1e-10, then the mean over pieces; and
end to end through ``evaluate --generations``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dancedata.metrics.multimodality import multimodality
from tests.helpers import run_cli
from tests.study.test_evaluate import SPLIT, fact_rows, model_path, noisy_motion, store  # noqa: F401


def avg_distance(features: np.ndarray, mean: np.ndarray, std: np.ndarray) -> float:
    """FACT / Bailando ``calculate_avg_distance`` with the ground truth's mean and std."""
    x = (np.stack(features) - mean) / std
    n = x.shape[0]
    dist = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            dist += np.linalg.norm(x[i] - x[j])
    return dist / ((n * n - n) / 2)


def brute_multimodality(groups: dict[str, np.ndarray], reference: np.ndarray) -> float:
    mean, std = reference.mean(axis=0), reference.std(axis=0) + 1e-10
    return float(np.mean([avg_distance(g, mean, std) for g in groups.values() if len(g) >= 2]))


def test_multimodality_equals_brute_force() -> None:
    rng = np.random.default_rng(0)
    reference = rng.normal(2.0, 3.0, (12, 7))
    groups = {f"m{k}": rng.normal(k, 1.0 + k, (2 + k, 7)) for k in range(4)}
    result = multimodality(groups, reference, name="mm_k")
    assert result.value == pytest.approx(brute_multimodality(groups, reference), rel=1e-12)
    assert result.n_units == sum(len(g) for g in groups.values())
    assert result.details["n_groups"] == 4
    assert result.details["generations_per_group"] == [2, 3, 4, 5]
    raw = multimodality(groups)
    assert raw.convention["normalize"] == "none"
    mean_raw = np.mean(
        [avg_distance(g, np.zeros(7), np.ones(7)) for g in groups.values()]
    )  # no normalisation
    assert raw.value == pytest.approx(mean_raw, rel=1e-12)


def test_single_generation_groups_are_left_out_and_named() -> None:
    rng = np.random.default_rng(1)
    groups = {"a": rng.normal(size=(3, 4)), "b": rng.normal(size=(1, 4))}
    result = multimodality(groups, rng.normal(size=(6, 4)))
    assert result.details["single"] == ["b"] and result.details["n_groups"] == 1
    assert result.n_units == 3
    assert math.isnan(multimodality({"b": groups["b"]}).value)
    with pytest.raises(ValueError, match="group a"):
        multimodality({"a": np.zeros(4)})


def test_identical_generations_have_zero_multimodality() -> None:
    row = np.arange(5.0)
    result = multimodality(
        {"a": np.stack([row, row, row])}, np.random.default_rng(2).normal(size=(5, 5))
    )
    assert result.value == 0.0


@pytest.mark.slow
def test_evaluate_generations_end_to_end(
    store: Path,  # noqa: F811
    model_path: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    import dancedata
    from dancedata.compute.smpl_joints import smpl_joint_positions
    from dancedata.io.smpl_model import load_smpl_model
    from dancedata.metrics import motion_feature_matrix

    gens = tmp_path / "gens"
    runs = {}
    for k in range(3):
        runs[k] = noisy_motion(store, seed=20 + k)
        folder = gens / f"run{k}"
        folder.mkdir(parents=True)
        for seq, (aa, trans) in runs[k].items():
            np.save(folder / f"{seq}.npy", fact_rows(aa, trans))
    out = tmp_path / "res"
    run_cli("evaluate", str(store), "--generated", str(gens / "run0"), *SPLIT,
            "--generations", str(gens), "--smpl-model", str(model_path),
            "--out", str(out))  # fmt: skip
    record = json.loads((out / "results.json").read_text())
    by = {r["metric"]: r for r in record["results"]}
    assert record["generations"]["runs"] == ["run0", "run1", "run2"]

    s = dancedata.open_store(store)
    model = load_smpl_model(model_path)
    seqs = s.seq_ids(split="train")
    gt = [
        smpl_joint_positions(model, s.motion(q, "axis_angle"), s.motion(q, "trans")) for q in seqs
    ]
    for kind, name in (("kinetic", "mm_k"), ("geometric", "mm_g")):
        reference = motion_feature_matrix(gt, kind)
        groups: dict[str, list[np.ndarray]] = {}
        for q in seqs:
            music = s.sequence(q)["music_id"]
            for k in range(3):
                groups.setdefault(music, []).append(smpl_joint_positions(model, *runs[k][q]))
        features = {m: motion_feature_matrix(v, kind) for m, v in groups.items()}
        expected = brute_multimodality(features, reference)
        assert by[name]["value"] == pytest.approx(expected, rel=1e-6)
        assert by[name]["convention"]["group"] == "music"
        assert by[name]["details"]["n_groups"] == len(groups)


@pytest.mark.slow
def test_evaluate_without_generations_says_why(store: Path, tmp_path: Path) -> None:  # noqa: F811
    from dancedata.study.scoring import EvalSequence, EvaluateParams, evaluate_sequences

    rng = np.random.default_rng(3)
    walk = [np.cumsum(rng.normal(0, 0.01, (100, 24, 3)), axis=0) for _ in range(3)]
    seqs = [
        EvalSequence(
            seq_id=f"s{k}", music_id="m", n_frames=100, gt_positions=w, gen_positions=w + 0.01
        )  # fmt: skip
        for k, w in enumerate(walk)
    ]
    evaluation = evaluate_sequences(seqs, EvaluateParams())
    assert "--generations" in evaluation.skipped_metrics["mm_k"]
    gens = {"m": [w + rng.normal(0, 0.01, w.shape) for w in walk]}
    evaluation = evaluate_sequences(seqs, EvaluateParams(), generations=gens)
    mm = {r.name: r for r in evaluation.results}["mm_k"]
    from dancedata.metrics import motion_feature_matrix

    reference = motion_feature_matrix(walk, "kinetic")
    feats = {"m": motion_feature_matrix(gens["m"], "kinetic")}
    assert mm.value == pytest.approx(brute_multimodality(feats, reference), rel=1e-12)
    bad = tmp_path / "one"
    (bad / "only").mkdir(parents=True)
    proc = run_cli("evaluate", str(store), "--generated", str(bad / "only"), *SPLIT,
                   "--generations", str(bad), "--json", check=False)  # fmt: skip
    assert proc.returncode == 1
    assert "at least 2 run subfolders" in proc.stdout + proc.stderr
