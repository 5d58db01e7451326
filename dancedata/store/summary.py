"""What ``dancedata info`` reports about one version of a store."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dancedata.compute.bvh_units import USUAL_SIZE_M
from dancedata.store.backend import StoreBackend
from dancedata.store.checkout import checkout_log
from dancedata.store.integrity import CHECKSUMS_FILE
from dancedata.store.layout import TABLE_FILES, StoreLayout
from dancedata.store.reader import _VersionReader

# Per annotation kind: the sequences-table column (AIST++ ingest) and whether a row lacks it.
_MISSING_WHEN: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "keypoints3d": ("has_keypoints3d", lambda value: not value),
    "keypoints2d": ("has_keypoints2d", lambda value: not value),
    "cameras": ("camera_setting", lambda value: value is None),
    "music": ("music_missing", bool),
}


def annotations_missing(sequences: list[dict[str, Any]]) -> dict[str, int]:
    """Per annotation kind the sequences table tracks, how many sequences lack it."""
    if not sequences:
        return {}
    return {
        kind: sum(lacks(s[column]) for s in sequences)
        for kind, (column, lacks) in _MISSING_WHEN.items()
        if column in sequences[0]
    }


def lineage(layout: StoreLayout, version: str) -> list[dict[str, Any]]:
    """Manifests from ``version`` back through its parents (newest first)."""
    chain = []
    current: str | None = version
    seen: set[str] = set()
    while current and current not in seen and current in layout.committed_versions():
        seen.add(current)
        manifest = layout.read_manifest(current)
        chain.append(manifest)
        current = manifest.get("parent")
    return chain


def summarize(
    store: str | Path | StoreBackend | _VersionReader, version: str | None = None
) -> dict[str, Any]:
    """What ``dancedata info`` shows of ``version`` (default latest) of ``store``: a path or
    URL, the store's handle, or a version already open (then ``version`` is not used)."""
    reader = store if isinstance(store, _VersionReader) else _VersionReader(store, version)
    manifest = reader.manifest
    info: dict[str, Any] = {
        "store": reader.layout.backend.describe(),  # as given: a path, or a URL kept whole
        "version": reader.version,
        "latest": reader.layout.latest(),
        "versions": reader.layout.committed_versions(),
        "command": manifest.get("command"),
        "created_at": manifest.get("created_at"),
        "parent": manifest.get("parent"),
        "skipped": len(manifest.get("skipped", [])),
        "checkouts": checkout_log(reader.layout.backend),  # `dancedata checkout`, oldest first
    }
    if reader.has_table("sequences"):
        sequences = reader.table("sequences").to_pylist()
        info["sequences"] = len(sequences)
        frames = sum(s["n_frames"] for s in sequences)
        info["frames"] = frames
        info["hours"] = round(sum(s["n_frames"] / s["fps"] for s in sequences) / 3600.0, 4)
        info["sources"] = dict(Counter(s["source"] for s in sequences))
        genres = Counter(s["genre"] for s in sequences if s.get("genre") is not None)
        info["genres"] = dict(sorted(genres.items()))
        info["genre_missing"] = len(sequences) - sum(genres.values())
        info["bpms"] = sorted({s["bpm"] for s in sequences if s.get("bpm") is not None})
        # bpm_estimated (BVH / video ingest): tempo estimated from the audio, not given.
        info["bpms_estimated"] = sorted(
            {s["bpm"] for s in sequences if s.get("bpm") is not None and s.get("bpm_estimated")}
        )
        info["bpms_given"] = sorted(
            {s["bpm"] for s in sequences if s.get("bpm") is not None and not s.get("bpm_estimated")}
        )
        info["music_missing"] = sum(bool(s.get("music_missing")) for s in sequences)
        info["audio_truncated_sequences"] = sum(
            1 for s in sequences if (s.get("audio_truncated_frames") or 0) > 0
        )
        info["annotations_missing"] = annotations_missing(sequences)
        sizes = [
            float(s["rig_size_m"])
            for s in sequences
            if isinstance(s.get("rig_size_m"), int | float) and math.isfinite(s["rig_size_m"])
        ]
        if sizes:  # BVH ingest: the rig's size in metres (compute.bvh_units.rig_size)
            info["rig_size_m"] = {"min": min(sizes), "max": max(sizes), "sequences": len(sizes)}
    if reader.has_table("music"):
        info["music_tracks"] = reader.table("music").num_rows
    if reader.has_table("measures"):
        info["measures"] = reader.table("measures").num_rows
    if reader.has_table("cameras"):
        settings = reader.table("cameras").column("setting").to_pylist()
        info["camera_settings"] = sorted(set(settings))
    if reader.has_table("splits"):
        splits = Counter((r["scheme"], r["split"]) for r in reader.table("splits").to_pylist())
        table: dict[str, dict[str, int]] = {}
        for (scheme, split), n in sorted(splits.items()):
            table.setdefault(scheme, {})[split] = n
        info["splits_in_store"] = table
    for manifest_ in lineage(reader.layout, reader.version):
        if "splits" in manifest_.get("counts", {}):
            info["split_files"] = manifest_["counts"]["splits"]
            break
    info["arrays"] = {
        name: {"shape": list(reader.array(name).shape), "dtype": str(reader.array(name).dtype)}
        for name in reader.array_names()
    }
    info["tables"] = {
        name: reader.table(name).num_rows for name in TABLE_FILES if reader.has_table(name)
    }
    info["checksums_sha256"] = record_hash(reader)
    return info


def record_hash(reader: _VersionReader) -> str | None:
    """sha256 of the version's checksums.json: the end of the chain of integrity records
    (docs/STORE.md, 'What records the record'), to pin outside the store; None when the
    version has no record (versions from before checksums). Read through the version's
    backend, so local and object stores answer alike."""
    if not reader.files.is_file(CHECKSUMS_FILE):
        return None
    return reader.files.sha256(CHECKSUMS_FILE)


def format_info(info: dict[str, Any]) -> str:
    """Human-readable rendering of :func:`summarize`."""
    lines = [
        f"store     {info['store']}",
        f"version   {info['version']} (latest {info['latest']}; {len(info['versions'])} "
        f"committed) from `{info['command']}` at {info['created_at']}, "
        + (f"parent {info['parent']}" if info["parent"] else "the first version"),
    ]
    if "sequences" in info:
        lines.append(
            f"sequences {info['sequences']} ({info['frames']} frames, {info['hours']:.3f} h); "
            f"sources {info['sources']}"
        )
        lines.append(_genres_line(info))
        lines.append(_tempi_line(info))
        if info.get("rig_size_m"):
            lines.append(_rig_line(info["rig_size_m"]))
        if info.get("music_missing"):
            n = info["music_missing"]
            lines.append(f"music     missing for {n} sequence{'' if n == 1 else 's'}")
        for kind, n in info.get("annotations_missing", {}).items():
            if n and kind != "music":
                lines.append(f"missing   {kind} for {n} of {info['sequences']} sequences")
        if info.get("audio_truncated_sequences"):
            lines.append(
                f"audio     longer than motion (truncated) in "
                f"{info['audio_truncated_sequences']} sequences"
            )
    for key in ("music_tracks", "measures"):
        if key in info:
            lines.append(f"{key:<9} {info[key]}")
    if info.get("camera_settings"):
        lines.append(f"cameras   {len(info['camera_settings'])} settings of 9 views")
    if "split_files" in info:
        files = info["split_files"]
        line = f"ignore    {files.get('ignore_list', 0)} names in ignore_list.txt"
        if "ignore_list_in_store" in files:
            line += f", {files['ignore_list_in_store']} of them in the store"
        lines.append(line)
        for scheme, splits in files.get("schemes", {}).items():
            for split, c in splits.items():
                line = (
                    f"split     {scheme}/{split}: {c['listed']} listed, {c['ignored']} ignored, "
                    f"{c['usable']} usable, {c['in_store']} in store"
                )
                if c.get("missing_from_store"):
                    line += f" ({c['missing_from_store']} listed but not in the store: skipped)"
                lines.append(line)
    if "splits_in_store" in info:
        for scheme, splits in info["splits_in_store"].items():
            lines.append(f"in store  {scheme}: " + ", ".join(f"{k} {v}" for k, v in splits.items()))
    if info.get("skipped"):
        lines.append(f"skipped   {info['skipped']} inputs (see manifest.json)")
    lines.append("arrays")
    for name, spec in info["arrays"].items():
        lines.append(f"  {name:<28} {tuple(spec['shape'])} {spec['dtype']}")
    lines.append("tables    " + ", ".join(f"{k} ({v} rows)" for k, v in info["tables"].items()))
    if info.get("checksums_sha256"):
        lines.append(f"record    checksums.json sha256 {info['checksums_sha256']}")
    for entry in info.get("checkouts", []):
        lines.append(
            f"checkout  {entry.get('at')} {entry.get('by')}: latest {entry.get('previous')} "
            f"-> {entry.get('version')}"
        )
    return "\n".join(lines)


def _rig_line(rig: dict[str, Any]) -> str:
    """The BVH rigs' size: about the body height (the arm span when larger)."""
    low, high, n = rig["min"], rig["max"], rig["sequences"]
    size = f"{low:.2f} m" if round(low, 2) == round(high, 2) else f"{low:.2f}-{high:.2f} m"
    over = "" if n == 1 else f" over {n} sequences"
    line = f"rig       {size}{over} (body size: the largest side of a frame's bounding box)"
    usual_low, usual_high = USUAL_SIZE_M
    if low < usual_low or high > usual_high:
        line += f"; unusual for a person ({usual_low:g}-{usual_high:g} m): check --units"
    return line


def _genres_line(info: dict[str, Any]) -> str:
    missing = info.get("genre_missing", 0)
    if not info["genres"]:
        return "genres    none recorded (the source has no genre labels; --genre sets one)"
    tail = f"; {missing} sequences without one" if missing else ""
    return f"genres    {info['genres']}{tail}"


def _tempi_line(info: dict[str, Any]) -> str:
    """Given tempi (the dataset's, or --bpm) apart from tempi estimated from the audio."""
    given = info.get("bpms_given", info["bpms"])
    estimated = info.get("bpms_estimated", [])
    parts = []
    if given:
        parts.append(f"{_bpm_list(given)} BPM given (dataset or --bpm)")
    if estimated:
        parts.append(f"{_bpm_list(estimated)} BPM estimated from the audio (librosa beat_track)")
    return "tempi     " + ("; ".join(parts) if parts else "none (no music or no tempo)")


def _bpm_list(bpms: list[float]) -> str:
    return ", ".join(f"{b:g}" if float(b).is_integer() else f"{b:.2f}" for b in bpms)
