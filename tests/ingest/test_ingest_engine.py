"""The ingest engine with a source written here (issue 15 item 2): a source is one module.

``PointsSource`` reads a folder of ``.npy`` files (one sequence each, (frames, 3) metres at
30 fps) and nothing else; the engine gives it fingerprinting, ``--on-error``, parallel and
resumable reads, frame offsets, the sequences row, tables and the commit. Real stores
throughout (zarr arrays, Parquet tables, validate).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import dancedata.ingest.resumable_reads as reads_module
from dancedata.errors import InputError
from dancedata.ingest.engine import ingest, sequence_row
from dancedata.ingest.registry import register_source, source_named
from dancedata.ingest.source import (
    Finished,
    IngestPlan,
    IngestTotals,
    InputChecksums,
    MusicTable,
    ReadTask,
    SequenceRecord,
    SkipPolicy,
    Source,
    StoredArray,
)
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store

FPS = 30.0


def read_points(path: str) -> np.ndarray:
    """The read function: top level, so process pools can run it."""
    try:
        points = np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise InputError(f"not a .npy array ({exc})", path) from None
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"expected (frames, 3) points, found shape {points.shape}", path)
    return points


@register_source("test_points")
class PointsSource(Source):
    command = "ingest points"

    def __init__(self, folder: Path, on_error: str = "fail", workers: int = 1) -> None:
        self.folder, self.on_error, self.workers = folder, on_error, workers

    def plan(self, store: Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        files = sorted(self.folder.glob("*.npy"))
        self.checksums = checksums
        return IngestPlan(
            config={"fps": FPS, "on_error": self.on_error},
            fingerprint_keys=[f"{p.stem}|{checksums.sha(p)}" for p in files],
            inputs=None,
            tasks=[ReadTask(str(p), str(p)) for p in files],
            parse=read_points,
            task_kind="points",
            arrays=[StoredArray("positions", (1, 3), np.float32, attrs={"units": "m"})],
            batch_size=2,
            workers=self.workers,
        )

    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        value = parsed()
        return SequenceRecord(
            seq_id=Path(task.path).stem,
            source="points",
            path=task.path,
            sha256=self.checksums.sha(Path(task.path)),
            fps=FPS,
            n_frames=len(value),
            arrays={"positions": value[:, None, :]},  # one joint
        )

    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        skeleton = {"name": "point", "joints": ["point"], "parents": [-1]}
        motion = {"fps": FPS, "up_axis": "y", "source": "points", "skeleton": skeleton}
        music = MusicTable()
        return Finished(
            music=music,
            counts=totals.counts(music),
            tables={"splits": []},
            attrs={"motion": motion},
        )


def write_points(folder: Path, lengths: list[int]) -> list[np.ndarray]:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    arrays = []
    for k, n in enumerate(lengths):
        points = rng.normal(size=(n, 3)).astype(np.float32)
        np.save(folder / f"seq{k:02d}.npy", points)
        arrays.append(points)
    return arrays


def data_files(store: Path) -> dict[str, str]:
    """checksums.json's per-file checksums of v1 (the manifest, which records times, left out)."""
    return json.loads((store / "versions" / "v1" / "checksums.json").read_text())["files"]


def test_a_source_module_gets_a_whole_store(tmp_path: Path) -> None:
    arrays = write_points(tmp_path / "in", [5, 7, 3, 9, 4])
    store = tmp_path / "store"
    result = ingest(store, source_named("test_points")(tmp_path / "in"))
    assert result.created and result.counts["sequences"] == 5 and result.counts["frames"] == 28
    assert result.counts["units"] == 3  # five files in read tasks of two
    reader = _VersionReader(store)
    rows = reader.table("sequences").to_pylist()
    assert [r["frame_start"] for r in rows] == [0, 5, 12, 15, 24]
    assert [r["frame_stop"] - r["frame_start"] for r in rows] == [5, 7, 3, 9, 4]
    assert all(r["music_missing"] and r["audio_frames"] == 0 for r in rows)
    assert np.array_equal(reader.array("motion/positions")[:, 0], np.concatenate(arrays))
    assert reader.group_attrs("motion")["fps"] == FPS
    assert [i["path"] for i in reader.manifest["inputs"]] == [r["path"] for r in rows]
    assert validate_store(store) == []
    again = ingest(store, PointsSource(tmp_path / "in"))
    assert not again.created and again.version == "v1"


def test_bad_input_fails_with_its_file_or_is_skipped(tmp_path: Path) -> None:
    write_points(tmp_path / "in", [5, 6, 7])
    np.save(tmp_path / "in" / "seq01.npy", np.zeros((4, 2), np.float32))
    with pytest.raises(InputError, match=r"seq01\.npy.*found shape \(4, 2\)"):
        ingest(tmp_path / "failed", PointsSource(tmp_path / "in"))
    assert not StoreLayout(tmp_path / "failed").committed_versions()

    result = ingest(tmp_path / "store", PointsSource(tmp_path / "in", on_error="skip"))
    assert result.counts["sequences"] == 2 and result.counts["frames"] == 12
    assert [s["path"] for s in result.skipped] == [str(tmp_path / "in" / "seq01.npy")]
    rows = _VersionReader(tmp_path / "store").table("sequences").to_pylist()
    assert [(r["seq_id"], r["frame_start"]) for r in rows] == [("seq00", 0), ("seq02", 5)]


def test_workers_write_the_same_bytes(tmp_path: Path) -> None:
    write_points(tmp_path / "in", [50, 70, 30, 90, 40, 20, 10])
    ingest(tmp_path / "serial", PointsSource(tmp_path / "in"))
    ingest(tmp_path / "parallel", PointsSource(tmp_path / "in", workers=2))
    assert data_files(tmp_path / "serial") == data_files(tmp_path / "parallel")


def test_an_interrupted_ingest_resumes_its_finished_read_tasks(tmp_path, monkeypatch) -> None:
    write_points(tmp_path / "in", [5, 7, 3, 9, 4, 6])
    ingest(tmp_path / "reference", PointsSource(tmp_path / "in"))
    calls = {"n": 0}
    real = reads_module.read_batch

    def crash_on_third(*args: Any) -> Any:
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(*args)

    monkeypatch.setattr(reads_module, "read_batch", crash_on_third)
    with pytest.raises(KeyboardInterrupt):
        ingest(tmp_path / "store", PointsSource(tmp_path / "in"))
    monkeypatch.setattr(reads_module, "read_batch", real)
    resumed = ingest(tmp_path / "store", PointsSource(tmp_path / "in"))
    assert resumed.counts["units"] == 3 and resumed.counts["resumed_units"] == 2
    assert data_files(tmp_path / "store") == data_files(tmp_path / "reference")


def test_sources_are_found_by_name() -> None:
    from dancedata.ingest.aist import AistSource
    from dancedata.ingest.bvh import BvhSource

    assert source_named("bvh") is BvhSource and source_named("aist") is AistSource
    with pytest.raises(InputError, match="unknown ingest source 'nope'"):
        source_named("nope")
    with pytest.raises(ValueError, match="already registered"):
        register_source("bvh")(type("OtherBvh", (Source,), {}))


def test_the_sequence_row_says_how_music_covers_the_motion() -> None:
    record = SequenceRecord(
        seq_id="a", source="x", path="/in/a", sha256="0" * 64, fps=60.0, n_frames=100,
        arrays={}, music_key="m", bpm=None, bpm_estimated=True,
        name_columns={"camera": "c01"}, columns={"extra": 1},
    )  # fmt: skip
    record.frame_start = 40
    music = {"music_id": "m1", "frame_start": 10, "frame_stop": 130, "bpm": 96.0}
    row = sequence_row(record, music)
    assert (row["frame_start"], row["frame_stop"], row["audio_offset"]) == (40, 140, 0)
    assert (row["audio_frames"], row["audio_truncated_frames"]) == (100, 20)
    assert (row["music_id"], row["bpm"], row["bpm_estimated"]) == ("m1", 96.0, True)
    assert row["music_missing"] is False
    keys = list(row)
    assert keys.index("camera") < keys.index("audio_frames") < keys.index("extra")
    short = sequence_row(record, music | {"frame_stop": 70})
    assert (short["audio_frames"], short["audio_truncated_frames"]) == (60, 0)
    alone = sequence_row(record, None)
    assert alone["music_missing"] and alone["audio_frames"] == 0 and alone["bpm"] is None
    assert alone["bpm_estimated"] is None  # no tempo, nothing estimated


def test_each_source_folders_options_are_its_command() -> None:
    """``cli/ingest.py`` builds ``dancedata ingest <name>`` from the folder's ``Options``: one
    parameter per field, in field order, with the field's default, then --quiet and --json."""
    from dataclasses import MISSING, fields

    from dancedata.cli.main import build_command

    from dancedata.ingest.options import source_options

    commands = build_command().commands["ingest"].commands
    found = source_options()
    assert sorted(found) == sorted(commands) == ["aist", "bvh", "generated", "music", "video"]
    for name, options in found.items():
        params = {p.name: p for p in commands[name].params}
        assert list(params) == [f.name for f in fields(options)] + ["quiet", "as_json"], name
        for item in fields(options):
            default = params[item.name].default
            expected = None if item.default is MISSING else item.default
            assert getattr(default, "value", default) == expected, (name, item.name)
