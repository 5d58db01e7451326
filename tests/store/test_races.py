"""No lost update (issue 11, item 3): a writer that waited for the store lock plans its version
(parent, fingerprint, "already done") only once it holds the lock.

Each race is made deterministic without mocking anything: the first writer is a real
``dancedata featurize`` subprocess, frozen with SIGSTOP as soon as it holds the store lock (its
version not yet committed); the second command is started, and the test waits until it reports
"waiting for the store lock" before letting the first one go on (SIGCONT).
"""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests import race_harness as race
from tests.helpers import run_cli

# slow: concurrent CLI subprocesses race on one store
pytestmark = pytest.mark.slow

# Motion only: the race is about versions, not features, and this keeps featurize ~1 s of work.
FEATURIZE = ("featurize", "--no-audio", "-q")


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("races") / "raw"
    synth_aist(path, n_sequences=2, seed=3)
    return path


@pytest.fixture
def store(raw: Path, tmp_path: Path) -> Path:
    path = tmp_path / "store"
    run_cli("ingest", "aist", str(raw), "--store", str(path), "-q")
    return path


@pytest.fixture
def frozen_featurize(store: Path, tmp_path: Path) -> Iterator[subprocess.Popen]:
    """A featurize run stopped (SIGSTOP) while it holds the lock, before it commits."""
    proc = None
    try:
        proc = race.freeze(
            store,
            *FEATURIZE,
            str(store),
            stderr=tmp_path / "first.err",
            what="the first featurize to take the lock",
        )
        assert StoreLayout(store).committed_versions() == ["v1"], "froze it too late"
        yield proc
    finally:
        if proc is not None:
            race.finish(proc)


def _queue_behind(frozen: subprocess.Popen, tmp_path: Path, *args: str) -> tuple[str, str]:
    """Start ``dancedata ARGS --wait`` while ``frozen`` holds the lock, let ``frozen`` finish,
    and return the second command's (stdout, stderr)."""
    out_first, out, err = race.queue_behind(frozen, tmp_path, *args)
    assert "wrote version v2" in out_first
    return out, err


def test_segment_waiting_behind_featurize_keeps_the_features(frozen_featurize, store, tmp_path):
    out, _ = _queue_behind(frozen_featurize, tmp_path, "segment", str(store), "-q")
    assert "wrote version v3" in out
    layout = StoreLayout(store)
    assert layout.latest() == "v3"
    latest = _VersionReader(store)
    # The segment version derives from the featurize result, not from v1 as planned earlier.
    assert latest.manifest["parent"] == "v2"
    assert set(latest.manifest["stages"]) == {"ingest", "featurize", "segment"}
    assert latest.has_array("motion/quat") and latest.has_array("motion/rot6d")
    assert latest.table("measures").num_rows > 0
    assert validate_store(store) == []


def test_second_featurize_waiting_behind_the_same_featurize_writes_nothing(
    frozen_featurize, store, tmp_path
):
    out, _ = _queue_behind(frozen_featurize, tmp_path, *FEATURIZE, str(store))
    assert "nothing to do, version v2 already holds this result" in out
    assert StoreLayout(store).committed_versions() == ["v1", "v2"]
    assert StoreLayout(store).temp_dirs() == []
    assert not (store / LOCK_FILE).exists()


def test_second_ingest_of_the_same_data_waiting_for_the_lock_adds_no_duplicate(
    raw, store, tmp_path
):
    """Ingest plans before the lock (it reads its inputs first); the writer still finds the
    result committed by the writer it waited for and commits nothing."""
    other = tmp_path / "raw2"
    synth_aist(other, n_sequences=2, seed=4)
    holder = race.freeze(
        store,
        *FEATURIZE,
        str(store),
        stderr=tmp_path / "first.err",
        what="featurize to take the lock",
    )
    try:
        errs = [tmp_path / "ingest-a.err", tmp_path / "ingest-b.err"]
        ingests = [
            race.start(
                "ingest", "aist", str(other), "--store", str(store), "--wait", "-q", stderr=e
            )
            for e in errs
        ]
        for proc, err in zip(ingests, errs, strict=True):
            race.waiting(proc, err)
    finally:
        race.thaw(holder)
    holder.communicate(timeout=race.TIMEOUT_S)
    outs = [p.communicate(timeout=race.TIMEOUT_S)[0] for p in ingests]
    assert [p.returncode for p in ingests] == [0, 0], [e.read_text() for e in errs]
    committed = StoreLayout(store).committed_versions()
    assert committed == ["v1", "v2", "v3"], (committed, outs)  # v2 featurize, v3 one ingest
    fingerprints = [StoreLayout(store).read_manifest(v)["fingerprint"] for v in committed]
    assert len(set(fingerprints)) == len(fingerprints)
    assert all("v3" in out for out in outs)


def test_a_writer_based_on_a_version_that_is_no_longer_latest_refuses(store):
    """``based_on`` (for commands that read the latest version's data before the lock, such as
    an append): once another writer has committed, the write is refused with one line instead
    of dropping that writer's version; the store is left as it was."""
    from dancedata.errors import StoreError
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.store.writer import VersionWriter

    read_before_the_lock = StoreLayout(store).latest()
    assert segment(store, SegmentOptions()).version == "v2"  # another writer got in first
    writer = VersionWriter(
        store,
        command="test",
        config={},
        fingerprint="f" * 64,
        parent="v1",
        carry_over=False,
        based_on=read_before_the_lock,
    )
    changed = "read v1, the latest version is now v2; run it again"
    with pytest.raises(StoreError, match=changed), writer:
        pass
    assert StoreLayout(store).committed_versions() == ["v1", "v2"]
    assert StoreLayout(store).temp_dirs() == []
    assert not (store / LOCK_FILE).exists()
    with VersionWriter(
        store, command="test", config={}, fingerprint="f" * 64, parent="v2", based_on="v2"
    ) as version:
        assert version.commit() == "v3"
