"""Audio feature families: each computes a set of ``audio/...`` arrays from one music track.

featurize decodes every track once at ``cfg.sr`` and hands the samples to every requested
family, so a song's features are computed once whatever number of sequences share it. A family
declares the arrays it writes (path, row shape, dtype, attrs) and computes them; all arrays run
at the motion frame rate (cfg.fps frames per second) and are trimmed to a common length per track.

To add a family, subclass :class:`AudioFamily` and add an instance to :data:`FAMILIES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig, fact_features


@dataclass(frozen=True)
class ArraySpec:
    """One array a family writes, relative to the ``audio`` group."""

    path: str
    row_shape: tuple[int, ...]
    dtype: Any
    attrs: dict[str, Any] | None = None


class AudioFamily:
    """Base class: ``name``, ``arrays`` and ``compute``; ``config`` lists its settings."""

    name: str = ""

    def arrays(self, cfg: AudioFeatureConfig) -> list[ArraySpec]:
        raise NotImplementedError

    def compute(
        self, y: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig
    ) -> dict[str, np.ndarray]:
        """Arrays keyed by :attr:`ArraySpec.path`, each with one row per feature frame."""
        raise NotImplementedError

    def config(self) -> dict[str, Any]:
        return {}


class FactFamily(AudioFamily):
    """The FACT / AIST++ 35-d ingredients (see :mod:`dancedata.compute.audio_features`)."""

    name = "fact"

    def arrays(self, cfg: AudioFeatureConfig) -> list[ArraySpec]:
        return [
            ArraySpec("onset_env", (), np.float32, {"recipe": "librosa.onset.onset_strength"}),
            ArraySpec("mfcc", (cfg.n_mfcc,), np.float32, {"recipe": "librosa.feature.mfcc"}),
            ArraySpec(
                "chroma_cens",
                (cfg.n_chroma,),
                np.float32,
                {"recipe": "librosa.feature.chroma_cens"},
            ),
            ArraySpec("onset_peaks", (), np.uint8, {"recipe": "librosa.onset.onset_detect"}),
            ArraySpec(
                "beats",
                (),
                np.uint8,
                {"recipe": "librosa.beat.beat_track(start_bpm=music bpm, tightness)"},
            ),
        ]

    def compute(
        self, y: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig
    ) -> dict[str, np.ndarray]:
        return fact_features(y, bpm, cfg)


FAMILIES: dict[str, AudioFamily] = {"fact": FactFamily()}
DEFAULT_FAMILIES: tuple[str, ...] = ("fact",)
