"""Audio feature families: each computes a set of ``audio/...`` arrays from one music track.

featurize runs every requested family on each track once (never once per sequence), through a
:class:`TrackAudio` that decodes the track at ``cfg.sr`` on first use and shares intermediate
results between families (the stems feed both ``stems`` and ``nmfd``). A family declares the
arrays it writes (path, row shape, dtype, attrs) and computes them; all arrays run at the motion
frame rate (cfg.fps frames per second) and are trimmed to a common length per track. Each
family's results per track are kept in the feature cache (:mod:`dancedata.featurize.feature_cache`).

Families (:data:`FAMILIES`); the default set is :data:`DEFAULT_FAMILIES`:

==============  ==========================================================================
``fact``        onset_env, mfcc, chroma_cens, onset_peaks, beats (the FACT 35-d parts)
``stems``       stems/<stem>/{onset_env, mfcc, onset_peaks} for drums, bass, vocals, other
``nmfd``        nmfd_drums (A, 3): kick, snare, hi-hat activations of the drums stem
``mel96``       mel96 (A, 96): ChoreoGraph's mel spectrogram (on request)
``stft_frames`` stft_frames (A, 1025, k): per-motion-frame STFT of the genre study (on request)
``tempogram``   tempogram (A, 384) (on request)
==============  ==========================================================================

Every family registers itself (``@register_family``, :mod:`dancedata.featurize.family`); the
registry loads every ``audio*`` module of ``featurize/families/``, and :data:`FAMILIES` (the
registered audio families) stays importable from here. To add a family, subclass
:class:`AudioFamily` in a new ``audio_<name>.py`` module and decorate it with
``@register_family("<name>")``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig, fact_features
from dancedata.featurize.families.audio_base import (
    ArraySpec,
    AudioFamily,
    AudioSettings,
    TrackAudio,
)
from dancedata.featurize.family import register_family, registered

__all__ = [
    "DEFAULT_FAMILIES",
    "STEM_FAMILIES",
    "ArraySpec",
    "AudioFamily",
    "AudioSettings",
    "FactFamily",
    "TrackAudio",
    "default_families",
    "family_problems",
    "group_attrs",
]


_CFG = AudioFeatureConfig()


@register_family("fact")
class FactFamily(AudioFamily):
    """The FACT / AIST++ 35-d ingredients (see :mod:`dancedata.compute.audio_features`)."""

    outputs = (
        ArraySpec("onset_env", (), np.float32),
        ArraySpec("mfcc", (_CFG.n_mfcc,), np.float32),
        ArraySpec("chroma_cens", (_CFG.n_chroma,), np.float32),
        ArraySpec("onset_peaks", (), np.uint8),
        ArraySpec("beats", (), np.uint8),
    )
    uses_bpm = True  # beats: beat_track(start_bpm=the music's BPM)

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
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

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        return fact_features(track.y, track.bpm, track.cfg, track.stft())


DEFAULT_FAMILIES: tuple[str, ...] = ("fact", "stems", "nmfd")
STEM_FAMILIES: tuple[str, ...] = ("stems", "nmfd")


def __getattr__(name: str) -> Any:
    """``FAMILIES``: the registered audio families (every audio* module of families/), by name."""
    if name == "FAMILIES":
        return registered("audio")
    raise AttributeError(name)


def default_families(settings: AudioSettings | None = None) -> list[str]:
    """:data:`DEFAULT_FAMILIES`, without the stem families when ``settings.stems`` is none."""
    stems = (settings or AudioSettings()).stems
    return [n for n in DEFAULT_FAMILIES if stems != "none" or n not in STEM_FAMILIES]


def family_problems(names: list[str], settings: AudioSettings) -> list[str]:
    """One line per unknown family, or per family that cannot run with ``settings``."""
    families = registered("audio")
    problems = [
        f"unknown audio feature family {name!r}; choose from {sorted(families)}"
        for name in names
        if name not in families
    ]
    for name in names:
        if name in families:
            reason = families[name].check(settings)
            if reason:
                problems.append(f"audio family {name!r} {reason}")
    return problems


def group_attrs(
    names: list[str] | tuple[str, ...], cfg: AudioFeatureConfig, settings: AudioSettings
) -> dict[str, dict[str, Any]]:
    """Attrs of the groups under ``audio`` that the families ``names`` describe."""
    out: dict[str, dict[str, Any]] = {}
    families = registered("audio")
    for name in names:
        for group, attrs in families[name].group_attrs(cfg, settings).items():
            out.setdefault(group, {}).update(attrs)
    return out
