"""``dancedata segment``: the measures table, from each sequence's BPM and fps."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.compute.downbeat import method_config
from dancedata.compute.measures import measure_grid
from dancedata.errors import InputError, StoreError
from dancedata.pipeline.version_step import DerivedVersion, derive_version
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.layout import warn_once
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
        return config


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


def segment(store: str | Path, options: SegmentOptions) -> CommandResult:
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
        from dancedata.pipeline.segment_phase import downbeat_phases

        phases, tracks = downbeat_phases(reader, sequences, options.beats_per_measure)
    rows = measure_rows(sequences, options, phases)
    check_measures(sequences, rows, str(step.store))
    with step.writer(config, fp) as version:
        version.write_table("measures", build_table("measures", rows))
        # One unit, committed atomically: segment is quick, so a killed run just starts over.
        counts = {
            "measures": len(rows),
            "sequences": len({r["seq_id"] for r in rows}),
            "units": 1,
            "resumed_units": 0,
        }
        if tracks is not None:  # per music track: where beat 1 fell (the phase moved from 0)
            counts["phase"] = tracks
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts)
