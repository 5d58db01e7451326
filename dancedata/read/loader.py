"""Read a store back: what users open. The thin reader plus the views, as methods.

    import dancedata
    store = dancedata.open_store("data/stores/aist-demo")
    store.motion("gBR_sBM_cAll_d01_mBR1_ch01", "rotmat")      # (F, 24, 3, 3)
    store.view("gBR_sBM_cAll_d01_mBR1_ch01", "fact_motion_225")  # (F, 225)
    for m in store.iter_measures(split="train"):               # crossmodal scheme by default
        m.motion, m.audio                                     # (frames, 225), (frames, 35)

:class:`DanceStore` is :class:`dancedata.read.sequence_reader._SequenceReader` (tables, per-sequence
arrays, aligned audio, splits, measures table; nothing derived) with one-line methods for what
is built on it, each in its own module: the paper views (:mod:`dancedata.read.views.assemble`,
layouts in :mod:`dancedata.read.views.fact` and :mod:`dancedata.read.views.thesis`), the measure
windows (:mod:`dancedata.read.views.measures`) and the AIST++ cameras
(:mod:`dancedata.read.views.cameras`).

Arrays are read whole into memory on first use and kept (a store's arrays are immutable), so
random access afterwards costs a numpy slice. For stores larger than memory, read slices through
:meth:`DanceStore.zarr` instead.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dancedata.read.sequence_reader import _SequenceReader
from dancedata.read.views import assemble, measures, thesis
from dancedata.read.views.cameras import sequence_cameras
from dancedata.read.views.layouts import AUDIO_VIEWS, MOTION_VIEWS, VIEWS, ViewSpec
from dancedata.read.views.measures import MeasureWindow
from dancedata.read.views.normalization import ArrayStats, normalization

if TYPE_CHECKING:
    from dancedata.read.cameras import CameraSet
    from dancedata.read.windows import MeasureWindows

__all__ = [
    "AUDIO_VIEWS",
    "MOTION_VIEWS",
    "VIEWS",
    "DanceStore",
    "MeasureWindow",
    "open_store",
]


class DanceStore(_SequenceReader):
    """A committed version of a store, opened for reading (see the module docstring)."""

    # -- paper views ---------------------------------------------------------------------------
    def view(self, seq_id: str, name: ViewSpec) -> np.ndarray:
        """A derived layout as float32 (frames, D): fact_motion_225, thesis_euler_75,
        fact_audio_35, thesis_audio_22 (CONTRACT.md §3) or thesis_stems_88 (the 22-d
        per stem: drums, bass, vocals, other; docs/STORE.md); or array paths
        (``"motion/quat"``, a list of them) side by side, each flattened."""
        return assemble.sequence_view(self, seq_id, name)

    def view_parts(self, name: ViewSpec) -> list[np.ndarray | None]:
        """The arrays of view ``name`` over the whole store (see
        :func:`dancedata.read.views.assemble.view_parts`)."""
        return assemble.view_parts(self, name)

    def weighted_stem_onsets(
        self,
        seq_id: str,
        weights: dict[str, float] | None = None,
        normalize: bool = False,
    ) -> np.ndarray:
        """The thesis's weighted stem onset curve Σ_stem w_stem · onset_env_stem, (frames,)
        float32, from the stored per-stem onset envelopes (nothing extra is stored).
        ``weights`` maps stem → weight (default all 1; stems absent from it weigh 0 unless
        it is None); ``normalize`` divides each curve by its maximum over the sequence first."""
        return thesis.weighted_stem_onsets(self, seq_id, weights, normalize)

    def weighted_nmfd(
        self,
        seq_id: str,
        weights: dict[str, float] | None = None,
        normalize: bool = False,
    ) -> np.ndarray:
        """The thesis's weighted NMFD activation curve Σ_c w_c · activation_c over the kick,
        snare and hi-hat columns of ``audio/nmfd_drums``, (frames,) float32. ``weights`` maps
        component → weight (default all 1); ``normalize`` divides each column by its maximum
        over the sequence first."""
        return thesis.weighted_nmfd(self, seq_id, weights, normalize)

    # -- normalisation statistics --------------------------------------------------------------
    def normalization(self, array: str) -> ArrayStats:
        """Mean and std of ``array`` (e.g. ``"motion/quat"``) over the split ``dancedata stats``
        used, each of the array's row shape; normalise with
        ``dancedata.compute.normalization.normalize(x, s.mean, s.std)``."""
        return normalization(self, array)

    # -- AIST++ cameras ------------------------------------------------------------------------
    def cameras(self, seq_id: str) -> CameraSet:
        """The calibrated cameras of the sequence's AIST++ setting, in the view order of
        ``motion/keypoints2d``, with translation in metres (see :mod:`dancedata.read.cameras`)."""
        return sequence_cameras(self, seq_id)

    def projection_matrices(self, seq_id: str) -> np.ndarray:
        """(9, 3, 4) float64 P = K [R | t] per view, for world points in metres (no lens
        distortion: use :meth:`cameras` with ``cv2.projectPoints`` to include it)."""
        return self.cameras(seq_id).projection

    # -- measure windows -----------------------------------------------------------------------
    def measure_windows(
        self,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
    ) -> MeasureWindows:
        """Fast random access to the measures of ``split`` as view windows (a data loader's
        sampler): ``windows[i]`` gives (motion, audio) in a few microseconds. The table and
        zarr lookups happen here, once; :class:`MeasureWindows` gets only arrays."""
        return measures.measure_windows(self, split, scheme, motion, audio)

    def iter_measures(
        self,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
    ) -> Iterator[MeasureWindow]:
        """Every measure of the sequences in ``split``, with the chosen motion and audio views
        sliced to the measure. With an audio view, measures not fully covered by audio are
        left out."""
        return measures.iter_measures(self, split, scheme, motion, audio)


def open_store(path: str | Path, version: str | None = None) -> DanceStore:
    """Open ``version`` (default: the latest committed) of the store at ``path``."""
    return DanceStore(path, version)
