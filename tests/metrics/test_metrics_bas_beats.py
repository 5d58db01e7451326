"""``bas_beats``: which music beats bas_mint matches. ``whole_track_mint`` is mint's
generated-motion path (tools/calculate_beat_scores.py @ 83d64b9: ``audio_feature[:, -1]``, the
whole track's beats, then ``[120:]`` of both), checked against mint's code transcribed in
tests/metrics/test_metrics_reference.py, on clips where it differs from ``motion_span``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dancedata.metrics.beats import bas_mint
from tests.helpers import run_cli
from tests.metrics.test_metrics_reference import (
    dance,
    ref_mint_alignment_score,
    ref_mint_motion_peak_onehot,
)
from tests.study.test_evaluate import SPLIT, fact_rows, model_path, noisy_motion, store  # noqa: F401


def _track(rng: np.random.Generator, n_frames: int) -> np.ndarray:
    """A track's per-frame beat one-hot: a beat every 28–36 frames, ±2 frames of jitter."""
    step = int(rng.integers(28, 37))
    beats = np.arange(int(rng.integers(0, step)), n_frames, step)
    beats = np.clip(beats + rng.integers(-2, 3, size=beats.size), 0, n_frames - 1)
    onehot = np.zeros(n_frames, dtype=np.float32)
    onehot[beats] = 1.0
    return onehot


def _mint_generated(joints: np.ndarray, track_onehot: np.ndarray, skip: int) -> float:
    """mint's generated-motion path on one clip: motion beats on the whole clip, the track's
    beats (longer than the clip), both from frame ``skip``."""
    peaks = ref_mint_motion_peak_onehot(joints)
    return ref_mint_alignment_score(track_onehot[skip:], peaks[skip:], sigma=3)


def test_whole_track_mint_equals_mint_generated_path_where_motion_span_differs() -> None:
    differ = 0
    for seed in range(32):
        rng = np.random.default_rng(seed)
        joints = dance(rng)
        track = _track(rng, joints.shape[0] + 60)  # the music runs 1 s longer
        beats = np.flatnonzero(track)
        for skip in (0, 120):
            ref = _mint_generated(joints, track, skip)
            ours = bas_mint(joints, beats, skip_frames=skip, beats="whole_track_mint")
            assert ours == pytest.approx(ref, abs=1e-6)
            span = bas_mint(joints, beats, skip_frames=skip, beats="motion_span")
            ref_span = ref_mint_alignment_score(
                track[skip : joints.shape[0]], ref_mint_motion_peak_onehot(joints)[skip:]
            )
            assert span == pytest.approx(ref_span, abs=1e-6)
            differ += abs(ours - span) > 1e-9
    assert differ >= 3, differ


def test_bas_beats_is_checked() -> None:
    from dancedata.errors import InputError
    from dancedata.study.scoring import EvaluateParams

    with pytest.raises(ValueError, match="beats must be one of motion_span, whole_track_mint"):
        bas_mint(np.zeros((30, 24, 3)), np.array([3]), beats="all")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="bas_beats"):
        EvaluateParams(bas_beats="all")


@pytest.mark.slow
def test_evaluate_whole_track_mint_keeps_beats_after_the_last_motion_frame(
    store: Path,  # noqa: F811
    model_path: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    """Generated motion shorter than the track: evaluate --bas-beats whole_track_mint
    --skip-frames 120 equals mint's generated path on the store's beats to the track's end,
    and the record names the convention."""
    import dancedata
    from dancedata.compute.smpl_joints import smpl_joint_positions
    from dancedata.io.smpl_model import load_smpl_model

    motion = noisy_motion(store, seed=5)
    gen = tmp_path / "gen"
    gen.mkdir()
    cut = {}
    for seq, (aa, trans) in motion.items():
        n = min(len(aa), 400)  # stop well before the music does
        cut[seq] = (aa[:n], trans[:n])
        np.save(gen / f"{seq}.npy", fact_rows(*cut[seq]))
    values = {}
    for mode in ("motion_span", "whole_track_mint"):
        out = tmp_path / mode
        run_cli("evaluate", str(store), "--generated", str(gen), *SPLIT,
                "--smpl-model", str(model_path), "--skip-frames", "120",
                "--bas-beats", mode, "--out", str(out))  # fmt: skip
        record = json.loads((out / "results.json").read_text())
        row = next(r for r in record["results"] if r["metric"] == "bas_mint")
        assert row["convention"]["music_beats_span"] == mode
        values[mode] = row["value"]
    s = dancedata.open_store(store)
    model = load_smpl_model(model_path)
    whole, span = [], []
    for seq in s.seq_ids(split="train"):
        joints = smpl_joint_positions(model, *cut[seq])
        track = np.asarray(s.audio_to_track_end(seq, "beats"))
        assert len(track) > len(joints)
        whole.append(_mint_generated(joints, track, 120))
        peaks = ref_mint_motion_peak_onehot(joints)
        span.append(ref_mint_alignment_score(track[120 : len(joints)], peaks[120:]))
    assert values["whole_track_mint"] == pytest.approx(float(np.mean(whole)), abs=1e-6)
    assert values["motion_span"] == pytest.approx(float(np.mean(span)), abs=1e-6)
