"""``dancedata evaluate``: score generated motion against a store's ground truth on a split.

Reads the store version (never writes to it), one generated file per sequence of the split (or
the same sequences of another dancedata store), puts both sides into the metrics' spaces, runs
:func:`dancedata.study.scoring.evaluate_sequences` and writes a results record:
``results.json`` (everything) and ``results.parquet`` (docs/EXPERIMENTS.md §5.5 long format, one
row per metric), each written under a temporary name and renamed into ``out``.

Assumptions, recorded in the record: generated motion runs at the store's frame rate, frame i
beside ground-truth frame i, in SMPL's frame (metres, y up). On SMPL-24 stores ground-truth
positions come from forward kinematics of the stored rotations about the run's rest skeleton:
``smpl_model`` when given, else the built-in ``edge_smpl_offsets``
(:mod:`dancedata.ops.smpl_skeletons`); generated rotations are posed the same way (a file
holding positions only is used as it is). The skeleton is recorded in ``config.skeleton`` and in the
convention of every metric computed from positions. Other stores: ``smpl_model`` if given,
else the store's ``motion/positions``. Music beats are the store's ``audio/beats`` (librosa
``beat_track``; ``beat_source = "bailando"``: ``audio/beats_bailando``), inside the compared
frames, or for ``bas_beats = "whole_track_mint"`` (mint's generated-motion path) up to the end of
the track. ``generations`` (a folder of generation runs) feeds multimodality.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.compute.smpl import SMPL_JOINTS
from dancedata.errors import DancedataError, InputError, StoreError
from dancedata.io.generated_motion import (
    GENERATED_SUFFIXES,
    find_generated_file,
    generated_frame_limit,
    read_generated_motion,
)
from dancedata.metrics.beats import beat_frames
from dancedata.metrics.evaluate_inputs import (
    axis_angle_euler,
    euler75_rows,
    fact225_rows,
    fact_rows_to_smpl,
    resample_generated,
    z_up_to_y_up,
)
from dancedata.ops.smpl_skeletons import smpl_skeleton
from dancedata.read.loader import DanceStore, open_store
from dancedata.store.checksums import canonical_json, sha256_file
from dancedata.study.metric_registry import (
    metric_names,
    range_notes,
    rotation_only_outputs,
    unit_range_outputs,
)
from dancedata.study.results_schema import results_table
from dancedata.study.scoring import (
    EvalSequence,
    EvaluateParams,
    Evaluation,
    evaluate_sequences,
)

__all__ = ["EvaluateOptions", "EvaluateSummary", "evaluate"]


@dataclass
class EvaluateOptions:
    """What to score and how (every metric choice is in ``params``)."""

    generated: Path
    split: str = "test"
    scheme: str = "crossmodal"
    exclude_genres: list[str] = field(default_factory=list)
    smpl_model: str | None = None
    out: Path | None = None
    row_key: str = "generated"
    version: str | None = None
    generated_version: str | None = None
    generated_fps: float | None = None
    generated_up_axis: str = "y"
    params: EvaluateParams = field(default_factory=EvaluateParams)
    generations: Path | None = None


@dataclass
class EvaluateSummary:
    """What ``evaluate`` did, for the CLI: the record and where it went."""

    record: dict[str, Any]
    out: Path
    skipped: list[dict[str, str]] = field(default_factory=list)

    @property
    def unscored_sequences(self) -> list[dict[str, str]]:
        return self.record["unscored_sequences"]

    def as_dict(self) -> dict[str, Any]:
        return {"out": str(self.out), **self.record}

    def table(self) -> str:
        """The results as a fixed-width text table, a line per metric (scored or not), then
        what the columns mean and a note on every value a reader could misread."""
        total = self.record["n_sequences"]
        lines = [f"{'metric':<22}{'value':>14}{'sequences':>11}{'n_items':>9}{'frames':>9}"]
        for row in self.record["results"]:
            value = "nan" if row["value"] is None else f"{row['value']:.6g}"
            scored = f"{total - len(row['unscored'])}/{total}"
            lines.append(
                f"{row['metric']:<22}{value:>14}{scored:>11}{row['n_units']:>9}{row['n_frames']:>9}"
            )
        for name, reason in self.record["skipped_metrics"].items():
            lines.append(f"{name:<22}{'—':>14}{f'0/{total}':>11}{0:>9}{0:>9}  ({reason})")
        lines.append(
            "sequences: scored of the split's; n_items: the sequences, measures or music pieces "
            "a value is computed over (its convention in results.json); frames: motion frames "
            "scored"
        )
        for row in self.record["results"]:
            constant = row["details"].get("constant_ref_columns", 0)
            if constant and not row["details"].get("dropped_columns"):
                lines.append(
                    f"note: {row['metric']}: {constant} feature column(s) constant in the ground "
                    "truth, z-scored by 1e-10 (docs/STORE.md, Scoring generated motion); "
                    "--drop-constant-ref-columns leaves them out"
                )
            note = _range_note(row["metric"], row["value"])
            if note:
                lines.append(f"note: {note}")
        return "\n".join(lines)

    def convention_row(self) -> str | None:
        """With a named convention (``params.convention``): its name, what it means, and the
        paper's row of metrics in the paper's order ("—" where a metric has no value)."""
        name = self.record["config"]["params"].get("convention")
        if not name:
            return None
        from dancedata.metrics.evaluate_conventions import convention_named

        preset = convention_named(name)
        values = {r["metric"]: r["value"] for r in self.record["results"]}
        cells = [
            f"{header} {'—' if values.get(metric) is None else format(values[metric], '.4g')}"
            for metric, header in preset.row
        ]
        skeleton = (self.record["config"].get("skeleton") or {}).get("skeleton")
        return (
            f"convention {preset.name}: {preset.summary}; skeleton {skeleton}\n"
            f"{preset.name} row: " + "  ".join(cells)
        )

    def message(self, command: str) -> str:
        results = self.record["results"]
        total = self.record["n_sequences"]
        n_metrics = len(results) + len(self.record["skipped_metrics"])
        counts = sorted({total - len(r["unscored"]) for r in results}, reverse=True)
        on = " or ".join(str(c) for c in counts) if counts else "0"
        head = (
            f"{command}: {self.record['store_version']} {self.record['split']}, "
            f"{len(results)} of {n_metrics} metrics scored (on {on} of {total} sequences); "
            f"record in {self.out}"
        )
        row = self.convention_row()
        return head + "\n" + self.table() + ("" if row is None else "\n" + row)


def _range_note(metric: str, value: float | None) -> str | None:
    """Why ``value`` of a ratio-like metric lies outside [0, 1], or None when it does not."""
    if value is None or not np.isfinite(value) or 0.0 <= value <= 1.0:
        return None
    notes = range_notes()  # ratio-like metrics: what a value outside [0, 1] means
    if metric in notes:
        return f"{metric} {value:.3g} {notes[metric]}"
    if metric in unit_range_outputs():
        return (
            f"{metric} {value:.3g} is outside [0, 1], which its definition bounds "
            "(should not happen: please report it)"
        )
    return None


# ------------------------------------------------------------------------- reading each side


def _gt_side(
    store: DanceStore, seq_id: str, model: Any, order: str
) -> tuple[dict[str, np.ndarray | None], dict[str, str]]:
    missing: dict[str, str] = {}
    aa = np.asarray(store.motion(seq_id, "axis_angle"), dtype=np.float64)
    trans = np.asarray(store.motion(seq_id, "trans"), dtype=np.float64)
    names = set(store.array_names())
    if "motion/euler" in names:
        euler = np.asarray(store.motion(seq_id, "euler"), dtype=np.float64)
    else:
        euler = axis_angle_euler(aa, order)
    positions = None
    if model is not None:
        from dancedata.compute.smpl_joints import smpl_joint_positions

        positions = smpl_joint_positions(model, aa, trans)
    elif "motion/positions" in names:
        positions = np.asarray(store.motion(seq_id, "positions"), dtype=np.float64)
    else:
        missing["positions"] = (
            "ground truth has no joint positions (give --smpl-model, or featurize "
            "--motion-families positions)"
        )
    if positions is not None and positions.shape[1] != 24:
        missing["positions"] = (
            f"ground-truth positions have {positions.shape[1]} joints; FID and beat metrics "
            "here need SMPL-24 (give --smpl-model)"
        )
        positions = None
    return {"axis_angle": aa, "trans": trans, "euler": euler, "positions": positions}, missing


def _gen_from_store(gen: DanceStore, seq_id: str, model: Any) -> dict[str, Any]:
    if seq_id not in gen.seq_ids():
        raise InputError(f"no sequence {seq_id} in the generated store", gen.path)
    names = gen.array_names()
    aa = trans = positions = None
    if "motion/axis_angle" in names and "motion/trans" in names:
        aa = np.asarray(gen.motion(seq_id, "axis_angle"), dtype=np.float64)
        trans = np.asarray(gen.motion(seq_id, "trans"), dtype=np.float64)
    elif "motion/positions" not in names:
        raise InputError(
            "the generated store holds neither rotations (motion/axis_angle + motion/trans) "
            "nor joint positions (motion/positions)",
            gen.path,
        )
    # A store of generated joint positions (``ingest generated`` of a positions layout) is
    # scored on its positions, as a folder of position files is.
    if (model is None or aa is None) and "motion/positions" in names:
        positions = np.asarray(gen.motion(seq_id, "positions"), dtype=np.float64)
    return {
        "layout": "store",
        "axis_angle": aa,
        "trans": trans,
        "positions": positions,
        "source": f"{gen.path}::{seq_id}",
    }


def _gen_from_file(path: Path, max_frames: int | None = None) -> dict[str, Any]:
    motion = read_generated_motion(path, max_frames)
    aa = trans = None
    if motion.fact_rows is not None:
        aa, trans = fact_rows_to_smpl(motion.fact_rows)
    elif motion.axis_angle is not None:
        aa, trans = motion.axis_angle, motion.trans
    return {
        "layout": motion.layout,
        "axis_angle": aa,
        "trans": trans,
        "positions": motion.positions,
        "source": str(path),
    }


def _adapt(gen: dict[str, Any], options: EvaluateOptions, fps: float) -> dict[str, Any]:
    """Generated motion into the store's frame: y up, the store's frame rate."""
    aa, trans, positions = gen["axis_angle"], gen["trans"], gen["positions"]
    if options.generated_up_axis == "z":
        aa, trans, positions = z_up_to_y_up(aa, trans, positions)
    src = options.generated_fps or fps
    if abs(src - fps) > 1e-9:
        aa, trans, positions, _ = resample_generated(aa, trans, positions, src, fps)
    return {**gen, "axis_angle": aa, "trans": trans, "positions": positions}


def _gen_positions(gen: dict[str, Any], model: Any) -> tuple[np.ndarray | None, str | None]:
    if model is not None and gen["axis_angle"] is not None:
        from dancedata.compute.smpl_joints import smpl_joint_positions

        return smpl_joint_positions(model, gen["axis_angle"], gen["trans"]), None
    positions = gen["positions"]
    if positions is None:
        return None, "generated motion holds rotations only: give --smpl-model for positions"
    if positions.shape[1] != 24:
        return None, f"generated positions have {positions.shape[1]} joints, metrics need SMPL-24"
    return positions, None


def _pair(
    seq_id: str,
    music_id: str | None,
    gt: dict[str, Any],
    gt_missing: dict[str, str],
    gen: dict[str, Any],
    model: Any,
    beats: np.ndarray | None,
    beats_missing: str | None,
    params: EvaluateParams,
    measures: list[tuple[int, int]] | None = None,
) -> tuple[EvalSequence, dict[str, Any]]:
    """Both sides cropped to [skip, min(F_gt, F_gen)); raises InputError when too short."""
    missing = dict(gt_missing)
    gen_pos, why = _gen_positions(gen, model)
    if why and "positions" not in missing:
        missing["positions"] = why
    gen_frames = len(gen["axis_angle"]) if gen["axis_angle"] is not None else len(gen_pos)
    gt_frames = len(gt["axis_angle"])
    skip = params.skip_frames
    stop = min(gt_frames, gen_frames)
    if params.max_frames is not None:
        stop = min(stop, skip + params.max_frames)
    if stop - skip < 3:
        raise InputError(
            f"{stop - skip} frames to compare after skipping {skip} (ground truth {gt_frames}, "
            f"generated {gen_frames}; need 3)",
            gen["source"],
        )
    cut = slice(skip, stop)
    gen_rows = gt_rows = gen_aa = None
    if gen["axis_angle"] is not None:
        gen_aa = gen["axis_angle"][cut]
        gen_euler = axis_angle_euler(gen_aa, params.euler_order)
        if params.mse_space == "rotmat":
            gen_rows, gt_rows = (
                fact225_rows(gen_aa, gen["trans"][cut]),
                fact225_rows(gt["axis_angle"][cut], gt["trans"][cut]),
            )
        else:
            gen_rows = euler75_rows(gen_euler, gen["trans"][cut])
            gt_rows = euler75_rows(gt["euler"][cut], gt["trans"][cut])
    else:
        missing["rotations"] = "generated motion holds joint positions only (no rotations)"
    music = track_beats = None
    if beats is not None:
        music = beats[(beats >= skip) & (beats < stop)] - skip
        track_beats = beats[beats >= skip] - skip
    elif beats_missing:
        missing["music_beats"] = beats_missing
    if measures is None:
        missing["measures"] = "the store has no measures table (run dancedata segment)"
        inside: tuple[tuple[int, int], ...] = ()
    else:
        inside = tuple((a - skip, b - skip) for a, b in measures if a >= skip and b <= stop)
        if not inside:
            missing["measures"] = "no complete measure inside the compared frames"
    seq = EvalSequence(
        seq_id=seq_id,
        music_id=music_id,
        n_frames=stop - skip,
        gt_positions=None if gt["positions"] is None else gt["positions"][cut],
        gen_positions=None if gen_pos is None else gen_pos[cut],
        gen_positions_before=None if gen_pos is None else gen_pos[:skip],
        gt_rows=gt_rows,
        gen_rows=gen_rows,
        gt_axis_angle=gt["axis_angle"][cut],
        gen_axis_angle=gen_aa,
        music_beats=music,
        measures=inside,
        missing=missing,
        music_beats_track=track_beats,
    )
    info = {
        "seq_id": seq_id,
        "layout": gen["layout"],
        "source": gen["source"],
        "gt_frames": gt_frames,
        "generated_frames": gen_frames,
        "used_frames": stop - skip,
    }
    return seq, info


_BEAT_ARRAYS = {"fact": ("beats", "fact"), "bailando": ("beats_bailando", "bailando_beats")}


def _beats(
    store: DanceStore, seq_id: str, source: str = "fact"
) -> tuple[np.ndarray | None, str | None]:
    """Music-beat frames from the sequence's first frame to the end of its track (beats past
    the last motion frame included: ``bas_beats = whole_track_mint`` uses them; every other
    beat metric keeps those inside the compared frames), from the array of ``beat_source``."""
    array, family = _BEAT_ARRAYS[source]
    if f"audio/{array}" not in store.array_names():
        why = f"the store has no audio/{array} (run featurize with the {family} family)"
        return None, why
    if store.audio_frames(seq_id) == 0:
        return None, "the sequence has no music"
    return beat_frames(store.audio_to_track_end(seq_id, array)), None


def _generation_runs(folder: Path) -> list[Path]:
    """The generation runs of ``--generations``: its subfolders (sorted by name), each laid out
    like ``--generated`` (one <seq_id> file per sequence); at least 2."""
    if not folder.is_dir():
        raise InputError("--generations must be a folder of generation-run subfolders", folder)
    runs = sorted(d for d in folder.iterdir() if d.is_dir() and not d.name.startswith("."))
    if len(runs) < 2:
        raise InputError(
            f"--generations needs at least 2 run subfolders (<run>/<seq_id>.npy), found "
            f"{len(runs)}",
            folder,
        )
    return runs


def _generations(
    store: DanceStore,
    runs: list[Path],
    seqs: list[EvalSequence],
    options: EvaluateOptions,
    model: Any,
) -> tuple[dict[str, list[np.ndarray]], list[dict[str, str]], list[str]]:
    """Music piece → the positions of every run's generation of its scored sequences, cropped
    as the scored pair is ([skip, min(F_gt, F_gen)), at most max_frames); the (run, seq_id,
    reason) of every generation that could not be read; the files' sha256."""
    params = options.params
    groups: dict[str, list[np.ndarray]] = {}
    problems: list[dict[str, str]] = []
    hashes: list[str] = []
    for seq in seqs:
        gt_frames = int(store.sequence(seq.seq_id)["n_frames"])
        for run in runs:
            try:
                file = find_generated_file(run, seq.seq_id)
                if file is None:
                    raise InputError(f"no generated file {seq.seq_id}", run)
                hashes.append(sha256_file(file))
                gen = _adapt(_gen_from_file(file), options, params.fps)
                positions, why = _gen_positions(gen, model)
                if positions is None:
                    raise InputError(str(why), file)
                stop = min(gt_frames, len(positions))
                if params.max_frames is not None:
                    stop = min(stop, params.skip_frames + params.max_frames)
                if stop - params.skip_frames < 3:
                    raise InputError(f"{stop - params.skip_frames} frames after skipping", file)
            except (DancedataError, ValueError) as exc:
                problems.append({"run": run.name, "seq_id": seq.seq_id, "reason": str(exc)})
                continue
            key = seq.music_id or seq.seq_id
            groups.setdefault(key, []).append(positions[params.skip_frames : stop])
    return groups, problems, sorted(hashes)


def _reference_units(
    store: DanceStore,
    options: EvaluateOptions,
    model: Any,
    euler_order: str,
    measures: dict[str, list[tuple[int, int]]] | None,
) -> list[np.ndarray] | None:
    """Ground-truth position units of ``fid_reference`` ``train_gt`` (the scheme's train split)
    or ``all_gt`` (every sequence; mint uses all of AIST++), whole sequences or their complete
    measures; None for ``paired_gt``. Excluded genres stay excluded."""
    params = options.params
    if params.fid_reference == "paired_gt":
        return None
    split = "train" if params.fid_reference == "train_gt" else None
    seq_ids = store.seq_ids(split=split, scheme=options.scheme)
    seq_ids = [q for q in seq_ids if store.sequence(q)["genre"] not in set(options.exclude_genres)]
    units: list[np.ndarray] = []
    for seq_id in seq_ids:
        gt, missing = _gt_side(store, seq_id, model, euler_order)
        if gt["positions"] is None:
            raise InputError(
                f"fid_reference {params.fid_reference}: {seq_id}: {missing['positions']}"
            )
        if params.fid_unit == "measure":
            if measures is None:
                raise InputError("fid_unit measure needs the measures table (run segment)")
            units.extend(gt["positions"][a:b] for a, b in measures.get(seq_id, []))
        else:
            units.append(gt["positions"])
    if len(units) < 2:
        raise InputError(f"fid_reference {params.fid_reference} has {len(units)} unit(s), need 2")
    return units


# ---------------------------------------------------------------------------------- record


def _write_record(out: Path, record: dict[str, Any], rows: list[dict[str, Any]]) -> None:
    import pyarrow.parquet as pq

    out.mkdir(parents=True, exist_ok=True)
    table = results_table(rows, unscored=True)
    tag = f".tmp-{os.getpid()}"
    pq_tmp, json_tmp = out / f"results.parquet{tag}", out / f"results.json{tag}"
    try:
        pq.write_table(table, pq_tmp)
        json_tmp.write_text(json.dumps(record, indent=2, default=str) + "\n")
        os.replace(pq_tmp, out / "results.parquet")
        os.replace(json_tmp, out / "results.json")
    finally:
        for tmp in (pq_tmp, json_tmp):
            tmp.unlink(missing_ok=True)


def _long_rows(record: dict[str, Any], evaluation: Evaluation) -> list[dict[str, Any]]:
    base = {
        "run_id": record["run_id"],
        "row_key": record["row_key"],
        "n_keyframes": None,
        "split": record["split"],
        "genres_excluded": ",".join(record["genres_excluded"]),
        "store_version": record["store_version"],
        "dancedata_version": record["dancedata_version"],
        "created_at": record["created_at"],
    }
    rows = []
    for result in evaluation.results:
        left_out = evaluation.unscored.get(result.name, [])
        rows.append(
            {
                **base,
                "metric": result.name,
                "value": float(result.value),
                "n_units": result.n_units,
                "n_frames": result.n_frames,
                "variant": canonical_json(result.convention),
                "n_unscored": len(left_out),
                "unscored": canonical_json(left_out),
            }
        )
    return rows


# ------------------------------------------------------------------------------------- run


def evaluate(store_path: str | Path, options: EvaluateOptions) -> EvaluateSummary:
    """Score ``options.generated`` against the store's ground truth on the split; write the
    record; return it. Raises InputError / StoreError for a bad store, split or PATH, and when
    no sequence at all can be scored."""
    params = options.params
    if options.generated_up_axis not in ("y", "z"):
        raise InputError(f"--generated-up-axis must be y or z, got {options.generated_up_axis!r}")
    if options.generated_fps is not None and not options.generated_fps > 0:
        raise InputError(f"--generated-fps must be positive, got {options.generated_fps}")
    runs = _generation_runs(Path(options.generations)) if options.generations else None
    store = open_store(store_path, options.version)
    seq_ids = store.seq_ids(split=options.split, scheme=options.scheme)
    genres = set(options.exclude_genres)
    seq_ids = [s for s in seq_ids if store.sequence(s)["genre"] not in genres]
    if not seq_ids:
        raise StoreError(
            f"split {options.scheme}:{options.split} has no sequences"
            + (f" outside {sorted(genres)}" if genres else ""),
            store.path,
        )
    fps = {float(store.sequence(s)["fps"]) for s in seq_ids}
    if fps != {params.fps}:
        raise StoreError(f"the split's frame rates {sorted(fps)} differ from fps {params.fps}")
    euler_order = params.euler_order
    if "motion/euler" in store.array_names():
        euler_order = str(dict(store.zarr("motion/euler").attrs).get("order", euler_order))
    params = EvaluateParams(**{**params.as_dict(), "euler_order": euler_order})

    generated = Path(options.generated)
    gen_store = None
    if (generated / "store.json").is_file():
        gen_store = open_store(generated, options.generated_version)
    elif not generated.is_dir():
        raise InputError("--generated must be a folder of <seq_id> files or a store", generated)

    # The rest skeleton: a model file wins; SMPL-24 stores otherwise use edge_smpl_offsets.
    skeleton = None
    motion_skeleton = store.group_attrs("motion").get("skeleton") or {}
    if options.smpl_model or tuple(motion_skeleton.get("joints") or ()) == SMPL_JOINTS:
        skeleton = smpl_skeleton(options.smpl_model)
    model = None if skeleton is None else skeleton.model
    model_id = None if skeleton is None else skeleton.record()["smpl_model"]

    measures: dict[str, list[tuple[int, int]]] | None = None
    if store.has_table("measures"):
        measures = {}
        for m in store.measures.select(["seq_id", "frame_start", "frame_stop"]).to_pylist():
            measures.setdefault(m["seq_id"], []).append((m["frame_start"], m["frame_stop"]))
    seqs: list[EvalSequence] = []
    unreadable: list[dict[str, str]] = []
    sequences_info: list[dict[str, Any]] = []
    inputs: list[str] = []
    for seq_id in seq_ids:
        row = store.sequence(seq_id)
        try:
            if gen_store is not None:
                gen = _gen_from_store(gen_store, seq_id, model)
            else:
                file = find_generated_file(generated, seq_id)
                if file is None:
                    raise InputError(
                        f"no generated file {seq_id}{{{','.join(GENERATED_SUFFIXES)}}}", generated
                    )
                inputs.append(sha256_file(file))
                limit = generated_frame_limit(
                    int(row["n_frames"]), options.generated_fps, params.fps
                )
                gen = _gen_from_file(file, limit)
            gen = _adapt(gen, options, params.fps)
            gt, gt_missing = _gt_side(store, seq_id, model, euler_order)
            beats, beats_missing = _beats(store, seq_id, params.beat_source)
            seq, info = _pair(
                seq_id,
                row.get("music_id"),
                gt,
                gt_missing,
                gen,
                model,
                beats,
                beats_missing,
                params,
                None if measures is None else measures.get(seq_id, []),
            )
        except (DancedataError, ValueError) as exc:
            unreadable.append({"seq_id": seq_id, "reason": str(exc)})
            continue
        seqs.append(seq)
        sequences_info.append(info)
    if not seqs:
        reasons = "; ".join(f"{u['seq_id']}: {u['reason']}" for u in unreadable[:3])
        raise InputError(f"no sequence of the split could be scored ({reasons})", generated)

    reference = _reference_units(store, options, model, euler_order, measures)
    generations = None
    generations_info: dict[str, Any] | None = None
    if runs is not None:
        generations, problems, hashes = _generations(store, runs, seqs, options, model)
        generations_info = {
            "folder": str(options.generations),
            "runs": [r.name for r in runs],
            "group": "music_id",
            "files_sha256": hashes,
            "unread": problems,
        }
    evaluation = evaluate_sequences(seqs, params, unreadable, reference, generations)
    if skeleton is not None:  # every metric computed from joint positions names its skeleton
        rotation_only = rotation_only_outputs()  # metrics that need no joint positions
        for result in evaluation.results:
            if result.name not in rotation_only:
                result.convention["skeleton"] = skeleton.name
    config = {
        "params": params.as_dict(),
        "split": options.split,
        "scheme": options.scheme,
        "exclude_genres": sorted(genres),
        "row_key": options.row_key,
        "smpl_model": model_id,
        "skeleton": None if skeleton is None else skeleton.record(),
        "assumptions": {
            "generated_fps": options.generated_fps or "store fps",
            "generated_up_axis": options.generated_up_axis,
            "resampled_to": params.fps,
            "alignment": "frame i = frame i",
            "up_axis": "y",
            "units": "m, rad",
        },
    }
    gen_id = (
        {"store": str(gen_store.path), "version": gen_store.version}
        if gen_store is not None
        else {"folder": str(generated), "files_sha256": sorted(inputs)}
    )
    run_id = sha256_text(
        canonical_json(
            {
                "config": config,
                "store": store.manifest.get("fingerprint"),
                "store_version": store.version,
                "generated": gen_id,
                "generations": generations_info,
                "dancedata": __version__,
            }
        )
    )
    created = datetime.now(UTC).isoformat(timespec="seconds")
    unscored_by_seq: dict[str, dict[str, Any]] = {}
    for metric, items in evaluation.unscored.items():
        for item in items:
            entry = unscored_by_seq.setdefault(
                item["seq_id"], {"seq_id": item["seq_id"], "reasons": {}}
            )
            entry["reasons"].setdefault(item["reason"], []).append(metric)
    record = {
        "run_id": run_id,
        "row_key": options.row_key,
        "store": str(store.path),
        "store_version": store.version,
        "store_fingerprint": store.manifest.get("fingerprint"),
        "split": f"{options.scheme}:{options.split}",
        "genres_excluded": sorted(genres),
        "generated": {**gen_id, "layouts": sorted({i["layout"] for i in sequences_info})},
        "generations": generations_info,
        "dancedata_version": __version__,
        "created_at": created,
        "config": config,
        "n_sequences": len(seq_ids),
        "n_scored": len(seqs),
        "metrics": list(metric_names()),
        "results": [
            {**r.as_dict(), "unscored": evaluation.unscored.get(r.name, [])}
            for r in evaluation.results
        ],
        "skipped_metrics": evaluation.skipped_metrics,
        "unscored_sequences": list(unscored_by_seq.values()),
        "sequences": sequences_info,
    }
    out = options.out or Path("results") / f"evaluate-{run_id[:12]}"
    _write_record(Path(out), record, _long_rows(record, evaluation))
    return EvaluateSummary(record, Path(out))


def sha256_text(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode()).hexdigest()
