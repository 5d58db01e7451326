"""Looking at a store: sequence figures (:mod:`dancedata.viz.plot`), the dataset report page
(:mod:`dancedata.viz.report`) and skeleton videos (``dancedata.viz.render``).

Everything here needs the optional ``viz`` extra (``pip install 'dancedata[viz]'``: matplotlib
and PyAV). Importing this package imports neither; the names below load their module on first
use, and a missing extra is one clear error (:func:`dancedata.viz.extras.require`).

    from dancedata.viz import sequence_figure, build_report
    fig = sequence_figure(store, seq_id)          # matplotlib Figure, Agg canvas
    html = build_report("data/stores/aist-demo")  # self-contained HTML page
"""

from __future__ import annotations

from typing import Any

_LAZY = {
    "sequence_figure": "dancedata.viz.plot",
    "build_report": "dancedata.viz.report",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dancedata.viz' has no attribute {name!r}")
