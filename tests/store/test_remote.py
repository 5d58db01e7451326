"""Stores on S3 through fsspec, against a real S3-compatible server (moto, server mode) that
the test starts on 127.0.0.1: write a store with the CLI, read it back, and check what the
commit protocol promises (store.json is the commit point, one writer at a time)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import dancedata
from dancedata.errors import StoreError
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.store.writer import VersionWriter
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli
from tests.s3_server import moto_s3

# slow: a moto S3 server on loopback; stores written and read over it
pytestmark = pytest.mark.slow

moto_server = pytest.importorskip("moto.server")
s3fs = pytest.importorskip("s3fs")

BUCKET = "dance"


@pytest.fixture(scope="module")
def s3_env():
    """A moto S3 server on loopback, and the environment that points clients at it."""
    with moto_s3(BUCKET) as env:
        yield env


@pytest.fixture(scope="module")
def stores(s3_env, tmp_path_factory):
    """The same raw data through the CLI into S3 and through the library into a local dir."""
    root = tmp_path_factory.mktemp("remote")
    raw, local = root / "raw", root / "local"
    synth_aist(raw, n_sequences=3, seed=4)
    url = f"s3://{BUCKET}/stores/demo"
    env = {**s3_env, "DANCEDATA_CACHE": str(root / "cache-remote")}  # compute, never load
    run_cli("ingest", "aist", str(raw), "--store", url, "-q", env=env)
    run_cli("featurize", url, "-q", "--workers", "2", env=env)
    run_cli("segment", url, "-q", env=env)
    ingest_aist(local, raw, AistIngestOptions())
    featurize(local, FeaturizeOptions(cache_dir=str(root / "cache-local")))
    segment(local, SegmentOptions())
    return {"url": url, "local": local, "raw": raw}


def test_remote_store_holds_the_same_data_as_a_local_one(stores):
    remote, local = dancedata.open_store(stores["url"]), dancedata.open_store(stores["local"])
    assert remote.version == "v3"
    assert remote.array_names() == local.array_names()
    for name in local.array_names():
        assert np.array_equal(remote.zarr(name)[...], local.zarr(name)[...], equal_nan=True), name
    for table in ("sequences", "measures", "splits"):
        assert (
            remote.table(table)
            .drop_columns(["path"] if table == "sequences" else [])
            .equals(local.table(table).drop_columns(["path"] if table == "sequences" else []))
        )
    seq = local.seq_ids()[0]
    assert np.array_equal(remote.view(seq, "fact_audio_35"), local.view(seq, "fact_audio_35"))


def test_remote_store_is_valid_and_listed(stores, s3_env):
    assert validate_store(stores["url"]) == []
    out = run_cli("versions", stores["url"], "--json", env=s3_env).stdout
    assert [row["version"] for row in json.loads(out)] == ["v1", "v2", "v3"]
    info = json.loads(run_cli("info", stores["url"], "--json", env=s3_env).stdout)
    assert info["version"] == "v3" and info["sequences"] == 3
    fs = s3fs.S3FileSystem()
    assert not fs.glob(f"{BUCKET}/stores/demo/versions/.tmp-*")  # temporaries removed
    assert not fs.exists(f"{BUCKET}/stores/demo/.lock")


def test_a_version_copied_but_not_pointed_to_is_invisible_and_replaced(stores):
    """A writer that died after copying v4 but before rewriting store.json committed nothing."""
    fs = s3fs.S3FileSystem()
    prefix = f"{BUCKET}/stores/demo/versions"
    fs.copy(f"{prefix}/v3", f"{prefix}/v4", recursive=True)  # manifest and all
    layout = StoreLayout(stores["url"])
    assert layout.committed_versions() == ["v1", "v2", "v3"] and layout.latest() == "v3"
    assert dancedata.open_store(stores["url"]).version == "v3"
    # The next writer takes the name v4 over: it is rebuilt, then committed.
    result = segment(stores["url"], SegmentOptions(beats_per_measure=2))
    assert result.version == "v4" and layout.latest() == "v4"
    assert layout.read_manifest("v4")["config"]["beats_per_measure"] == 2
    two_beat = dancedata.open_store(stores["url"]).measures.num_rows
    assert two_beat > dancedata.open_store(stores["url"], "v3").measures.num_rows


def test_one_writer_at_a_time(stores):
    common = {"command": "test", "config": {}, "fingerprint": "f" * 64}
    with (
        VersionWriter(stores["url"], **common),
        pytest.raises(StoreError, match="locked by another writer"),
        VersionWriter(stores["url"], **common),
    ):
        pass
    with VersionWriter(stores["url"], **common):  # released: free again
        pass


def test_featurize_on_s3_resumes_after_a_crash(stores, monkeypatch, tmp_path):
    import dancedata.featurize.featurize as featurize_module

    url = f"s3://{BUCKET}/stores/resume"
    ingest_aist(url, stores["raw"], AistIngestOptions())
    real = featurize_module.run_audio_task
    calls = {"n": 0}

    def crash_on_second_track(job, unit):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError("connection reset")
        return real(job, unit)

    monkeypatch.setattr(featurize_module, "run_audio_task", crash_on_second_track)
    monkeypatch.setenv("DANCEDATA_CACHE", str(tmp_path / "feature-cache"))
    with pytest.raises(OSError):
        featurize(url, FeaturizeOptions())
    layout = StoreLayout(url)
    assert layout.committed_versions() == ["v1"] and len(layout.temp_dirs()) == 1
    monkeypatch.setattr(featurize_module, "run_audio_task", real)
    result = featurize(url, FeaturizeOptions())
    assert result.counts["resumed_units"] == 1  # the first track (tracks run first)
    assert layout.temp_dirs() == []
    local = dancedata.open_store(stores["local"], "v2")
    remote = dancedata.open_store(url)
    for name in local.array_names():
        assert np.array_equal(remote.zarr(name)[...], local.zarr(name)[...], equal_nan=True), name


def test_remote_versions_get_the_same_checksums_record_as_local_ones(stores):
    """Issue 15 item 1: one commit path, so checksums.json is written on S3 exactly as on disk;
    the arrays are byte-identical, so their recorded hashes are too, and a zeroed chunk is
    caught by the deep check."""
    from dancedata.store.integrity import check_record, load_record

    remote, local = StoreLayout(stores["url"]), StoreLayout(stores["local"])
    for version in ("v1", "v2", "v3"):
        mine, theirs = (
            load_record(remote.version_backend(version)),
            load_record(local.version_backend(version)),
        )
        assert mine is not None, version
        assert mine["algorithm"] == "sha256" and mine["record_version"] == 2
        assert set(mine["files"]) == set(theirs["files"]), version
        zarr_files = [rel for rel in theirs["files"] if rel.startswith("data.zarr/")]
        assert zarr_files
        for rel in zarr_files:
            assert mine["files"][rel] == theirs["files"][rel], (version, rel)
        assert check_record(remote.version_backend(version), deep=True) == []
    # a copy of v1 under another prefix, with one chunk zeroed (same size): caught only deep
    fs = s3fs.S3FileSystem()
    fs.invalidate_cache()
    source = f"{BUCKET}/stores/demo/versions/v1"
    copy = f"{BUCKET}/stores/zeroed/versions/v1"
    fs.copy(source, copy, recursive=True)
    chunk = next(
        r
        for r in sorted(load_record(local.version_backend("v1"))["files"])
        if r.startswith("data.zarr/motion/") and "/c/" in r
    )
    size = fs.size(f"{copy}/{chunk}")
    fs.pipe_file(f"{copy}/{chunk}", bytes(size))
    zeroed = StoreLayout(f"s3://{BUCKET}/stores/zeroed").version_backend("v1")
    assert check_record(zeroed, deep=False) == []
    problems = check_record(zeroed, deep=True)
    assert len(problems) == 1 and chunk in problems[0] and "sha256 differs" in problems[0]


def test_remote_children_reference_the_parents_unchanged_files(stores):
    """Issue 15 item 1: a remote version stores only what changed; every other file is named in
    references.json with the version that holds it, and reads, checksums and the deep check go
    through the references (data equality with the local store is checked above)."""
    from dancedata.store.integrity import check_record, load_record
    from dancedata.store.references import REFERENCES_FILE, parse_references

    fs = s3fs.S3FileSystem()
    fs.invalidate_cache()
    prefix = f"{BUCKET}/stores/demo/versions"
    assert not fs.exists(f"{prefix}/v1/{REFERENCES_FILE}")  # no parent: holds everything
    remote = StoreLayout(stores["url"])
    for version in ("v2", "v3"):
        refs = parse_references(fs.cat_file(f"{prefix}/{version}/{REFERENCES_FILE}"), version)
        record = load_record(remote.version_backend(version))["files"]
        stored = {p[len(f"{prefix}/{version}/") :] for p in fs.find(f"{prefix}/{version}")}
        assert refs and set(refs) <= set(record)
        assert not set(refs) & stored  # referenced files are not stored again
        assert set(record) == (stored - {REFERENCES_FILE, "manifest.json", "checksums.json"}) | set(
            refs
        )
        for rel, holder in refs.items():
            assert holder != version and fs.exists(f"{prefix}/{holder}/{rel}"), (rel, holder)
            assert (
                not fs.exists(f"{prefix}/{holder}/{REFERENCES_FILE}")
                or rel
                not in json.loads(fs.cat_file(f"{prefix}/{holder}/{REFERENCES_FILE}"))["files"]
            )  # a reference always names the version that holds the bytes
        assert check_record(remote.version_backend(version), deep=True) == []
    # segment changes only tables: v3 references every zarr file of v2 (or v1 through it)
    v3_refs = parse_references(fs.cat_file(f"{prefix}/v3/{REFERENCES_FILE}"), "v3")
    v2_record = load_record(remote.version_backend("v2"))["files"]
    chunks = [r for r in v2_record if r.startswith("data.zarr/") and "/c/" in r]
    assert chunks and all(r in v3_refs for r in chunks)


def test_an_object_written_at_a_referenced_path_is_reported(stores):
    """A file a version references (held by an older version) that appears in the version's own
    prefix after the commit is not read, but validate must say so."""
    from dancedata.store.integrity import check_record, load_record
    from dancedata.store.references import REFERENCES_FILE, parse_references

    fs = s3fs.S3FileSystem()
    fs.invalidate_cache()
    fs.copy(f"{BUCKET}/stores/demo", f"{BUCKET}/stores/shadowed", recursive=True)
    prefix = f"{BUCKET}/stores/shadowed/versions/v3"
    refs = parse_references(fs.cat_file(f"{prefix}/{REFERENCES_FILE}"), "v3")
    rel = next(r for r in sorted(refs) if "/c/" in r)
    fs.pipe_file(f"{prefix}/{rel}", b"\0" * 8)
    version = StoreLayout(f"s3://{BUCKET}/stores/shadowed").version_backend("v3")
    assert rel in load_record(version)["files"]
    problems = check_record(version, deep=False)
    assert len(problems) == 1 and rel in problems[0] and f"says {refs[rel]} holds it" in problems[0]


@pytest.fixture
def s3_requests(monkeypatch):
    """Counts the S3 requests this process sends, by operation (the real requests still go to
    the server: s3fs's one entry point to the client is wrapped, nothing is answered here)."""
    import collections

    import s3fs.core

    counts: collections.Counter = collections.Counter()
    real = s3fs.core.S3FileSystem._call_s3

    async def counted(self, method, *args, **kwargs):  # noqa: ANN001, ANN202
        counts[method] += 1
        return await real(self, method, *args, **kwargs)

    monkeypatch.setattr(s3fs.core.S3FileSystem, "_call_s3", counted)
    return counts


def test_reads_cost_one_request_each(stores, s3_requests):
    """store.json, a manifest and every chunk are one GET each: no size asked first (s3fs's
    HEAD), no existence check before a read that would fail anyway. Measured before: the
    pointer 5 requests, open_store 29, every array of the demo store 220 (HEAD + GET per
    chunk), ``info`` 235, ``validate`` 1253; after: 1, 10-13, 102, 120 and 707. open_store
    then sent two HEADs per manifest ("is it a file", then its ETag); one since: 8-12 requests
    for the 4 versions here, 12 when no manifest was parsed before in this process (its
    parsed-manifest cache is bounded, and earlier tests in a worker can empty it: 16 before)."""
    layout = StoreLayout(stores["url"])
    layout.read_pointer()
    assert dict(s3_requests) == {"get_object": 1}
    versions = layout.version_dirs()
    import dancedata.store.layout as layout_module

    layout_module._MANIFEST_CACHE.clear()  # the worst case: no manifest parsed before
    s3_requests.clear()
    remote = dancedata.open_store(stores["url"])
    assert s3_requests["head_object"] == len(versions), dict(s3_requests)
    assert sum(s3_requests.values()) <= 3 * len(versions) + 2, dict(s3_requests)
    assert sum(s3_requests.values()) <= 14, dict(s3_requests)
    s3_requests.clear()
    for name in remote.array_names():
        remote.zarr(name)[...]
    assert s3_requests["head_object"] <= 2, dict(s3_requests)
    s3_requests.clear()
    run_cli("info", stores["url"], "--json")
    # 120 with v1-v3, 142 once the test above has committed v4 (the old code: 235 with v1-v3)
    assert sum(s3_requests.values()) <= 150, dict(s3_requests)


def test_small_reads_are_bounded_and_exact(stores):
    """One ranged GET of limit + 1 bytes: an empty object (where S3 has no range to give), an
    object of exactly the limit, and one a byte over it (refused, its real size named)."""
    from dancedata.store.backend_fsspec import FsspecBackend
    from dancedata.store.untrusted import UnsafeFile

    fs = s3fs.S3FileSystem()
    backend = FsspecBackend(f"s3://{BUCKET}/small-reads")
    fs.pipe_file(f"{BUCKET}/small-reads/empty", b"")
    fs.pipe_file(f"{BUCKET}/small-reads/ten", b"0123456789")
    assert backend.read_small("empty", 4) == b"" and backend.read_bytes("empty") == b""
    assert backend.read_small("ten", 10) == b"0123456789"
    assert backend.read_bytes("ten") == b"0123456789"
    with pytest.raises(UnsafeFile, match="10 bytes, over the reader's limit of 9 bytes"):
        backend.read_small("ten", 9)
    with pytest.raises(FileNotFoundError):
        backend.read_small("missing", 10)
