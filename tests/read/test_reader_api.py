"""The thin reader's public API (:mod:`dancedata.read.sequence_reader`), and the rule that code
outside the reader (views, viz, featurize, study, CLI, benches, examples) uses only that API,
never the private members of the reader classes (issue 15, item 5)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# The reader itself: the classes whose private members nobody else may touch.
READER_FILES = (
    "dancedata/read/sequence_reader.py",
    "dancedata/read/loader.py",
    "dancedata/store/reader.py",
)
# Code that must use the public API only.
CHECKED_DIRS = ("dancedata", "cli", "bench", "examples")
# (file, expression) still reaching into the reader, each with who removes it. May only shrink:
# delete the line when the access goes (a stale line fails the test).
KNOWN_PRIVATE_ACCESSES: set[tuple[str, str]] = set()


def _private_names() -> set[str]:
    """Single-underscore names the reader classes define: methods, properties and ``self._x``
    attributes of every class in :data:`READER_FILES`."""
    names: set[str] = set()
    for rel in READER_FILES:
        tree = ast.parse((ROOT / rel).read_text(encoding="utf-8"))
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            for node in ast.walk(cls):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    names.add(node.name)
                elif isinstance(node, ast.Assign):
                    names.update(t.id for t in node.targets if isinstance(t, ast.Name))
                elif (
                    isinstance(node, ast.Attribute)
                    and isinstance(node.value, ast.Name)
                    and node.value.id == "self"
                ):
                    names.add(node.attr)
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


def _private_accesses(private: set[str]) -> set[tuple[str, str]]:
    """(file, ``receiver._name``) for every access to one of ``private`` on anything but
    ``self``/``cls`` in the checked code outside the reader files."""
    found: set[tuple[str, str]] = set()
    for top in CHECKED_DIRS:
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel in READER_FILES:
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if not isinstance(node, ast.Attribute) or node.attr not in private:
                    continue
                if isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
                    continue
                found.add((rel, ast.unparse(node)))
    return found


def test_the_private_name_scan_sees_the_reader_internals() -> None:
    private = _private_names()
    # the cached row maps, the version reader and the array cache must be recognised, or the
    # next test would pass by seeing nothing
    assert {"_reader", "_music_rows", "_seq_rows", "_arrays", "_split_file_counts"} <= private
    assert not any(n.startswith("__") for n in private)


def test_nothing_outside_the_reader_touches_its_private_members() -> None:
    found = _private_accesses(_private_names())
    new = sorted(found - KNOWN_PRIVATE_ACCESSES)
    assert not new, (
        f"use the public reader API (dancedata/read/sequence_reader.py) instead of: {new}"
    )
    stale = sorted(KNOWN_PRIVATE_ACCESSES - found)
    assert not stale, f"fixed, delete from KNOWN_PRIVATE_ACCESSES: {stale}"


def test_the_old_private_aliases_are_gone() -> None:
    from dancedata.read.loader import DanceStore

    for alias in ("_full", "_no_music_reason"):
        assert not hasattr(DanceStore, alias), alias


@pytest.fixture(scope="module")
def store_missing_a_song(tmp_path_factory) -> tuple[Path, str]:
    """A synthetic AIST++ store (4 sequences) ingested with one song's wav deleted: the
    sequences of that song are stored with ``music_missing``. Returns (store, missing id)."""
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("reader-api")
    synth_aist(root / "raw", n_sequences=4, seed=7)
    gone = sorted((root / "raw" / "wav").iterdir())[0]
    gone.unlink()
    options = AistIngestOptions(allow_missing_music=True, annotations=[])
    ingest_aist(root / "store", root / "raw", options)
    return root / "store", gone.stem


@pytest.mark.slow
def test_music_track_is_the_music_table_row(store_missing_a_song: tuple[Path, str]) -> None:
    import pyarrow.parquet as pq

    from dancedata.read.loader import DanceStore

    store, missing = store_missing_a_song
    ds = DanceStore(store)
    # the reference: music.parquet read by pyarrow itself, not through the reader
    music = pq.read_table(store / "versions" / ds.version / "music.parquet").to_pylist()
    by_id = {m["music_id"]: m for m in music}
    assert missing not in by_id
    with_music = without = 0
    for seq_id in ds.seq_ids():
        row = ds.sequence(seq_id)
        track = ds.music_track(seq_id)
        if row["music_id"] == missing:
            without += 1
            assert track is None and ds.audio_frames(seq_id) == 0
            continue
        with_music += 1
        assert track == by_id[row["music_id"]]
        # audio_start is counted in the same global audio rows as the track's frame_start
        assert ds.audio_start(seq_id) == track["frame_start"] + row["audio_offset"]
    assert with_music and without
    # a copy: changing it does not change what the reader returns next time
    seq_id = next(s for s in ds.seq_ids() if ds.sequence(s)["music_id"] != missing)
    first = ds.music_track(seq_id)
    assert first is not None
    first["path"] = "elsewhere"
    assert ds.music_track(seq_id) == by_id[ds.sequence(seq_id)["music_id"]]


@pytest.mark.slow
def test_a_process_that_read_tables_exits_cleanly(store_missing_a_song: tuple[Path, str]) -> None:
    """A CLI that reads a store's tables and then exits (here after an error, as `plot STORE
    nope` does) must exit with its own code: pyarrow reading a Python file object (io.BytesIO)
    left IO threads that aborted about one exit in three with SIGABRT ("terminate called
    without an active exception"). 12 runs: the old reader failed this with p > 0.99. Then
    ``read_table`` over an Arrow buffer still started a scanner thread: 2 exits in 40 aborted
    with the thread pools pinned to one thread (OMP_NUM_THREADS=1 and the others, as here);
    ``ParquetFile.read`` starts none (0 in 60). 24 runs catch that rate with p ≈ 0.7, so the
    cause is checked too, without chance: the reads start no native thread."""
    import os
    import subprocess
    import sys

    from dancedata.exec.threads import thread_env

    store, _ = store_missing_a_song
    script = (
        "import sys, dancedata\n"
        f"ds = dancedata.open_store({str(store)!r})\n"
        "ds.seq_ids(); ds.splits; ds.music\n"
        "sys.exit(3)\n"
    )
    env = {**os.environ, **thread_env(1)}
    codes = [subprocess.run([sys.executable, "-c", script], env=env).returncode for _ in range(24)]
    assert codes == [3] * 24, codes
    # the cause, checked without chance: reading the tables starts no native thread
    count = "len(__import__('os').listdir('/proc/self/task'))"
    threads = (
        "import dancedata, pyarrow.parquet\n"
        f"before = {count}\n"
        f"ds = dancedata.open_store({str(store)!r})\n"
        "ds.seq_ids(); ds.splits; ds.music\n"
        f"print(before, {count})\n"
    )
    out = subprocess.run([sys.executable, "-c", threads], env=env, capture_output=True, text=True)
    before, after = map(int, out.stdout.split())
    assert after == before, f"reading the tables started {after - before} native thread(s)"
