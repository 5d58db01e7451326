"""The thesis's layouts and weighted onset curves (docs/STORE.md, CONTRACT.md §3).

* ``thesis_euler_75`` — root translation (3, metres) and 24 joints' Euler angles (72, radians).
* ``thesis_audio_22`` — M_full: MFCC (20), onset envelope (1), onset peaks (1, 0/1).
* ``thesis_stems_88`` — the 22-d M_full of each stem, stems in contract order: drums, bass,
  vocals, other.

The weighted curves (Σ_stem w · onset_env_stem, Σ_c w_c · NMFD activation_c) are computed by
:func:`dancedata.compute.stem_features.weighted_stem_onsets` and
:func:`dancedata.compute.nmfd.weighted_nmfd_activation`; this module only reads their inputs
from the store and checks the weights' names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dancedata.errors import StoreError

if TYPE_CHECKING:
    from dancedata.read.sequence_reader import _SequenceReader

STEM_ORDER: tuple[str, ...] = ("drums", "bass", "vocals", "other")

THESIS_VIEWS: dict[str, list[tuple[str, str]]] = {
    "thesis_euler_75": [("motion", "trans"), ("motion", "euler")],
    "thesis_audio_22": [("audio", "mfcc"), ("audio", "onset_env"), ("audio", "onset_peaks")],
    "thesis_stems_88": [
        ("audio", f"stems/{stem}/{feature}")
        for stem in STEM_ORDER
        for feature in ("mfcc", "onset_env", "onset_peaks")
    ],
}


def weighted_stem_onsets(
    store: _SequenceReader,
    seq_id: str,
    weights: dict[str, float] | None = None,
    normalize: bool = False,
) -> np.ndarray:
    """The weighted stem onset curve of ``seq_id``, (audio frames,) float32, from the stored
    per-stem onset envelopes. ``weights`` maps stem → weight (default all 1; stems absent from
    it weigh 0 unless it is None); ``normalize`` divides each curve by its maximum over the
    sequence first. StoreError for an unknown stem or a store without stems."""
    from dancedata.compute.stem_features import DEFAULT_STEM_WEIGHTS
    from dancedata.compute.stem_features import weighted_stem_onsets as weighted

    weights = DEFAULT_STEM_WEIGHTS if weights is None else weights
    unknown = sorted(set(weights) - set(DEFAULT_STEM_WEIGHTS))
    if unknown:
        raise StoreError(f"unknown stem(s) {unknown}; stems are {list(DEFAULT_STEM_WEIGHTS)}")
    onsets = {
        stem: store.stem_audio(seq_id, stem, "onset_env")
        for stem, weight in weights.items()
        if float(weight) != 0.0
    }
    if not onsets:
        return np.zeros(store.audio_frames(seq_id), dtype=np.float32)
    return weighted(onsets, weights, normalize=normalize)


def weighted_nmfd(
    store: _SequenceReader,
    seq_id: str,
    weights: dict[str, float] | None = None,
    normalize: bool = False,
) -> np.ndarray:
    """The weighted NMFD activation curve of ``seq_id`` over the kick, snare and hi-hat
    columns of ``audio/nmfd_drums``, (audio frames,) float32. ``weights`` maps component →
    weight (default all 1); ``normalize`` divides each column by its maximum first."""
    from dancedata.compute.nmfd import weighted_nmfd_activation

    activations = store.audio_or_hint(
        seq_id, "nmfd_drums", "run `dancedata featurize` with the nmfd family"
    )
    return weighted_nmfd_activation(activations, weights, normalize=normalize)
