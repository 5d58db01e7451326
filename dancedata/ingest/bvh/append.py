"""``ingest bvh --append``: the version appended to (read under the store lock), and the checks
that the new files fit it (new sequence ids; nothing to do when it holds them all already)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.errors import InputError
from dancedata.ingest.bvh.arrays import SOURCE
from dancedata.ingest.bvh.inputs import BvhInput
from dancedata.ingest.source import InputChecksums
from dancedata.io.bvh_attrs import is_bvh_skeleton
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader


@dataclass
class AppendedVersion:
    """What the version appended to (``--append``) contributes."""

    reader: _VersionReader
    attrs: dict[str, Any]
    rows: list[dict[str, Any]]
    music: list[dict[str, Any]]
    splits: list[dict[str, Any]]


def read_appended_version(store: str | Path, layout: StoreLayout) -> AppendedVersion:
    if not layout.exists():
        raise InputError("--append needs an existing store", store)
    reader = _VersionReader(store)
    attrs = reader.group_attrs("motion")
    if attrs.get("source") != SOURCE or not is_bvh_skeleton(attrs.get("skeleton")):
        raise InputError(
            f"--append adds to a BVH store, but version {reader.version} holds "
            f"{attrs.get('source') or 'another kind of'} data; ingest without --append or into "
            "another store",
            store,
        )
    return AppendedVersion(
        reader=reader,
        attrs=attrs,
        rows=reader.table("sequences").to_pylist(),
        music=reader.table("music").to_pylist() if reader.has_table("music") else [],
        splits=reader.table("splits").to_pylist() if reader.has_table("splits") else [],
    )


def already_appended(
    parent: AppendedVersion,
    inputs: list[BvhInput],
    checksums: InputChecksums,
    config: dict[str, Any],
    command: str,
) -> bool:
    """The parent was made by this command with these settings and already holds every input
    (same sequence id and content): appending them again has nothing to do."""
    if parent.reader.manifest.get("command") != command:
        return False
    old = {k: v for k, v in parent.reader.manifest.get("config", {}).items() if k != "append"}
    if old != {k: v for k, v in config.items() if k != "append"}:
        return False
    held = {r["seq_id"]: r for r in parent.rows}

    def same(item: BvhInput) -> bool:
        row = held.get(item.seq_id)
        return (
            row is not None
            and row["sha256"] == checksums.sha(item.path)
            and row["genre"] == item.genre
            and (item.bpm is None or row["bpm"] == item.bpm)
            and (row["music_id"] is None) == (item.music is None)
        )

    return all(same(item) for item in inputs)


def check_new_ids(parent: AppendedVersion, inputs: list[BvhInput]) -> None:
    present = {r["seq_id"] for r in parent.rows}
    for item in inputs:
        if item.seq_id in present:
            raise InputError(
                f"sequence {item.seq_id!r} is already in version {parent.reader.version}; "
                "rename the file, or ingest without --append",
                item.path,
            )
