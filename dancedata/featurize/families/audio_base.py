"""What every audio feature family is built on: array specs, settings, the per-track context.

A family turns one music track into ``audio/...`` arrays with one row per feature frame (the
motion frame rate, ``cfg.fps``). It sees the track through a :class:`TrackAudio`, which decodes
the samples only when a family asks for them (a track whose every family comes from the feature
cache is never decoded) and holds intermediate results that several families share, such as the
four stems: ``track.shared(key, make)`` runs ``make`` once per track and key, so the stems are
separated once and feed both the per-stem features and the NMFD of the drums stem.

Families are stateless; what they compute is set by :class:`AudioSettings` (picklable, passed to
worker processes with the job) and by the FACT :class:`AudioFeatureConfig`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.featurize.family import ArraySpec, Family
from dancedata.featurize.family_settings import STEM_CHOICES, AudioSettings

__all__ = [
    "BASE_LIBRARIES",
    "STEM_CHOICES",
    "ArraySpec",
    "AudioFamily",
    "AudioSettings",
    "TrackAudio",
]

STFT_KEY = "stft"  # the mix's STFT in TrackAudio.shared

# Distributions whose versions can change any family's numbers (decoding, resampling, features).
BASE_LIBRARIES: tuple[str, ...] = ("librosa", "numpy", "scipy", "soundfile", "soxr")


class TrackAudio:
    """One music track as the families see it.

    ``y`` (mono float32 at ``cfg.sr`` Hz) is decoded from ``path`` on first use: at most its
    first ``span_s`` seconds (None: all of it), from the very bytes whose sha256 must equal
    ``sha256`` when given (see :func:`dancedata.featurize.music_inputs.decode_checked`).
    ``timings`` collects wall seconds of the decode (``decode``) and of every shared computation
    (by key); ``decoded_s`` the seconds of the file decoded.
    """

    def __init__(
        self,
        path: str,
        bpm: float | None,
        cfg: AudioFeatureConfig,
        *,
        y: np.ndarray | None = None,
        sha256: str | None = None,
        span_s: float | None = None,
    ) -> None:
        self.path = path
        self.bpm = bpm
        self.cfg = cfg
        self.sha256 = sha256
        self.span_s = span_s
        self.decoded_s: float | None = None
        self._y = y
        self._shared: dict[str, Any] = {}
        self.timings: dict[str, float] = {}

    @property
    def decoded(self) -> bool:
        return self._y is not None

    @property
    def y(self) -> np.ndarray:
        if self._y is None:
            from dancedata.featurize.music_inputs import decode_checked

            start = time.perf_counter()
            decoded = decode_checked(
                self.path, self.cfg.sr, self.sha256, self.span_s, res_type=self.cfg.res_type
            )
            self._y, self.decoded_s = decoded.y, decoded.decoded_s
            self.timings["decode"] = time.perf_counter() - start
        return self._y

    def shared(self, key: str, make: Callable[[], Any], timed: bool = True) -> Any:
        """``make()`` computed once per track and ``key`` (e.g. the stems of one backend).
        Its seconds are a step of their own in ``timings`` (less those of the shared steps it
        asked for), unless ``timed`` is false: then they count for whichever family or step
        asked first (a quick intermediate such as one STFT)."""
        if key not in self._shared:
            self.y  # noqa: B018 - decode first, so its time is not billed to ``key``
            if not timed:
                self._shared[key] = make()
                return self._shared[key]
            start = time.perf_counter()
            nested = self.shared_seconds()
            value = make()
            self.timings[key] = time.perf_counter() - start - (self.shared_seconds() - nested)
            self._shared[key] = value
        return self._shared[key]

    def stft(self) -> np.ndarray:
        """``librosa.stft`` of ``y`` with ``cfg.n_fft`` and ``cfg.hop_length`` (Hann, centred),
        computed once per track: the FACT features and the offline stems both start from it.
        Its time counts for the first family or step that asks for it."""
        from dancedata.compute.audio_features import stft

        return self.shared(STFT_KEY, lambda: stft(self.y, self.cfg), timed=False)

    def shared_seconds(self) -> float:
        """Seconds spent so far in the decode and in shared computations."""
        return float(sum(self.timings.values()))


class AudioFamily(Family):
    """Base of the audio families (:class:`~dancedata.featurize.family.Family` with group
    ``audio``, settings :class:`AudioSettings`): ``arrays``, ``compute`` (or
    ``compute_track``) and ``config``. Their input is the music track, not arrays.

    ``compute(y, bpm, cfg)`` suits a family that needs only the samples; a family that shares
    work with others overrides ``compute_track``. ``config`` lists every setting that changes
    the numbers (it goes into the manifest config, the fingerprint and the feature cache key);
    ``group_attrs`` gives attrs of groups under ``audio`` (e.g. the stem backend on
    ``audio/stems``).
    """

    group: ClassVar[str] = "audio"
    settings_type: ClassVar[type] = AudioSettings
    uses_bpm: bool = False  # the track's known tempo changes the numbers (cache key)

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        raise NotImplementedError

    def compute(
        self, y: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig
    ) -> dict[str, np.ndarray]:
        """Arrays keyed by :attr:`ArraySpec.path`, each with one row per feature frame."""
        raise NotImplementedError

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        return self.compute(track.y, track.bpm, track.cfg)

    def group_attrs(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> dict[str, dict[str, Any]]:
        return {}

    def libraries(self, settings: AudioSettings | None = None) -> tuple[str, ...]:
        """Distributions whose versions go into the family's feature-cache key."""
        return BASE_LIBRARIES
