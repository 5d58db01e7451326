"""Bailando's music beats (docs/METRICS.md, "Music beats"), as a pure function of a mono signal.

Bailando (Li et al., CVPR 2022) scores its beat alignment against its own beats, column 53 of
its music features (``extractor.py``, ``_prepro_aistpp.py``): the track at 30720 Hz
(= 60 fps × hop 512), the percussive part of a harmonic/percussive separation
(``librosa.effects.hpss``, defaults), its onset strength with a *median* over mel bands
(``librosa.onset.onset_strength(aggregate=np.median)``), then ``librosa.beat.beat_track`` with
librosa's defaults (start_bpm 120, tightness 100): no known tempo. The FACT beats of the store
(:func:`dancedata.compute.audio_features.beats`) track the mix's mean onset strength seeded with
the music's BPM, so the two beat sets differ.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BAILANDO_HOP", "BAILANDO_SR", "bailando_beats", "bailando_onset_envelope"]

BAILANDO_SR = 30720  # Hz: 15360 * 2 in Bailando's preprocessing, 60 frames per second
BAILANDO_HOP = 512  # librosa's default hop


def bailando_onset_envelope(y: np.ndarray, sr: int, hop_length: int = BAILANDO_HOP) -> np.ndarray:
    """(A,) float onset strength of the percussive component, median over mel bands."""
    import librosa

    y = np.asarray(y, dtype=np.float32)
    _, percussive = librosa.effects.hpss(y)
    return librosa.onset.onset_strength(
        y=percussive, sr=sr, hop_length=hop_length, aggregate=np.median
    )


def bailando_beats(y: np.ndarray, sr: int, hop_length: int = BAILANDO_HOP) -> np.ndarray:
    """(A,) uint8 one-hot of Bailando's beats of the mono signal ``y`` at ``sr`` Hz, one row per
    ``hop_length`` samples (A = 1 + len(y) // hop_length)."""
    import librosa

    env = bailando_onset_envelope(y, sr, hop_length)
    _, frames = librosa.beat.beat_track(
        onset_envelope=env, sr=sr, hop_length=hop_length, units="frames"
    )
    out = np.zeros(env.shape[0], dtype=np.uint8)
    frames = np.asarray(frames, dtype=np.int64)
    out[frames[(frames >= 0) & (frames < env.shape[0])]] = 1
    return out
