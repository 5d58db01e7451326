"""A store is untrusted input: the readers' limits, one function at a time, and every hostile
store case of tests/data/bad/hostile_store.py run through the CLI (exit code, one line naming
the file, one JSON object under --json, no traceback, bounded time)."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import StoreError
from dancedata.store.chunks import ChunkGrid, decoded_size_problem, zstd_content_size
from dancedata.store.metadata_checks import (
    MAX_CHUNKS,
    array_meta_problem,
    counts_problem,
    fps_problem,
    group_attrs_problem,
    skeleton_problem,
    table_problem,
)
from dancedata.store.references import parse_references
from dancedata.store.untrusted import (
    JSON_MAX_DEPTH,
    UnsafeFile,
    parse_json,
    read_regular,
    special_entries,
)
from tests.data.bad import hostile_store
from tests.data.bad.hostile import all_cases
from tests.helpers import run_cli


# -- JSON --------------------------------------------------------------------------------------
def test_deep_json_is_refused_by_name_not_recursion():
    for depth in (100_000, JSON_MAX_DEPTH + 1):
        with pytest.raises(StoreError, match=r"store\.json: unreadable store\.json: nested"):
            parse_json(hostile_store.nested(depth), "S/store.json", "store.json")
    assert parse_json(hostile_store.nested(JSON_MAX_DEPTH), "x", "x") is not None
    deep_object = "{" + '"a":{' * 80 + "}" * 81
    with pytest.raises(StoreError, match="nested deeper than 64"):
        parse_json(deep_object, "x", "manifest")


def test_json_number_of_5000_digits_is_one_error():
    with pytest.raises(StoreError, match="unreadable manifest: Exceeds the limit"):
        parse_json('{"n": ' + "9" * 5000 + "}", "m.json", "manifest")


# -- files -------------------------------------------------------------------------------------
def test_read_regular_refuses_links_fifos_devices_and_oversize(tmp_path):
    good = tmp_path / "good.json"
    good.write_bytes(b"{}")
    assert read_regular(good, 10) == b"{}"
    link = tmp_path / "link.json"
    link.symlink_to(good)
    with pytest.raises(UnsafeFile, match="symbolic link"):
        read_regular(link)
    zero = tmp_path / "zero"
    zero.symlink_to("/dev/zero")
    with pytest.raises(UnsafeFile, match="symbolic link"):
        read_regular(zero)
    with pytest.raises(UnsafeFile, match="device"):
        read_regular("/dev/zero")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    outcome: list[BaseException] = []
    thread = threading.Thread(target=lambda: _capture(outcome, read_regular, fifo), daemon=True)
    thread.start()
    thread.join(5)
    assert not thread.is_alive(), "reading a FIFO blocked"
    assert isinstance(outcome[0], UnsafeFile) and "FIFO" in str(outcome[0])
    sparse = tmp_path / "sparse.json"
    with sparse.open("wb") as handle:
        handle.truncate(2 << 30)
    started = time.process_time()
    with pytest.raises(UnsafeFile, match="2,147,483,648 bytes, over the reader's limit"):
        read_regular(sparse, 1 << 20)
    assert time.process_time() - started < 0.5  # refused from fstat, never read


def _capture(outcome, function, *args):
    try:
        outcome.append(function(*args))
    except BaseException as exc:  # noqa: BLE001 - handed to the test
        outcome.append(exc)


def test_special_entries_names_links_and_fifos_without_following(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "b" / "chunk").write_bytes(b"x")
    (tmp_path / "a" / "out").symlink_to("/", target_is_directory=True)
    os.mkfifo(tmp_path / "a" / "b" / "pipe")
    found = special_entries(tmp_path)
    assert found == [("a/b/pipe", "a FIFO (named pipe)"), ("a/out", "a symbolic link")]


# -- zarr metadata -----------------------------------------------------------------------------
def _rotmat_meta(store: Path) -> dict:
    return json.loads(
        (hostile_store.version(store) / hostile_store.ROTMAT / "zarr.json").read_text()
    )


GOOD_META = {
    "shape": [1164, 24, 3, 3],
    "data_type": "float32",
    "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [8192, 24, 3, 3]}},
    "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
    "fill_value": 0.0,
    "codecs": [
        {"name": "bytes", "configuration": {"endian": "little"}},
        {"name": "zstd", "configuration": {"level": 0, "checksum": False}},
        {"name": "crc32c"},
    ],
    "attributes": {},
    "zarr_format": 3,
    "node_type": "array",
    "storage_transformers": [],
}


def _meta(**change) -> dict:
    meta = json.loads(json.dumps(GOOD_META))
    for key, value in change.items():
        if key == "chunk_shape":
            meta["chunk_grid"]["configuration"]["chunk_shape"] = value
        else:
            meta[key] = value
    return meta


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"shape": [3_000_000, 24, 3, 3], "chunk_shape": [1, 24, 3, 3]}, "3e\\+06 chunks"),
        ({"shape": [10**15, 24, 3, 3], "chunk_shape": [1, 24, 3, 3]}, "2\\*\\*40"),
        ({"shape": [10**6, 10**6, 3, 3], "chunk_shape": [10**6, 10**6, 3, 3]}, "elements, over"),
        ({"chunk_shape": [0, 24, 3, 3]}, "integer in \\[1, 2\\*\\*40\\)"),
        ({"chunk_shape": [-1, 24, 3, 3]}, "integer in \\[1, 2\\*\\*40\\)"),
        (
            {"shape": [4629629629, 24, 3, 3], "chunk_shape": [4629629629, 24, 3, 3]},
            "bytes decoded, over the limit",
        ),
        ({"shape": "1164"}, "shape must be a list"),
        ({"shape": [True, 24, 3, 3]}, "every entry must be an integer"),
        ({"chunk_shape": [8192, 24, 3]}, "differ in rank"),
        ({"data_type": "evil128"}, "unknown data type 'evil128'"),
        ({"codecs": [{"name": "bytes"}, {"name": "evil"}]}, "unknown codec 'evil'"),
        ({"codecs": [{"name": "bytes"}, {"name": "gzip"}]}, "unknown codec 'gzip'"),
        ({"zarr_format": 2}, "zarr_format 2"),
    ],
)
def test_array_metadata_out_of_bounds_is_refused_by_arithmetic(change, message):
    started = time.process_time()
    problem = array_meta_problem(_meta(**change))
    assert problem is not None and re.search(message, problem), problem
    assert time.process_time() - started < 0.05  # never enumerates chunks
    assert ChunkGrid.from_metadata(_meta(**change)) is None


def test_good_array_metadata_passes_and_its_grid_counts_chunks():
    assert array_meta_problem(GOOD_META) is None
    grid = ChunkGrid.from_metadata(GOOD_META)
    assert grid is not None and grid.n_chunks == 1 and grid.chunk_bytes == 8192 * 216 * 4
    limit = _meta(shape=[MAX_CHUNKS, 1, 1, 1], chunk_shape=[1, 1, 1, 1])
    assert array_meta_problem(limit) is None
    over = _meta(shape=[MAX_CHUNKS + 1, 1, 1, 1], chunk_shape=[1, 1, 1, 1])
    assert "chunks, over the limit" in array_meta_problem(over)


def test_zstd_header_size_matches_numcodecs_and_bombs_are_refused_before_decoding():
    from numcodecs import Zstd

    data = np.arange(8192 * 216, dtype=np.float32)
    frame = Zstd(level=0).encode(data)
    assert zstd_content_size(frame) == data.nbytes  # what numcodecs allocates
    grid = ChunkGrid.from_metadata(GOOD_META)
    good = hostile_store.with_crc32c(bytes(frame))
    assert decoded_size_problem(grid, np.frombuffer(good, np.uint8)) is None
    bomb = hostile_store.zstd_rle_bomb(800 * 1024 * 1024)
    assert len(bomb) < 30_000
    assert zstd_content_size(bomb) == 800 * 1024 * 1024
    # the bomb is a real zstd frame: numcodecs decodes a small one to what it declares
    small = hostile_store.zstd_rle_bomb(300_000, byte=7)
    assert bytes(Zstd().decode(small)) == bytes([7]) * 300_000
    problem = decoded_size_problem(grid, np.frombuffer(hostile_store.with_crc32c(bomb), np.uint8))
    assert "838,860,800 decoded bytes" in problem and "7,077,888" in problem


# -- values ------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", [0, 0.0, -60.0, math.nan, math.inf, 1e300, "60", None, True])
def test_fps_must_be_a_finite_positive_number(value):
    assert fps_problem(value) is not None


def test_fps_of_real_stores_pass():
    for value in (60, 60.0, 29.97, 120.0):
        assert fps_problem(value) is None


def test_skeleton_must_be_a_tree_with_one_root():
    from dancedata.compute.smpl import SMPL_PARENTS

    joints = [f"j{i}" for i in range(len(SMPL_PARENTS))]
    good = {"joints": joints, "parents": list(SMPL_PARENTS)}
    assert skeleton_problem(good) is None
    cycle = dict(good, parents=[1, 0, *SMPL_PARENTS[2:]])
    assert "roots" in skeleton_problem(cycle)
    loop = dict(good, parents=[-1, 2, 1, *SMPL_PARENTS[3:]])
    assert "cycle through joint" in skeleton_problem(loop)
    two_roots = dict(good, parents=[-1, -1, *SMPL_PARENTS[2:]])
    assert "2 roots" in skeleton_problem(two_roots)
    assert "joint index" in skeleton_problem(dict(good, parents=[-1, 99, *SMPL_PARENTS[2:]]))
    assert "one per joint" in skeleton_problem(dict(good, parents=[-1]))
    assert "group motion" in group_attrs_problem("motion", {"skeleton": cycle})
    # a long chain is walked once (no quadratic walk)
    chain = {"joints": [str(i) for i in range(100_000)], "parents": [-1, *range(99_999)]}
    started = time.process_time()
    assert skeleton_problem(chain) is None
    assert time.process_time() - started < 2


def test_table_values_are_bounded():
    import pyarrow as pa

    ok = pa.table({"fps": [60.0], "bpm": [float("nan")], "n_frames": [640]})
    assert table_problem("sequences", ok) is None
    assert "bpm 1e+300" in table_problem("sequences", pa.table({"bpm": [120.0, 1e300]}))
    assert "frame_stop 100000000000000000" in table_problem(
        "measures", pa.table({"frame_stop": [10**17]})
    )
    assert "fps" in table_problem("sequences", pa.table({"fps": [0.0]}))


def test_manifest_counts_of_the_wrong_type():
    assert counts_problem({"sequences": 2, "splits": {"schemes": {}}}) is None
    assert "'splits' is 'x'" in counts_problem({"splits": "x"})
    assert "'sequences' is [[[2]]]" in counts_problem({"sequences": [[[2]]]})
    assert "crossmodal.train" in counts_problem(
        {"splits": {"schemes": {"crossmodal": {"train": "x"}}}}
    )


def test_references_must_name_versions_and_paths_inside_them():
    def body(files):
        return json.dumps(
            {"format": "dancedata-references", "format_version": 1, "files": files}
        ).encode()

    assert parse_references(body({"sequences.parquet": "v1"}), "r") == {"sequences.parquet": "v1"}
    for files in (
        {"sequences.parquet": "../../etc"},
        {"../x": "v1"},
        {"/etc/passwd": "v1"},
        {"a/./b": "v1"},
    ):
        with pytest.raises(StoreError, match="plain path inside it"):
            parse_references(body(files), "r")
    with pytest.raises(StoreError, match="nested deeper"):
        parse_references(hostile_store.nested(100_000), "r")


# -- every hostile store case, through the CLI ------------------------------------------------
CASES = {
    n: c
    for n, c in all_cases().items()
    if n.split("/")[0] in ("store-metadata", "arrays", "links", "values")
}


def _copy(store: Path, dest: Path) -> Path:
    shutil.copytree(store, dest, symlinks=True)
    return dest


def _json_object(stdout: str) -> dict:
    value = json.loads(stdout)
    assert isinstance(value, dict)
    return value


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_hostile_store_case_is_refused(name, small_featurized_store, tmp_path):
    """Each case's validate and first two other commands (all of them with
    DANCEDATA_HOSTILE_ALL=1): the expected exit, no traceback, the message naming the file,
    one JSON object under --json, within the case's time."""
    case = CASES[name]
    (tmp_path / "plain").mkdir()
    (tmp_path / "json").mkdir()
    store = _copy(small_featurized_store, tmp_path / "plain" / "store")
    commands = case.plant(tmp_path / "plain", store)
    # the same case planted again for the --json runs (a refusal may clean up what it refused)
    again = _copy(small_featurized_store, tmp_path / "json" / "store")
    json_commands = case.plant(tmp_path / "json", again)
    chosen = list(range(len(commands)))
    if not os.environ.get("DANCEDATA_HOSTILE_ALL"):
        first = [i for i in chosen if commands[i].argv[0] == "validate"][:1]
        chosen = first + [i for i in chosen if commands[i].argv[0] != "validate"][:2]
    for index in chosen:
        command = commands[index]
        started = time.monotonic()
        proc = run_cli(*command.argv, check=False, timeout=case.timeout_s)
        spent = time.monotonic() - started
        where = f"{name}: dancedata {' '.join(command.argv[:2])}"
        assert "Traceback" not in proc.stderr, f"{where}\n{proc.stderr[-3000:]}"
        assert proc.returncode == command.expect_exit, (
            f"{where}: exit {proc.returncode}\n{proc.stderr[-2000:]}"
        )
        assert len(proc.stderr.splitlines()) <= 60, where  # bounded output
        if command.expect and command.expect_exit == 1 and command.argv[0] != "validate":
            assert re.search(command.expect, proc.stderr), f"{where}: {proc.stderr[-800:]}"
        assert spent < case.timeout_s, where
        if command.json or case.name == "links/build_area_symlink":
            argv = json_commands[index].argv
            proc = run_cli(*argv, "--json", check=False, timeout=case.timeout_s)
            assert proc.returncode == command.expect_exit, where
            record = _json_object(proc.stdout)
            if command.expect_exit == 1 and command.argv[0] != "validate":
                assert re.search(command.expect, record.get("error", "")), (where, record)


@pytest.mark.slow
def test_parquet_declaring_millions_of_rows_is_refused_from_its_footer(tmp_path):
    from dancedata.store.reader import parquet_size_problem

    path = tmp_path / "bomb.parquet"
    hostile_store.rle_bomb_parquet(path, rows=60_000_000)
    assert path.stat().st_size < 2_000_000
    problem = parquet_size_problem(path.read_bytes())
    assert problem is not None and "60,000,000 rows, over the limit" in problem


def test_declared_chunks_beyond_the_files_present_are_one_problem_not_a_listing(tmp_path):
    from dancedata.store.integrity import chunk_requirements

    array = tmp_path / "data.zarr" / "motion" / "rotmat"
    array.mkdir(parents=True)
    meta = _meta(shape=[900_000, 24, 3, 3], chunk_shape=[1, 24, 3, 3])
    (array / "zarr.json").write_text(json.dumps(meta))
    (array / "c" / "0" / "0" / "0").mkdir(parents=True)
    (array / "c" / "0" / "0" / "0" / "0").write_bytes(b"x")
    started = time.process_time()
    required, problems = chunk_requirements(tmp_path)
    assert time.process_time() - started < 1.0
    assert required == {}
    assert len(problems) == 1 and "call for 900,000 chunks, but its folder holds 1" in problems[0]
