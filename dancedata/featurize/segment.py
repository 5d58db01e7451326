"""``dancedata segment``: the measures table, from each sequence's BPM and fps."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.beat_units import beat_grid, phrase_bounds
from dancedata.compute.downbeat import method_config
from dancedata.compute.measures import measure_grid
from dancedata.errors import InputError, StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.layout import warn_once
from dancedata.store.version_step import DerivedVersion, derive_version
from dancedata.store.writer import base_fingerprint


@dataclass
class SegmentOptions:
    beats_per_measure: int = 4
    phase_frames: float = 0.0
    version: str | None = None
    wait_for_lock: bool = False
    # --phase auto: each sequence's downbeat phase estimated from its music's features
    # (dancedata.compute.downbeat); phase_frames is then unused.
    phase_auto: bool = False
    # Which unit tables to write: measures always; beats and phrases on request.
    tables: tuple[str, ...] = ("measures",)
    phrase_measures: int = 4

    def __post_init__(self) -> None:
        unknown = sorted(set(self.tables) - set(UNIT_TABLES))
        if unknown:
            raise InputError(
                f"unknown segment table(s) {', '.join(unknown)}; choose from "
                f"{', '.join(UNIT_TABLES)}"
            )
        self.tables = tuple(t for t in UNIT_TABLES if t in self.tables or t == "measures")
        if self.phrase_measures < 1:
            raise InputError("--phrase-measures must be at least 1")

    def config(self) -> dict[str, Any]:
        # A numeric phase keeps the config (and so the fingerprint) it always had.
        config: dict[str, Any] = {
            "beats_per_measure": self.beats_per_measure,
            "phase_frames": "auto" if self.phase_auto else self.phase_frames,
            "formula": "fpm = 60/bpm*beats_per_measure*fps; "
            "[floor(phase+k*fpm+0.5), floor(phase+(k+1)*fpm+0.5)), complete measures only",
        }
        if self.phase_auto:
            config["phase_method"] = method_config(self.beats_per_measure)
        if self.tables != ("measures",):  # the measures-only config keeps its old fingerprint
            config["tables"] = list(self.tables)
            config["beats"] = "tempo grid: beat j at phase + j*60/bpm*fps, nearest frame"
            if "phrases" in self.tables:
                config["phrase_measures"] = self.phrase_measures
        return config


UNIT_TABLES = ("measures", "beats", "phrases")


def beat_rows(
    sequences: list[dict[str, Any]],
    options: SegmentOptions,
    phases: dict[str, float] | None = None,
) -> list[dict[str, Any]]:
    """One row per beat of the tempo grid inside every sequence with a BPM (the grid of the
    measures: beat_in_measure 0 is a measure's first beat, a downbeat)."""
    rows: list[dict[str, Any]] = []
    for seq in sequences:
        bpm, fps = seq.get("bpm"), float(seq["fps"])
        if bpm is None or not bpm > 0:
            continue
        phase = options.phase_frames if phases is None else phases.get(seq["seq_id"], 0.0)
        grid = beat_grid(int(seq["n_frames"]), float(bpm), fps, options.beats_per_measure, phase)
        for j, frame, exact, measure, number, down in zip(
            *(
                grid[k].tolist()
                for k in ("beat", "frame", "time_exact", "measure", "beat_in_measure", "downbeat")
            ),
            strict=True,
        ):
            rows.append(
                {
                    "seq_id": seq["seq_id"],
                    "beat": j,
                    "frame": frame,
                    "time": frame / fps,
                    "time_exact": exact,
                    "measure": measure,
                    "beat_in_measure": number,
                    "downbeat": down,
                    "bpm": float(bpm),
                }
            )
    return rows


def phrase_rows(
    sequences: list[dict[str, Any]], measures: list[dict[str, Any]], phrase_measures: int
) -> list[dict[str, Any]]:
    """One row per complete phrase of ``phrase_measures`` consecutive measures."""
    fps = {s["seq_id"]: float(s["fps"]) for s in sequences}
    by_seq: dict[str, list[tuple[int, int]]] = {}
    for m in measures:
        by_seq.setdefault(m["seq_id"], []).append((m["frame_start"], m["frame_stop"]))
    rows: list[dict[str, Any]] = []
    for seq_id, bounds in by_seq.items():
        for k, (first, last, start, stop) in enumerate(
            phrase_bounds(np.asarray(bounds), phrase_measures).tolist()
        ):
            rows.append(
                {
                    "seq_id": seq_id,
                    "phrase": k,
                    "measure_start": first,
                    "measure_stop": last,
                    "frame_start": start,
                    "frame_stop": stop,
                    "time_start": start / fps[seq_id],
                    "time_stop": stop / fps[seq_id],
                }
            )
    return rows


def measure_rows(
    sequences: list[dict[str, Any]],
    options: SegmentOptions,
    phases: dict[str, float] | None = None,
) -> list[dict[str, Any]]:
    """One row per complete measure of every sequence with a known BPM. ``phases`` (frames,
    per seq_id; --phase auto) overrides ``options.phase_frames`` and adds ``phase_frames``.
    ``time_start``/``time_stop`` are the whole-frame bounds in seconds; ``time_start_exact``/
    ``time_stop_exact`` the measure's unrounded boundaries (phase + k·fpm) / fps."""
    rows: list[dict[str, Any]] = []
    for seq in sequences:
        bpm, fps = seq.get("bpm"), float(seq["fps"])
        if bpm is None or not bpm > 0:
            continue
        phase = options.phase_frames if phases is None else phases.get(seq["seq_id"], 0.0)
        bounds, exact = measure_grid(
            int(seq["n_frames"]), float(bpm), fps, options.beats_per_measure, phase
        )
        exact_s = (exact / fps).tolist()
        for k, (start, stop) in enumerate(bounds.tolist()):
            rows.append(
                {
                    "seq_id": seq["seq_id"],
                    "measure": k,
                    "frame_start": start,
                    "frame_stop": stop,
                    "time_start": start / fps,
                    "time_stop": stop / fps,
                    "bpm": float(bpm),
                    "time_start_exact": exact_s[k][0],
                    "time_stop_exact": exact_s[k][1],
                    **({} if phases is None else {"phase_frames": float(phase)}),
                }
            )
    return rows


def check_measures(sequences: list[dict[str, Any]], rows: list[dict[str, Any]], where: str) -> None:
    """Loud, not empty: StoreError when no sequence yields a measure (no BPM, or all shorter
    than one measure), so no version without measures is written; a one-line warning when
    some sequences have no BPM and so no measures."""
    no_bpm = [s["seq_id"] for s in sequences if not (s.get("bpm") is not None and s["bpm"] > 0)]
    if not rows:
        if not sequences:
            reason = "the store has no sequences"
        elif len(no_bpm) == len(sequences):
            reason = (
                f"none of its {len(sequences)} sequences has a BPM (pass --bpm to the ingest, "
                "or ingest music with a known tempo)"
            )
        else:
            reason = (
                f"{len(sequences) - len(no_bpm)} sequences have a BPM but none is as long as one "
                "measure" + (f", and {len(no_bpm)} have no BPM" if no_bpm else "")
            )
        raise StoreError(f"no measures, nothing written: {reason}", where)
    if no_bpm:
        warn_once(
            f"segment: {len(no_bpm)} of {len(sequences)} sequences have no BPM and get no "
            f"measures (e.g. {no_bpm[0]})"
        )


def segment(store: str | Path | StoreBackend, options: SegmentOptions) -> CommandResult:
    """Write the measures table as a new version derived from ``options.version`` (default:
    the latest version, as it is once this writer holds the store lock)."""
    if options.beats_per_measure < 1:
        raise InputError("--beats-per-measure must be at least 1")
    with derive_version(store, "segment", options.version, options.wait_for_lock) as step:
        return _segment_step(step, options)


def _segment_step(step: DerivedVersion, options: SegmentOptions) -> CommandResult:
    reader = step.reader
    config = options.config()
    fp = step.fingerprint(config, [base_fingerprint(reader.manifest)])
    done = step.already_done(fp)
    if done is not None:
        return done
    sequences = reader.table("sequences").to_pylist()
    phases = tracks = None
    if options.phase_auto:
        from dancedata.featurize.segment_phase import downbeat_phases

        phases, tracks = downbeat_phases(reader, sequences, options.beats_per_measure)
    rows = measure_rows(sequences, options, phases)
    check_measures(sequences, rows, str(step.store))
    extra: dict[str, list[dict[str, Any]]] = {}
    if "beats" in options.tables:
        extra["beats"] = beat_rows(sequences, options, phases)
    if "phrases" in options.tables:
        extra["phrases"] = phrase_rows(sequences, rows, options.phrase_measures)
    with step.writer(config, fp) as version:
        version.write_table("measures", build_table("measures", rows))
        for table, table_rows in extra.items():
            version.write_table(table, build_table(table, table_rows))
        # One unit, committed atomically: segment is quick, so a killed run just starts over.
        counts = {
            "measures": len(rows),
            "sequences": len({r["seq_id"] for r in rows}),
            "units": 1,
            "resumed_units": 0,
            **{table: len(table_rows) for table, table_rows in extra.items()},
        }
        if tracks is not None:  # per music track: where beat 1 fell (the phase moved from 0)
            counts["phase"] = tracks
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts)
