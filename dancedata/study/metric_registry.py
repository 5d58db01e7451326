"""The metric registry: every metric ``evaluate`` (and ``experiment run``) computes registers here.

A metric is a class decorated ``@register_metric("<name>")`` in a module
``dancedata/study/metric_<name>.py`` (the registry imports every such module). It declares:

* ``outputs``: the result names it computes, in the order results are listed (``fid_k``, ...);
* ``needs``: what each scored sequence must hold (see :data:`NEEDS`: ``positions``, ``rows``,
  ``axis_angle``, ``music_beats``, ``measures``, ...; ``generations`` is a set-level input).
  A metric that needs no joint positions is computed from rotations alone and names no skeleton;
* ``settings_type``: a frozen settings dataclass; its fields made with :func:`setting` and a help
  text are ``evaluate`` options (``--field-name``, type and default from the field), and every
  field is recorded in the result's ``config.params``;
* ``compute(inputs, settings)``: the list of :class:`MetricResult` of its outputs, from a
  :class:`MetricInputs` (the sequences, the set-level inputs, and the helpers that record the
  sequences a metric could not use and why);
* ``rank``: its place in the listing (built-ins 10, 20, ...; a new metric defaults to after them);
* optionally ``experiment_outputs`` and ``score_reconstructions(cell, names)``: the outputs
  ``experiment run`` also computes on keyframe reconstructions (config ``metrics.names``).

Kept free of numpy, scipy and pyarrow: ``dancedata evaluate --help`` imports this module and the
metric modules (which import their maths inside ``compute``).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

from dancedata.errors import InputError
from dancedata.featurize.family_settings import setting

if TYPE_CHECKING:
    import numpy as np

    from dancedata.metrics.result import MetricResult

__all__ = [
    "NEEDS",
    "EvalSequence",
    "Metric",
    "MetricInputs",
    "ScoringSettings",
    "check_choices",
    "experiment_metric_names",
    "metric_names",
    "register_metric",
    "registered_metrics",
    "range_notes",
    "rotation_only_outputs",
    "settings_types",
    "unit_range_outputs",
    "unregister_metric",
]


def check_choices(settings: Any, allowed: dict[str, tuple[Any, ...]]) -> None:
    """InputError naming the first field of ``settings`` whose value is not one of its choices."""
    for name, options in allowed.items():
        if getattr(settings, name) not in options:
            raise InputError(
                f"{name} must be one of {', '.join(options)} for evaluate, "
                f"got {getattr(settings, name)!r}"
            )


@dataclass(frozen=True)
class ScoringSettings:
    """What every metric shares: the frame rate, the compared frames and the named preset."""

    fps: float = 60.0
    euler_order: str = "XYZ"
    skip_frames: int = setting(0, help="Frames to drop at the start of both (mint: 120).", min=0)
    max_frames: int | None = setting(
        None, help="Compare at most this many frames after --skip-frames (Bailando: 1200).", min=3
    )
    length: str = "common_min"
    # The named preset the other fields were set from (``evaluate --convention``), or None.
    convention: str | None = setting(
        None,
        help="A paper's evaluation preset, named in the record and the output: bailando "
        "(FID/Div on the first 1200 frames, root-relative, against all ground truth; BAS on "
        "whole sequences). Options given explicitly still win.",
    )

    def __post_init__(self) -> None:
        check_choices(self, {"length": ("common_min",)})
        if self.max_frames is not None and self.max_frames < 3:
            raise InputError(f"max_frames must be at least 3, got {self.max_frames}")
        if self.skip_frames < 0:
            raise InputError("skip_frames and beat_tol must be ≥ 0, fpd_frame_step ≥ 1")

    def frame_step(self, name: str, rate: float) -> int:
        """``fps / rate`` as a whole number of frames; InputError naming ``name`` otherwise."""
        step = self.fps / rate if rate > 0 else 0.0
        if step < 1 or abs(step - round(step)) > 1e-9:
            raise InputError(f"{name} {rate} must divide fps {self.fps}")
        return round(step)


@dataclass(frozen=True)
class EvalSequence:
    """One sequence, ground truth and generated, cropped to the same frames.

    Attributes:
        seq_id, music_id: identifiers (music_id groups FPD/FMD per piece).
        n_frames: frames used (after ``skip_frames``, the shorter of the two).
        gt_positions, gen_positions: (F, 24, 3) SMPL joint positions, m, y up; or None.
        gt_rows, gen_rows: (F, D) rows in the MSE space; or None.
        gt_axis_angle, gen_axis_angle: (F, 24, 3) axis-angle, rad; or None.
        music_beats: music-beat frame indices in the used frames' time base; or None.
        measures: [start, stop) of every complete measure inside the used frames (the
            store's measures table, same time base); the units of ``fid_unit = "measure"``
            and ``mse_reduce = "measure_mean"``.
        music_beats_track: the music beats from the first used frame to the end of the track
            (same time base; beats past the last motion frame included), for ``bas_beats =
            "whole_track_mint"``; or None.
        gen_positions_before: the generated positions of the skipped first frames
            (``skip_frames``): ``bas_mint`` detects motion beats on the whole clip and drops
            the skipped frames afterwards, as mint does with its 120 seed frames.
        missing: why a side lacks something (e.g. ``{"positions": "no --smpl-model"}``).
    """

    seq_id: str
    music_id: str | None
    n_frames: int
    gt_positions: np.ndarray | None = None
    gen_positions: np.ndarray | None = None
    gt_rows: np.ndarray | None = None
    gen_rows: np.ndarray | None = None
    gt_axis_angle: np.ndarray | None = None
    gen_axis_angle: np.ndarray | None = None
    music_beats: np.ndarray | None = None
    measures: tuple[tuple[int, int], ...] = ()
    gen_positions_before: np.ndarray | None = None
    missing: dict[str, str] = field(default_factory=dict)
    music_beats_track: np.ndarray | None = None


def _both(a: str, b: str) -> Callable[[EvalSequence], bool]:
    return lambda s: getattr(s, a) is not None and getattr(s, b) is not None


# What a metric may need of each sequence: need -> (the key of EvalSequence.missing that says
# why a sequence lacks it, the check). ``generations`` and ``reference`` are set-level inputs.
NEEDS: dict[str, tuple[str, Callable[[EvalSequence], bool]]] = {
    "positions": ("positions", _both("gt_positions", "gen_positions")),
    "gen_positions": ("positions", lambda s: s.gen_positions is not None),
    "gt_positions": ("positions", lambda s: s.gt_positions is not None),
    "rows": ("rotations", _both("gt_rows", "gen_rows")),
    "axis_angle": ("rotations", _both("gt_axis_angle", "gen_axis_angle")),
    "music_beats": ("music_beats", lambda s: s.music_beats is not None),
    "measures": ("measures", lambda s: bool(s.measures)),
}
SET_NEEDS: tuple[str, ...] = ("generations", "reference")
_POSITION_NEEDS = frozenset({"positions", "gen_positions", "gt_positions"})


@dataclass
class MetricInputs:
    """What every metric is computed from, and where it records what it could not use.

    ``seqs``: the scored sequences; ``params``: the evaluation's settings (``EvaluateParams``);
    ``reference_positions``: the FID / diversity reference units when ``fid_reference`` is not
    ``paired_gt``; ``generations``: music piece → several generations' positions (or None).
    ``unscored``: metric → [{seq_id, reason}]; ``skipped``: metric → why it has no value.
    """

    seqs: Sequence[EvalSequence]
    params: Any
    reference_positions: Sequence[np.ndarray] | None = None
    generations: Any = None
    unscored: dict[str, list[dict[str, str]]] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def having(self, need: str, seqs: Sequence[EvalSequence] | None = None) -> list[EvalSequence]:
        """The sequences of ``seqs`` (default: all) that hold ``need``, recording nothing."""
        check = NEEDS[need][1]
        return [s for s in (self.seqs if seqs is None else seqs) if check(s)]

    def usable(
        self, names: Sequence[str], need: str, seqs: Sequence[EvalSequence] | None = None
    ) -> list[EvalSequence]:
        """The sequences of ``seqs`` (default: all) that hold ``need``; every other one is
        listed as unscored under each of ``names`` with its reason."""
        what, check = NEEDS[need]
        usable = []
        for s in self.seqs if seqs is None else seqs:
            if check(s):
                usable.append(s)
                continue
            reason = s.missing.get(what, f"no {what}")
            for name in names:
                self.unscored[name].append({"seq_id": s.seq_id, "reason": reason})
        return usable

    def skip(self, names: Sequence[str], reason: str) -> list[MetricResult]:
        """Record that ``names`` have no value, and why; returns no results."""
        for name in names:
            self.skipped[name] = reason
        return []

    def guard(
        self, names: Sequence[str], run: Callable[[], list[MetricResult]]
    ) -> list[MetricResult]:
        """``run()``; when the numbers cannot be computed (a ValueError or LinAlgError from the
        maths, e.g. a degenerate feature matrix), record why under each of ``names`` instead of
        stopping the whole evaluation, and return no results."""
        from numpy.linalg import LinAlgError

        try:
            return list(run())
        except (ValueError, LinAlgError) as exc:
            reason = f"could not be computed: {type(exc).__name__}: {str(exc)[:200]}"
            return self.skip(names, reason)


class Metric:
    """Base of a registered metric (see the module docstring)."""

    name: ClassVar[str] = ""
    outputs: ClassVar[tuple[str, ...]] = ()
    needs: ClassVar[tuple[str, ...]] = ()
    settings_type: ClassVar[type | None] = None
    rank: ClassVar[float] = 1000.0
    # The outputs ``experiment run`` also computes (on reconstructions), config metrics.names.
    experiment_outputs: ClassVar[tuple[str, ...]] = ()
    # Outputs their definition bounds to [0, 1] (a value outside is reported as a bug), and
    # ratio-like outputs that may leave [0, 1], with what such a value means (printed notes).
    unit_range: ClassVar[tuple[str, ...]] = ()
    range_notes: ClassVar[dict[str, str]] = {}

    def compute(self, inputs: MetricInputs, settings: Any) -> list[MetricResult]:
        raise NotImplementedError

    def score_reconstructions(self, cell: Any, names: list[str]) -> list[dict[str, Any]]:
        """``experiment run``: the result records (``MetricResult.as_dict()``) of ``names``
        (among ``experiment_outputs``) on one (row, N) ``cell``
        (:class:`dancedata.study.runner.ReconstructionCell`: the reconstruction, the
        ground truth, the config's ``[metrics]`` table); ``cell.skip`` records a skip."""
        raise NotImplementedError(f"metric {self.name!r} has no experiment_outputs")


_REGISTRY: dict[str, Metric] = {}
_LOADED = False
M = TypeVar("M", bound=type)


def register_metric(name: str) -> Callable[[M], M]:
    """Class decorator: name the metric and register one instance of it under ``name``.

    Raises:
        TypeError: not a :class:`Metric`, no outputs, or an unknown need.
        ValueError: a name, an output or a settings field another metric already has.
    """

    def register(cls: M) -> M:
        if not issubclass(cls, Metric) or not cls.outputs:
            raise TypeError(f"{cls.__name__}: a metric subclasses Metric and names its outputs")
        unknown = [n for n in cls.needs if n not in NEEDS and n not in SET_NEEDS]
        if unknown:
            raise TypeError(f"{cls.__name__}: unknown needs {unknown}; known: {list(NEEDS)}")
        known = _REGISTRY.get(name)
        if known is not None and type(known).__qualname__ != cls.__qualname__:
            raise ValueError(f"two metrics named {name!r}: {type(known)} and {cls}")
        others = [m for n, m in _REGISTRY.items() if n != name]
        taken = {o for m in others for o in m.outputs}
        clash = sorted(taken & set(cls.outputs))
        if clash:
            raise ValueError(f"metric {name!r}: outputs {clash} are another metric's")
        field_owner = {f.name: t for t in _types(others) for f in fields(t)}
        if cls.settings_type is not None and cls.settings_type not in field_owner.values():
            clash = sorted(f.name for f in fields(cls.settings_type) if f.name in field_owner)
            if clash:
                raise ValueError(f"metric {name!r}: settings {clash} are another metric's")
        cls.name = name
        _REGISTRY[name] = cls()
        return cls

    return register


def unregister_metric(name: str) -> None:
    """Remove the metric ``name`` (a metric registered by a plugin or a test)."""
    _REGISTRY.pop(name, None)


def _load_metric_modules() -> None:
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    import dancedata.study as package

    for module in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        if module.name.startswith("metric_") and module.name != "metric_registry":
            importlib.import_module(f"{package.__name__}.{module.name}")


def registered_metrics() -> dict[str, Metric]:
    """Every registered metric by name, in listing order (``rank``, then registration)."""
    _load_metric_modules()
    order = sorted(enumerate(_REGISTRY.items()), key=lambda item: (item[1][1].rank, item[0]))
    return {name: metric for _, (name, metric) in order}


def metric_names() -> tuple[str, ...]:
    """Every result name ``evaluate`` lists, in order."""
    return tuple(o for m in registered_metrics().values() for o in m.outputs)


def experiment_metric_names() -> tuple[str, ...]:
    """The result names ``experiment run`` computes (config ``metrics.names``), in order."""
    return tuple(o for m in registered_metrics().values() for o in m.experiment_outputs)


def unit_range_outputs() -> frozenset[str]:
    """The outputs whose definition bounds them to [0, 1]."""
    return frozenset(o for m in registered_metrics().values() for o in m.unit_range)


def range_notes() -> dict[str, str]:
    """Output → what a value of it outside [0, 1] means (ratio-like outputs that may)."""
    return {k: v for m in registered_metrics().values() for k, v in m.range_notes.items()}


def rotation_only_outputs() -> frozenset[str]:
    """The outputs of metrics that read no joint positions (they name no skeleton)."""
    return frozenset(
        o
        for m in registered_metrics().values()
        if not _POSITION_NEEDS & set(m.needs)
        for o in m.outputs
    )


def _types(metrics: Sequence[Metric]) -> list[type]:
    out: list[type] = []
    for metric in metrics:
        if metric.settings_type is not None and metric.settings_type not in out:
            out.append(metric.settings_type)
    return out


def settings_types() -> list[type]:
    """:class:`ScoringSettings`, then each registered metric's settings type once, in order."""
    return [ScoringSettings, *_types(list(registered_metrics().values()))]
