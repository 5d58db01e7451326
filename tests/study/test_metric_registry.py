"""The metric registry: metrics register as feature families do, and ``evaluate`` and
``experiment run`` take their metrics, options and settings from it.

A toy metric registered inside a test appears in ``evaluate --help`` (its settings field as an
option), in evaluate's output (results.json, results.parquet, the printed table) with the value
an independent computation gives, and in ``config.params``; once unregistered it is gone again.
"""

from __future__ import annotations

import json
import pickle
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

import dancedata
from dancedata.errors import InputError
from dancedata.featurize.family_settings import cli_settings, setting
from dancedata.study.metric_registry import (
    Metric,
    MetricInputs,
    ScoringSettings,
    experiment_metric_names,
    metric_names,
    range_notes,
    register_metric,
    registered_metrics,
    rotation_only_outputs,
    settings_types,
    unit_range_outputs,
    unregister_metric,
)
from dancedata.study.scoring import EvaluateParams
from tests.helpers import run_cli

# The names evaluate listed (and recorded under "metrics") before the registry existed.
LISTED = (
    "mse",
    "fid_k",
    "fid_g",
    "div_k",
    "div_g",
    "div_k_gt",
    "div_g_gt",
    "bas_mint",
    "bas_bailando",
    "bas_msd_motion2music",
    "bas_msd_music2motion",
    "beat_coverage",
    "beat_hit_rate",
    "beat_accuracy",
    "fpd",
    "fmd",
    "pfc",
    "pfc_gt",
    "mm_k",
    "mm_g",
)


def _help(args: list[str]) -> str:
    import dancedata.cli.commands  # noqa: F401 - registers every command
    from dancedata.cli.main import app

    result = CliRunner().invoke(app, [*args, "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    return result.output


def test_registry_lists_the_built_in_metrics_in_order() -> None:
    assert metric_names() == LISTED
    assert list(registered_metrics()) == ["mse", "features", "beats", "fpd", "pfc", "multimodality"]
    assert experiment_metric_names() == ("mse", "fid_g", "fid_k", "pfc")
    assert rotation_only_outputs() == {"mse", "fpd", "fmd"}  # they name no skeleton
    assert unit_range_outputs() == {"beat_hit_rate", "beat_accuracy", "bas_mint", "bas_bailando"}
    assert list(range_notes()) == ["beat_coverage"]


def test_every_setting_has_one_owner_and_every_option_is_a_setting() -> None:
    owners: dict[str, type] = {}
    for cls in settings_types():
        for item in fields(cls):
            assert item.name not in owners, f"{item.name}: {owners.get(item.name)} and {cls}"
            owners[item.name] = cls
    assert len(owners) == 31  # the fields EvaluateParams had when it was written by hand
    assert set(EvaluateParams().as_dict()) == set(owners)
    options = {s.name for cls in settings_types() for s in cli_settings(cls)}
    # Users script these names: the options evaluate had when they were written by hand.
    assert options == {
        *("mse_space", "mse_wrap", "mse_reduce", "fid_unit", "fid_reference", "kinetic_mode"),
        *("normalize", "drop_constant_ref_columns", "fid_eps", "bas_sigma", "beat_source"),
        *("bas_beats", "beat_tol", "beat_detector", "msd_fps", "fpd_parity", "fpd_aggregate"),
        *("max_frames", "feature_max_frames", "convention", "fid_origin", "pfc_fps"),
        *("pfc_clip_frames", "skip_frames"),
    }
    text = _help(["evaluate"])
    for name in options:
        assert f"--{name.replace('_', '-')}" in text
    assert "--no-normalize" in text and "--mse-wrap" in text  # bools are flags


def test_evaluate_params_is_flat_validated_and_frozen() -> None:
    p = EvaluateParams(fid_unit="measure", pfc_fps=20.0)
    assert (p.fid_unit, p.pfc_fps, p.fps) == ("measure", 20.0, 60.0)
    assert p == EvaluateParams(**p.as_dict())
    assert p.settings(ScoringSettings).skip_frames == 0
    with pytest.raises(AttributeError):
        p.fid_unit = "sequence"  # type: ignore[misc]
    with pytest.raises(TypeError, match="unknown field"):
        EvaluateParams(fid_units="measure")
    with pytest.raises(InputError, match="msd_fps 7.0 must divide fps 60.0"):
        EvaluateParams(msd_fps=7.0)
    with pytest.raises(InputError, match="mse_reduce must be one of"):
        EvaluateParams(mse_reduce="median")


def test_register_refuses_clashes() -> None:
    class Clash(Metric):
        outputs = ("fid_k",)

    with pytest.raises(ValueError, match="outputs \\['fid_k'\\] are another metric's"):
        register_metric("clash")(Clash)

    @dataclass(frozen=True)
    class Shadow:
        fid_unit: str = "sequence"

    class Shadowing(Metric):
        outputs = ("shadow",)
        settings_type = Shadow

    with pytest.raises(ValueError, match="settings \\['fid_unit'\\] are another metric's"):
        register_metric("shadowing")(Shadowing)

    class Unknown(Metric):
        outputs = ("unknown",)
        needs = ("telepathy",)

    with pytest.raises(TypeError, match="unknown needs"):
        register_metric("unknown")(Unknown)
    assert "clash" not in registered_metrics() and "unknown" not in registered_metrics()


# ------------------------------------------------------------------------------ a toy metric


@dataclass(frozen=True)
class ToySettings:
    toy_scale: float = setting(1.0, help="Toy metric: the factor its root distance is scaled by.")


class ToyMetric(Metric):
    """Mean root distance (m) between generated and ground-truth positions × ``toy_scale``."""

    outputs = ("toy_root_distance",)
    needs = ("positions",)
    settings_type = ToySettings

    def compute(self, inputs: MetricInputs, settings: ToySettings) -> list[Any]:
        from dancedata.metrics.result import mean_over_units

        seqs = inputs.usable(self.outputs, "positions")
        if not seqs:
            return inputs.skip(self.outputs, "no positions")
        per = [
            float(np.linalg.norm(s.gen_positions[:, 0] - s.gt_positions[:, 0], axis=-1).mean())
            * settings.toy_scale
            for s in seqs
        ]
        convention = {"convention": "toy", "scale": settings.toy_scale}
        return [mean_over_units(self.outputs[0], per, convention, sum(s.n_frames for s in seqs))]


@pytest.fixture(scope="module")
def small_store(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, float]]:
    """A 4-sequence synthetic store, generated motion for its train split (ground truth with a
    known root offset per sequence), and the toy value each sequence must score."""
    root = tmp_path_factory.mktemp("registry")
    raw, st, gen = root / "raw", root / "st", root / "gen"
    run_cli("synth", "aist", str(raw), "--sequences", "4", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(st), "-q")
    gen.mkdir()
    s = dancedata.open_store(st)
    offsets = {}
    for k, seq in enumerate(s.seq_ids(split="train")):
        aa = s.motion(seq, "axis_angle").astype(np.float64)
        shift = np.array([0.03 * (k + 1), 0.0, 0.04 * (k + 1)])  # |shift| = 0.05 (k + 1) m
        trans = s.motion(seq, "trans").astype(np.float64) + shift
        data = {"smpl_poses": aa.reshape(len(aa), 72), "smpl_trans": trans}
        (gen / f"{seq}.pkl").write_bytes(pickle.dumps(data, protocol=4))
        offsets[seq] = 0.05 * (k + 1)
    return st, gen, offsets


def _evaluate(store: Path, gen: Path, out: Path, *extra: str) -> dict[str, Any]:
    import dancedata.cli.commands  # noqa: F401 - registers every command
    from dancedata.cli.main import app

    args = ["evaluate", str(store), "--generated", str(gen), "--split", "train"]
    result = CliRunner().invoke(app, [*args, "--out", str(out), "--json", *extra])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_a_toy_metric_registered_in_a_test_is_an_option_and_a_result(
    small_store: tuple[Path, Path, dict[str, float]], tmp_path: Path
) -> None:
    store, gen, offsets = small_store
    assert "--toy-scale" not in _help(["evaluate"])
    register_metric("toy")(ToyMetric)
    try:
        assert metric_names()[-1] == "toy_root_distance"
        text = _help(["evaluate"])
        assert "--toy-scale" in text and "root distance is scaled by" in text
        record = _evaluate(store, gen, tmp_path / "toy", "--toy-scale", "2.5")
        rows = {r["metric"]: r for r in record["results"]}
        toy = rows["toy_root_distance"]
        # FK of the same rotations about a shifted root moves every joint, the root too, by
        # the shift: the toy value is the mean |shift| × 2.5 (a closed form, not the code's).
        assert toy["value"] == pytest.approx(2.5 * np.mean(list(offsets.values())), rel=1e-9)
        assert toy["n_units"] == len(offsets)
        assert toy["convention"]["scale"] == 2.5 and toy["convention"]["skeleton"]
        assert record["config"]["params"]["toy_scale"] == 2.5
        assert record["metrics"][-1] == "toy_root_distance"
        assert rows["mse"]["value"] >= 0  # the built-in metrics still run beside it
        table = pq.read_table(tmp_path / "toy" / "results.parquet").to_pylist()
        assert [r["value"] for r in table if r["metric"] == "toy_root_distance"] == [toy["value"]]
    finally:
        unregister_metric("toy")
    assert "--toy-scale" not in _help(["evaluate"])
    record = _evaluate(store, gen, tmp_path / "plain")
    assert "toy_root_distance" not in {r["metric"] for r in record["results"]}
    assert "toy_scale" not in record["config"]["params"]
    assert tuple(record["metrics"]) == LISTED


def test_experiment_config_names_the_registered_experiment_metrics(tmp_path: Path) -> None:
    from dancedata.study.config import build_config

    config = build_config({"rows": ["even+linear_slerp"], "metrics": {"names": ["pfc", "mse"]}})
    assert config.metrics == ["pfc", "mse"]
    with pytest.raises(InputError, match=r"the runner computes \['mse', 'fid_g', 'fid_k', 'pfc'\]"):
        build_config({"rows": ["even+linear_slerp"], "metrics": {"names": ["bas_mint"]}})
