"""Named evaluation conventions: the settings a paper's table row was computed with.

``dancedata evaluate --convention NAME`` sets the :class:`EvaluateParams` fields of NAME (options
given explicitly on the command line still win) and records ``params.convention = NAME``; the
printed summary then ends with the paper's row, its metrics in the paper's order.

* ``bailando`` — Bailando (Li et al., CVPR 2022), ``utils/metrics_new.py`` and
  ``utils/beat_align_score.py``: FID_k, FID_g (its "FID_m") and diversity Div_k, Div_g on each
  generated sequence's first 1200 frames (``pred_position[:1200]``), the first frame's root
  subtracted from every joint; reference = every ground-truth sequence, whole, also
  root-subtracted (``extract_aist_features.py``: ``aist_features_zero_start``); both sets
  z-scored by the reference's statistics; sqrtm retried with ε = 1e-5. Its beat score (BAS,
  ``bas_bailando``: music → motion, σ = 3, motion beats at minima of the σ = 5 smoothed mean joint
  speed) on the whole sequence, against Bailando's own music beats (column 53 of its music
  features: ``beat_source = "bailando"``, ``audio/beats_bailando``, made by ``featurize
  --audio-families bailando_beats``; without that array the beat metrics are listed as unscored
  with that command), recorded in the result.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from dancedata.errors import InputError

__all__ = ["CONVENTIONS", "Convention", "convention_named"]


@dataclass(frozen=True)
class Convention:
    """A named preset: the parameter values it sets and the row it reports."""

    name: str
    summary: str
    params: dict[str, Any]
    row: tuple[tuple[str, str], ...]  # (metric, the paper's column header)


CONVENTIONS: dict[str, Convention] = {
    "bailando": Convention(
        name="bailando",
        summary=(
            "Bailando: FID/Div on the first 1200 frames, first-frame root subtracted, against "
            "all ground truth (whole); BAS (bas_bailando) on whole sequences against Bailando's "
            "music beats (audio/beats_bailando)"
        ),
        params={
            "feature_max_frames": 1200,
            "max_frames": None,
            "skip_frames": 0,
            "fid_unit": "sequence",
            "fid_reference": "all_gt",
            "fid_origin": "first_frame_root",
            "fid_eps": 1e-5,
            "normalize": True,
            "drop_constant_ref_columns": False,
            "kinetic_mode": "parity",
            "bas_sigma": 3.0,
            "bailando_smoothing_sigma": 5.0,
            "beat_source": "bailando",
        },
        row=(
            ("fid_k", "FID_k"),
            ("fid_g", "FID_g"),
            ("div_k", "Div_k"),
            ("div_g", "Div_g"),
            ("bas_bailando", "BAS"),
        ),
    ),
}


def convention_named(name: str) -> Convention:
    """The preset called ``name``; InputError listing the known ones otherwise."""
    try:
        return CONVENTIONS[name]
    except KeyError:
        known = ", ".join(sorted(CONVENTIONS))
        raise InputError(f"unknown evaluate convention {name!r}; known: {known}") from None
