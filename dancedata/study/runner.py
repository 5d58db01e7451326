"""``dancedata experiment run``: a matrix of rows × N × metrics over a split
(docs/EXPERIMENTS.md §5).

For every row key (keyframe strategy + in-betweener) and every N of the config, the runner
selects keyframes in every complete measure of the eval split, reconstructs the in-betweens
(vectorised over all measures at once), and scores them against the stored ground truth with
every registered metric that has ``experiment_outputs``
(:mod:`dancedata.study.metric_registry`; each scores a :class:`ReconstructionCell` in
its ``score_reconstructions``):

* ``mse`` — :func:`dancedata.metrics.mse` over the measures (space, wrap, reduce
  from the config);
* ``pfc`` — :func:`dancedata.metrics.pfc.pfc` (EDGE's Physical Foot Contact score)
  of the reconstruction's SMPL-24 positions, one sequence (or ``pfc_clip_frames`` clip) per
  unit, every 60 / ``pfc_fps``-th frame; positions as for FID.
* ``fid_k`` / ``fid_g`` — :func:`dancedata.metrics.fid` on SMPL-24 joint positions
  of the reconstruction vs the ground truth of the same frames (``fid_reference =
  paired_gt``), one feature vector per sequence or per measure (``fid_unit``). Positions are
  forward kinematics about an SMPL model file's rest joints (``metrics.smpl_model``, default
  ``$DANCEDATA_SMPL_MODEL``) or, without one, the built-in ``edge_smpl_offsets`` skeleton
  (:mod:`dancedata.ops.smpl_skeletons`); the skeleton is in every FID row's ``variant`` and in
  the record's ``conventions.skeleton``, and enters the run id.

Rows whose inputs are missing (no audio / stems / NMFD for a peak strategy, fewer than 2 FID
units, no generated outputs for a ``transformer_*`` row) are skipped with a one-line reason in the
record; they are never replaced by something else. Class M rows take their in-betweens from
``generated`` folders (:mod:`dancedata.study.runner_generated`).

Output (§5.5): ``results.parquet`` (long format, one row per (row, N, metric)) and
``results.json`` (the record: run id, store version, split, every convention, the skips).
"""

from __future__ import annotations

import datetime as dt
import json
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.errors import InputError
from dancedata.methods.bezier import BezierTrainMean, bezier_fit, bezier_reconstruction
from dancedata.methods.inbetween import Reconstruction, linear_slerp, segment_map
from dancedata.store.checksums import fingerprint
from dancedata.study.config import ExperimentConfig, RowKey
from dancedata.study.results_schema import results_table
from dancedata.study.runner_data import (
    SplitData,
    load_split,
    require_strategy_inputs,
    select_keyframes,
)

RESULTS_TABLE = "results.parquet"
RESULTS_RECORD = "results.json"
FPS = 60.0


@dataclass
class Skip:
    """A (row, N, metric) cell left empty, and why (metric None: every metric of the run)."""

    row_key: str
    n_keyframes: int | None
    metric: str | None
    reason: str

    def as_dict(self) -> dict[str, Any]:
        return {
            "row_key": self.row_key,
            "n_keyframes": self.n_keyframes,
            "metric": self.metric,
            "reason": self.reason,
        }


@dataclass
class RunOutput:
    """What :func:`run_experiment` computed: result rows, skips and the record."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    skipped: list[Skip] = field(default_factory=list)
    record: dict[str, Any] = field(default_factory=dict)
    out_dir: Path | None = None


@dataclass
class Evaluated:
    """The evaluated measures of one run and their reconstruction."""

    rows: np.ndarray  # measure indices into SplitData
    truth75: np.ndarray  # (F', 75)
    recon75: np.ndarray  # (F', 75)
    reconstruction: Reconstruction | None
    frame: np.ndarray  # (F',) compact rows of the split data
    unit_bounds: np.ndarray  # (M'+1,) offsets of each measure in the F' rows


def _split_units(values: np.ndarray, bounds: np.ndarray) -> list[np.ndarray]:
    return [values[a:b] for a, b in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True)]


def _reconstruct(row: RowKey, data: SplitData, rows: np.ndarray, kf: np.ndarray,
                 config: ExperimentConfig, train: Any) -> Reconstruction:  # fmt: skip
    """The in-betweens of ``row`` for the measures ``rows`` with keyframes ``kf``."""
    seg = segment_map(data.start[rows], data.length[rows], kf)
    ib = config.data["inbetween"]
    if row.inbetween == "linear_slerp":
        return linear_slerp(data.quat, data.trans, seg, data.euler_order, truth_euler=data.euler)
    x75 = data.x75
    if row.inbetween == "bezier_oracle":
        p1, p2 = bezier_fit(x75, seg, ib["bezier_solver"])
    else:  # bezier_train_mean: control points averaged over the train split
        p1, p2 = train.control_points(x75, seg)
    return bezier_reconstruction(x75, seg, p1, p2, data.euler_order, ib["bezier_trans"])


def _fit_train_mean(row: RowKey, n: int, config: ExperimentConfig, train: SplitData,
                    store: Any) -> BezierTrainMean:  # fmt: skip
    params = config.keyframe_params()
    rows, kf = select_keyframes(train, row.strategy, n, params, store, _usable(row, train, n,
                                                                           config))  # fmt: skip
    if rows.size == 0:
        raise InputError(f"the train split has no measure that holds N = {n} keyframes")
    seg = segment_map(train.start[rows], train.length[rows], kf)
    ib = config.data["inbetween"]
    model = BezierTrainMean(group=ib["bezier_group"], param=ib["bezier_param"])
    return model.fit(train.x75, seg, ib["bezier_solver"])


def _usable(row: RowKey, data: SplitData, n: int, config: ExperimentConfig) -> np.ndarray:
    """Measures that can hold N keyframes (and, for peak strategies, have audio)."""
    total = config.keyframe_params().total_keyframes(n)
    ok = data.length >= total
    if row.strategy.startswith("peaks:"):
        ok &= data.audio_available
    return np.flatnonzero(ok)


def _evaluated(data: SplitData, rows: np.ndarray, rec: Reconstruction) -> Evaluated:
    seg = rec.segments
    bounds = np.concatenate([[0], np.cumsum(data.length[rows])])
    return Evaluated(rows, data.x75[seg.frame], rec.euler75(), rec, seg.frame, bounds)


def _fid_units(ev: Evaluated, data: SplitData, unit: str) -> np.ndarray:
    """Offsets of the FID units in the evaluated rows: one per measure, or per sequence
    (consecutive measures of one sequence concatenated)."""
    if unit == "measure":
        return ev.unit_bounds
    seq = data.measure_seq[ev.rows]
    change = np.flatnonzero(np.diff(seq)) + 1
    return np.concatenate([[0], ev.unit_bounds[change], [ev.unit_bounds[-1]]])


@dataclass
class ReconstructionCell:
    """One (row, N) of a run as a registered metric scores it (``score_reconstructions``):
    the reconstruction beside the ground truth of the same frames, the config's ``[metrics]``
    table, the rest skeleton of joint positions, and where to record a skipped metric."""

    ev: Evaluated
    data: SplitData
    metrics: dict[str, Any]
    skeleton: Any
    skipped: list[Skip]
    row_key: str
    n: int
    fps: float = FPS
    _positions: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def truth75(self) -> np.ndarray:
        return self.ev.truth75

    @property
    def recon75(self) -> np.ndarray:
        return self.ev.recon75

    def groups(self) -> list[str]:
        """The seq_id of every evaluated measure."""
        seqs = self.data.measure_seq[self.ev.rows].tolist()
        return [self.data.sequences[i]["seq_id"] for i in seqs]

    def n_units(self, unit: str) -> int:
        return len(_fid_units(self.ev, self.data, unit)) - 1

    def split(self, values: np.ndarray, unit: str) -> list[np.ndarray]:
        """Rows of the evaluated frames cut into units: ``measure`` or ``sequence``."""
        return _split_units(values, _fid_units(self.ev, self.data, unit))

    def positions(self, side: str) -> np.ndarray:
        """SMPL-24 joint positions (F', 24, 3) of ``gen`` (the reconstruction) or ``gt``."""
        if side not in self._positions:
            rec = self.ev.reconstruction
            assert rec is not None and self.data.axis_angle is not None
            if side == "gen":
                value = self.skeleton.positions(rec.axis_angle(), rec.trans)
            else:
                frame = self.ev.frame
                value = self.skeleton.positions(self.data.axis_angle[frame], self.data.trans[frame])
            self._positions[side] = value
        return self._positions[side]

    def skip(self, metric: str, reason: str) -> None:
        self.skipped.append(Skip(self.row_key, self.n, metric, reason))


def _needs_positions(metrics: list[str]) -> bool:
    """Whether any of ``metrics`` (config metrics.names) is computed from joint positions."""
    from dancedata.study.metric_registry import registered_metrics, rotation_only_outputs

    rotation_only = rotation_only_outputs()
    return any(
        name not in rotation_only
        for metric in registered_metrics().values()
        for name in metric.experiment_outputs
        if name in metrics
    )


def _score_cell(cell: ReconstructionCell, metrics: list[str], reason: str | None
                ) -> list[dict[str, Any]]:  # fmt: skip
    """Every registered metric's results of ``metrics`` on one (row, N), in listing order
    (``reason``: why joint positions are unavailable, or None)."""
    from dancedata.study.metric_registry import registered_metrics, rotation_only_outputs

    rotation_only = rotation_only_outputs()
    out: list[dict[str, Any]] = []
    for metric in registered_metrics().values():
        names = [m for m in metrics if m in metric.experiment_outputs]
        if not names:
            continue
        if reason and any(n not in rotation_only for n in names):
            for name in names:
                cell.skip(name, reason)
            continue
        out += metric.score_reconstructions(cell, names)
    return out


def _smpl_model(config: ExperimentConfig, override: str | Path | None) -> tuple[Any, str | None]:
    """(the rest skeleton of the FID positions, None): the model file of ``--smpl-model`` or
    ``metrics.smpl_model`` when given, else the built-in ``edge_smpl_offsets``."""
    from dancedata.ops.smpl_skeletons import smpl_skeleton

    path = Path(override) if override else config.smpl_model_path()
    return smpl_skeleton(path), None


def run_fingerprint(config: ExperimentConfig, store_fingerprint: str,
                    extra_inputs: list[str]) -> str:  # fmt: skip
    """run_id (§5.5): every config key (defaults filled, the store path left out: the
    version's fingerprint stands for the data) + the store version + model outputs' hashes."""
    data = {k: v for k, v in config.data.items() if k != "store"}
    return fingerprint("experiment", data, [store_fingerprint, *extra_inputs], __version__)[:16]


def run_experiment(
    config: ExperimentConfig,
    store: str | Path,
    *,
    version: str | None = None,
    out_dir: str | Path | None = None,
    generated: dict[str, str] | None = None,
    smpl_model: str | Path | None = None,
) -> RunOutput:
    """Run every (row, N, metric) of ``config`` on ``store`` and write the results to
    ``out_dir`` (nothing written when None). ``generated`` maps ``row_key`` or
    ``row_key@N`` (or ``*``, a folder of ``<row_key>@<N>`` subfolders) to model outputs; it
    extends the config's ``[generated]`` table."""
    from dancedata.read.loader import DanceStore
    from dancedata.study.runner_generated import GeneratedOutputs

    began = time.perf_counter()
    from dancedata.store.backend_open import make_backend
    from dancedata.store.reader import _VersionReader

    reader = _VersionReader(make_backend(store), version)  # opened once, shared by both
    loader = DanceStore(reader)
    params = config.keyframe_params()
    metrics = config.metrics
    wants_fid = _needs_positions(metrics)  # SMPL-24 positions
    split = config.split
    data = load_split(reader, split["scheme"], split["eval"], split["exclude_genres"],
                      need_axis_angle=wants_fid)  # fmt: skip
    train = None
    model, fid_reason = _smpl_model(config, smpl_model) if wants_fid else (None, None)
    outputs = GeneratedOutputs({**config.data["generated"], **(generated or {})}, config)
    stem_backend = reader.group_attrs("audio/stems").get("backend") if reader.has_array(
        "audio/stems/drums/onset_env") else None  # fmt: skip
    out = RunOutput()
    timings: dict[str, float] = {}
    for row in config.rows:
        reason = require_strategy_inputs(reader, row.strategy, params)
        if reason is not None:
            out.skipped.append(Skip(row.key, None, None, f"{row.strategy}: {reason}"))
            continue
        for n in config.n_keyframes:
            t0 = time.perf_counter()
            rows = _usable(row, data, n, config)
            if rows.size == 0:
                audio = " and has audio" if row.strategy.startswith("peaks:") else ""
                why = f"no measure of the split holds N = {n}{audio}"
                out.skipped.append(Skip(row.key, n, None, why))
                continue
            if row.learned:
                found = outputs.reconstruction(row.key, n, data, rows)
                if isinstance(found, str):
                    out.skipped.append(Skip(row.key, n, None, found))
                    continue
                rec = found
            else:
                rows, kf = select_keyframes(data, row.strategy, n, params, loader, rows)
                trained = None
                if row.inbetween == "bezier_train_mean":
                    if train is None:
                        train = load_split(reader, split["scheme"], [split["train"]],
                                           split["exclude_genres"])  # fmt: skip
                    trained = _fit_train_mean(row, n, config, train, loader)
                rec = _reconstruct(row, data, rows, kf, config, trained)
            ev = _evaluated(data, rows, rec)
            cell = ReconstructionCell(ev, data, config.data["metrics"], model, out.skipped,
                                      row.key, n)  # fmt: skip
            scored = _score_cell(cell, metrics, fid_reason)
            for result in scored:
                out.rows.append(_result_row(row, n, result, config, data, params, stem_backend))
            timings[f"{row.key}@{n}"] = round(time.perf_counter() - t0, 3)
    skeleton_id = [f"skeleton:{model.name}"] if model is not None else []
    run_id = run_fingerprint(config, reader.manifest["fingerprint"],
                             [*outputs.input_hashes(), *skeleton_id])  # fmt: skip
    created = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    for r in out.rows:
        r.update(run_id=run_id, store_version=loader.version, dancedata_version=__version__,
                 created_at=created)  # fmt: skip
    out.record = {
        "run_id": run_id,
        "config_id": config.id,
        "config_path": str(config.path) if config.path else None,
        "tables": config.data["tables"],
        "config": config.data,
        "store": str(store) if "://" in str(store) else str(Path(store).resolve()),
        "store_version": loader.version,
        "store_fingerprint": reader.manifest["fingerprint"],
        "split": data.label,
        "genres_excluded": data.genres_excluded,
        "n_sequences": len(data.sequences),
        "n_measures": int(data.length.size),
        "conventions": {
            "euler_order": data.euler_order,
            "stem_backend": stem_backend,
            "fps": FPS,
            "keyframes": params.as_dict(),
            "inbetween": config.data["inbetween"],
            "metrics": config.data["metrics"],
            "skeleton": None if model is None else model.record(),
        },
        "generated": outputs.describe(),
        "skipped": [s.as_dict() for s in out.skipped],
        "dancedata_version": __version__,
        "created_at": created,
        "seconds": {"total": round(time.perf_counter() - began, 3), "runs": timings},
    }
    if out_dir is not None:
        out.out_dir = write_results(out, Path(out_dir))
    return out


def _result_row(row: RowKey, n: int, result: dict[str, Any], config: ExperimentConfig,
                data: SplitData, params: Any, stem_backend: Any) -> dict[str, Any]:  # fmt: skip
    variant = {
        **result["convention"],
        "euler_order": data.euler_order,
        "keyframes": params.for_strategy(row.strategy) if not row.learned else "generated",
        "inbetween": row.inbetween,
    }
    if row.inbetween.startswith("bezier"):
        variant["bezier"] = config.data["inbetween"]
    if row.strategy == "peaks:stems":
        variant["stem_backend"] = stem_backend
    return {
        "row_key": row.key,
        "n_keyframes": n,
        "metric": result["metric"],
        "value": np.nan if result["value"] is None else float(result["value"]),
        "n_units": result["n_units"],
        "n_frames": result["n_frames"],
        "split": data.label,
        "genres_excluded": ",".join(data.genres_excluded),
        "variant": json.dumps(variant, sort_keys=True, default=str),
    }


def write_results(out: RunOutput, out_dir: Path) -> Path:
    """Write results.parquet and results.json into ``out_dir``: each file is written under a
    temporary name and renamed, the record last, so a reader never sees half a result."""
    import pyarrow.parquet as pq

    out_dir.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".results-", suffix=".parquet", dir=out_dir)
    os.close(fd)
    try:
        pq.write_table(results_table(out.rows), tmp)
        os.replace(tmp, out_dir / RESULTS_TABLE)
        fd, tmp = tempfile.mkstemp(prefix=".results-", suffix=".json", dir=out_dir)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(out.record, fh, indent=2, sort_keys=True, default=str)
            fh.write("\n")
        os.replace(tmp, out_dir / RESULTS_RECORD)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out_dir


def read_results(out_dir: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """(result rows, record) of a results folder; InputError naming what is missing."""
    from dancedata.store.reader import parquet_size_problem, parquet_table
    from dancedata.store.untrusted import TABLE_LIMIT, read_regular

    out_dir = Path(out_dir)
    table_path, record_path = out_dir / RESULTS_TABLE, out_dir / RESULTS_RECORD
    for path in (table_path, record_path):
        if not path.is_file():
            raise InputError("not a results folder (run `dancedata experiment run`)", path)
    try:
        record = json.loads(record_path.read_text(encoding="utf-8"))
        data = read_regular(table_path, TABLE_LIMIT)  # a regular file, its size bounded
        problem = parquet_size_problem(data)  # nor is its footer's declared size trusted
        if problem is not None:
            raise InputError(f"unreadable results: {problem}", table_path)
        rows = parquet_table(data).to_pylist()  # no native threads
    except (OSError, ValueError) as exc:
        raise InputError(f"unreadable results: {exc}", out_dir) from None
    return rows, record
