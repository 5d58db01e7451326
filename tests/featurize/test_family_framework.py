"""The feature-family framework: one registry for motion and audio families, declared outputs
that match what the families write and make the schema's array sections, settings that make the
featurize options, and families that read arrays an earlier family wrote in the same run."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.compute.motion_representations import KNOWN_REPRESENTATIONS
from dancedata.errors import InputError
from dancedata.featurize.families.motion_base import MotionFamily
from dancedata.featurize.family import (
    ArraySpec,
    Family,
    register_family,
    registered,
    run_order,
)
from dancedata.featurize.family_settings import AudioSettings, MotionSettings, cli_settings
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.schema_arrays import SCHEMA_PATH, generated_schema_text
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader
from dancedata.synth.aist import synth_aist
from tests.featurize.test_motion_families import write_npz_model
from tests.helpers import run_cli

ROOT = Path(__file__).resolve().parents[2]
MOTION = ["rotations", "positions", "kinematics", "angular", "geometric"]
MOTION += ["rotations_from_positions", "laban", "angular_derivatives"]
AUDIO = ["fact", "stems", "nmfd", "mel96", "stft_frames", "tempogram"]
AUDIO.append("bailando_beats")


# ----------------------------------------------------------------------------- registry


def test_featurize_help_names_every_family_it_accepts() -> None:
    """The --motion-families / --audio-families help lists every registered family by name."""
    import re

    out = run_cli("featurize", "--help", env={"COLUMNS": "200"}).stdout
    words = set(re.findall(r"[a-z_0-9]+", out))
    missing = sorted(name for name in registered() if name not in words)
    assert not missing, f"featurize --help does not name {missing}"


def test_every_family_is_registered_once_by_group() -> None:
    assert sorted(registered("motion")) == sorted(MOTION)
    assert sorted(registered("audio")) == sorted(AUDIO)
    assert sorted(registered()) == sorted(MOTION + AUDIO)
    for name, family in registered().items():
        assert family.name == name and isinstance(family, Family) and family.outputs, name


def test_register_family_refuses_a_second_family_of_the_same_name() -> None:
    with pytest.raises(ValueError, match="two families named 'kinematics'"):

        @register_family("kinematics")
        class Impostor(MotionFamily):
            pass

    with pytest.raises(TypeError, match="subclasses MotionFamily or AudioFamily"):

        @register_family("groupless")
        class Groupless(Family):
            pass

    assert "groupless" not in registered()


def test_run_order_puts_producers_first_and_refuses_circles() -> None:
    motion = registered("motion")
    outputs = {name: [s.path for s in f.outputs] for name, f in motion.items()}

    def order(*names: str) -> list[str]:
        families = [motion[n] for n in names]
        return [f.name for f in run_order(families, lambda f: outputs[f.name])]

    assert order("kinematics", "angular", "positions") == ["angular", "positions", "kinematics"]
    assert order("geometric", "kinematics", "positions") == ["positions", "geometric", "kinematics"]
    assert order("rotations", "angular") == ["rotations", "angular"]  # no edge: as asked
    assert order("rotations", "rotations_from_positions") == [
        "rotations_from_positions",
        "rotations",
    ]  # rotations reads the solved axis_angle
    with pytest.raises(InputError, match="in a circle"):
        order("positions", "rotations_from_positions")  # each reads the other's output


# ----------------------------------------------------------------------------- declarations


def _fits(declared: tuple[ArraySpec, ...], written: list[ArraySpec], n_joints: int) -> list[str]:
    by_path = {s.path: s for s in declared}
    return [
        s.path for s in written if s.path not in by_path or not by_path[s.path].matches(s, n_joints)
    ]


@pytest.mark.parametrize("n_joints", [24, 19])
def test_motion_arrays_written_match_the_declared_outputs(n_joints: int, tmp_path: Path) -> None:
    settings = MotionSettings(
        representations=KNOWN_REPRESENTATIONS,
        euler_order="XYZ",
        smpl_model=str(write_npz_model(tmp_path / "smpl.npz")),
    )
    for name, family in registered("motion").items():
        written = family.arrays(n_joints, settings)
        assert written and not _fits(family.outputs, written, n_joints), name
    # Every representation is declared, so the schema lists each.
    rotations = registered("motion")["rotations"]
    assert [s.path for s in rotations.outputs] == list(KNOWN_REPRESENTATIONS)


def test_audio_arrays_written_match_the_declared_outputs() -> None:
    for cfg in (AudioFeatureConfig(), AudioFeatureConfig(fps=30.0)):
        for settings in (AudioSettings(), AudioSettings(stft_sr=32000, tempogram_frames=100)):
            for name, family in registered("audio").items():
                written = family.arrays(cfg, settings)
                assert written and not _fits(family.outputs, written, 0), name
                assert {s.path for s in written} == {s.path for s in family.outputs}, name


def test_a_declared_spec_rejects_what_it_does_not_declare() -> None:
    declared = ArraySpec("velocity", ("J", 3), np.float32, required_attrs=("units",))
    good = ArraySpec("velocity", (24, 3), np.float32, {"units": "m/s"})
    assert declared.matches(good, 24)
    assert not declared.matches(good, 19)  # J
    assert not declared.matches(replace(good, dtype=np.float64), 24)
    assert not declared.matches(replace(good, attrs={}), 24)  # a required attr missing
    assert not declared.matches(replace(good, path="jerk"), 24)
    assert ArraySpec("t", (None,), np.float32).matches(ArraySpec("t", (7,), np.float32), 0)


# ----------------------------------------------------------------------------- schema


@pytest.mark.slow
def test_committed_schema_arrays_are_the_generated_ones() -> None:
    committed = SCHEMA_PATH.read_text(encoding="utf-8")
    assert generated_schema_text(committed) == committed, (
        "schemas/store.schema.json differs from the declared arrays: run "
        "python -m dancedata.featurize.schema_arrays"
    )
    check = subprocess.run(
        [sys.executable, "-m", "dancedata.featurize.schema_arrays", "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert check.returncode == 0, check.stderr


@pytest.mark.slow
def test_schema_check_fails_on_a_hand_edited_array(tmp_path: Path) -> None:
    edited = tmp_path / "store.schema.json"
    text = SCHEMA_PATH.read_text(encoding="utf-8")
    edited.write_text(text.replace('"motion/trans": {"dtype": "float32"', '"motion/trans": '
                                   '{"dtype": "float64"'))  # fmt: skip
    assert edited.read_text() != text
    check = subprocess.run(
        [sys.executable, "-m", "dancedata.featurize.schema_arrays", "--check", str(edited)],
        capture_output=True,
        text=True,
    )
    assert check.returncode == 1 and "differ from the declared arrays" in check.stderr
    subprocess.run(
        [sys.executable, "-m", "dancedata.featurize.schema_arrays", str(edited)], check=True
    )
    assert edited.read_text() == text


# ----------------------------------------------------------------------------- CLI options


@pytest.mark.slow
def test_featurize_options_come_from_the_settings_fields() -> None:
    from dancedata.cli.main import build_command

    featurize_command = build_command().commands["featurize"]
    options = {p.name: p for p in featurize_command.params if p.name != "store"}
    for cls in (MotionSettings, AudioSettings):
        for setting in cli_settings(cls):
            option = options[setting.name]
            assert option.opts == ["--" + setting.name.replace("_", "-")]
            assert option.default == setting.default, setting.name
            assert option.help == setting.help
    for option, low in (("--stft-sr", "999"), ("--nmfd-iterations", "0")):  # below the minimum
        proc = run_cli("featurize", "no-store", option, low, check=False)
        assert proc.returncode == 2 and option in proc.stderr, proc.stderr
    assert "stems_device" not in options  # a field without help is no option


# ----------------------------------------------------------------------------- one run


def _aist_store(tmp_path: Path, name: str) -> Path:
    raw = tmp_path / "raw"
    if not raw.exists():
        synth_aist(raw, n_sequences=3, seed=3, workers=1)
    store = tmp_path / name
    ingest_aist(store, raw, AistIngestOptions())
    return store


def _arrays(store: Path) -> dict[str, np.ndarray]:
    reader = _VersionReader(store)
    return {n: np.asarray(reader.array(n)[:]) for n in reader.array_names()}


@pytest.mark.slow
def test_positions_then_kinematics_in_one_run_equal_two_runs(tmp_path: Path, monkeypatch) -> None:
    model = write_npz_model(tmp_path / "smpl.npz")
    monkeypatch.setenv("DANCEDATA_SMPL_MODEL", str(model))
    derived = ["kinematics", "geometric"]

    two = _aist_store(tmp_path, "two")
    featurize(two, FeaturizeOptions(audio=False, motion_families=["positions"]))
    featurize(two, FeaturizeOptions(audio=False, motion_families=derived))

    one = _aist_store(tmp_path, "one")
    # Asked in the wrong order: positions runs first all the same.
    options = FeaturizeOptions(audio=False, motion_families=[*derived, "positions"])
    result = featurize(one, options)
    assert result.counts["motion_absent"] == {}
    assert StoreLayout(one).committed_versions() == ["v1", "v2"]

    got, want = _arrays(one), _arrays(two)
    assert set(got) == set(want)
    for name in ("motion/positions", "motion/velocity", "motion/kinetic_features",
                 "motion/geometric_features", "motion/motion_beats_mint"):  # fmt: skip
        assert name in got
    for name, values in want.items():
        assert got[name].dtype == values.dtype, name
        np.testing.assert_array_equal(got[name], values, err_msg=name)  # NaN equal NaN

    # Without the producer in the run, the store still lacks positions: reported absent.
    alone = _aist_store(tmp_path, "alone")
    options = FeaturizeOptions(audio=False, motion_families=["rotations", *derived])
    result = featurize(alone, options)
    assert set(result.counts["motion_absent"]) == set(derived)


def test_families_reading_each_other_are_refused_with_one_line(tmp_path: Path) -> None:
    store = _aist_store(tmp_path, "aist")
    both = ["positions", "rotations_from_positions"]
    options = FeaturizeOptions(audio=False, motion_families=both)
    with pytest.raises(InputError, match="read each other's arrays in a circle"):
        featurize(store, options)
    assert StoreLayout(store).committed_versions() == ["v1"]


def test_the_smpl_model_reaches_worker_processes_inside_the_task(
    tmp_path: Path, monkeypatch
) -> None:
    """``smpl_model`` travels in the options (and so in every task), not in the environment:
    with the variable unset, two worker processes pose with the given model file, and the
    positions equal a serial run's."""
    import hashlib

    monkeypatch.delenv("DANCEDATA_SMPL_MODEL", raising=False)
    model = write_npz_model(tmp_path / "smpl.npz")
    runs = {}
    for workers in (1, 2):
        store = _aist_store(tmp_path, f"w{workers}")
        options = FeaturizeOptions(
            audio=False, motion_families=["positions"], smpl_model=str(model), workers=workers
        )
        featurize(store, options)
        runs[workers] = _VersionReader(store).array("motion/positions")
    sha = hashlib.sha256(model.read_bytes()).hexdigest()
    assert runs[2].attrs["smpl_model"]["sha256"] == sha
    np.testing.assert_array_equal(runs[2][:], runs[1][:])
    builtin = _aist_store(tmp_path, "builtin")
    featurize(builtin, FeaturizeOptions(audio=False, motion_families=["positions"], workers=2))
    assert "smpl_model" not in _VersionReader(builtin).array("motion/positions").attrs
