"""``bailando_beats``: Bailando's music beats as an audio family, computed only on request
(``--audio-families bailando_beats``).

``audio/beats_bailando`` (A,) uint8, 1 on Bailando's beats (:mod:`dancedata.compute.bailando_beats`:
HPSS percussive part, median onset strength, ``beat_track`` with librosa's defaults), at the
store's feature rate (sr = fps × hop; Bailando's 30720 Hz at 60 fps). ``evaluate
--beat-source bailando`` scores the beat metrics against it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.featurize.families.audio_base import (
    ArraySpec,
    AudioFamily,
    AudioSettings,
    TrackAudio,
)
from dancedata.featurize.family import register_family


@register_family("bailando_beats")
class BailandoBeatsFamily(AudioFamily):
    """Bailando's beat one-hot (its music feature column 53)."""

    outputs = (
        ArraySpec(
            "beats_bailando",
            (),
            np.uint8,
            required_attrs=("recipe",),
            extension=True,
            note="Bailando's music beats (HPSS percussive, median onset, beat_track defaults)",
        ),
    )

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        attrs = {
            "recipe": "librosa.effects.hpss -> onset_strength(aggregate=median) -> beat_track "
            "(start_bpm 120, tightness 100)",
            "convention": "Bailando extractor.py get_onset_beat",
            "sr": cfg.sr,
            "hop_length": cfg.hop_length,
        }
        return [ArraySpec("beats_bailando", (), np.uint8, attrs)]

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        from dancedata.compute.bailando_beats import bailando_beats

        return {"beats_bailando": bailando_beats(track.y, track.cfg.sr, track.cfg.hop_length)}

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        return {"recipe": "bailando_get_onset_beat"}
