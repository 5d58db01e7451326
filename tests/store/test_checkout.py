"""``dancedata checkout`` (issue 14, item 3): a user can make an older version the latest again,
the "nothing to do" message says how, every reader takes a version, and the next writer derives
from the checked-out version. On a real local store and on S3 (moto server on loopback)."""

from __future__ import annotations

import json
import shutil

import pytest

import dancedata
from dancedata.errors import StoreError
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.checkout import checkout, checkout_log
from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli
from tests.s3_server import moto_s3

# slow: a moto S3 server on loopback; a four-version store
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    path = tmp_path_factory.mktemp("checkout") / "raw"
    synth_aist(path, n_sequences=2, seed=0)
    return path


@pytest.fixture(scope="module")
def store(raw, tmp_path_factory):
    """v1 ingest, v2 featurize (motion only), v3 segment 4 beats, v4 segment 2 beats."""
    path = tmp_path_factory.mktemp("checkout") / "store"
    ingest_aist(path, raw, AistIngestOptions())
    featurize(path, FeaturizeOptions(audio=False))
    segment(path, SegmentOptions(beats_per_measure=4))
    segment(path, SegmentOptions(beats_per_measure=2))
    assert StoreLayout(path).latest() == "v4"
    return path


def _measures(path, version=None) -> int:
    return dancedata.open_store(path, version).measures.num_rows


def test_already_holds_names_the_latest_and_the_checkout_command(store):
    out = run_cli("segment", str(store), "-q").stdout.strip()
    assert out == (
        "segment: nothing to do, version v3 already holds this result; the latest version is v4; "
        f"run `dancedata checkout {store} v3` to make it the latest"
    )
    summary = json.loads(run_cli("segment", str(store), "-q", "--json").stdout)
    assert summary["version"] == "v3" and summary["created"] is False
    assert summary["latest"] == "v4" and "dancedata checkout" in summary["hint"]
    # the result that is the latest says nothing more
    out = run_cli("segment", str(store), "-q", "--beats-per-measure", "2").stdout.strip()
    assert out == "segment: nothing to do, version v4 already holds this result"


def test_rerun_step_under_a_latest_that_builds_on_it_suggests_no_checkout(store, raw):
    """Re-running the ingest of a store whose latest (v4: featurized and segmented) descends from
    v1 says so: following the old checkout hint made the un-featurized v1 the latest."""
    out = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q").stdout.strip()
    assert out == (
        "ingest aist: nothing to do, version v1 already holds this result; "
        "the latest version v4 builds on it"
    )
    assert "dancedata checkout" not in out and "to make it the latest" not in out
    summary = json.loads(
        run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", "--json").stdout
    )
    assert summary["version"] == "v1" and summary["latest"] == "v4"
    assert summary["latest_builds_on"] is True and "hint" not in summary
    assert StoreLayout(store).latest() == "v4"


def test_checkout_moves_latest_and_readers_follow(store, tmp_path):
    work = tmp_path / "store"
    shutil.copytree(store, work)
    four_beat, two_beat = _measures(work, "v3"), _measures(work, "v4")
    assert two_beat > four_beat > 0
    proc = run_cli("checkout", str(work), "3")  # "3" means v3
    assert proc.stdout.strip().startswith("checkout: latest is now v3 (was v4)")
    layout = StoreLayout(work)
    assert layout.latest() == "v3" and layout.committed_versions() == ["v1", "v2", "v3", "v4"]
    pointer = json.loads((work / "store.json").read_text())
    assert pointer["latest"] == "v3"
    [entry] = pointer["checkouts"]
    assert (entry["version"], entry["previous"], entry["newest"]) == ("v3", "v4", "v4")
    assert entry["at"].endswith("Z") and "@" in entry["by"]
    # every reader: default is now v3, and each takes an explicit version
    assert dancedata.open_store(work).version == "v3" and _measures(work) == four_beat
    assert _measures(work, "v4") == two_beat and _measures(work, "4") == two_beat
    from dancedata.read.torch_data import MeasureDataset

    train_v3 = MeasureDataset(work, split="train", audio=None)
    train_v4 = MeasureDataset(work, split="train", audio=None, version="v4")
    assert train_v3.source.version == "v3" and train_v4.source.version == "v4"
    assert len(train_v4) > len(train_v3) > 0
    info = json.loads(run_cli("info", str(work), "--json").stdout)
    assert info["version"] == "v3" and info["latest"] == "v3" and info["measures"] == four_beat
    assert info["checkouts"] == [entry]
    assert "checkout  " in run_cli("info", str(work)).stdout  # the log, human-readable
    info4 = json.loads(run_cli("info", str(work), "--version", "v4", "--json").stdout)
    assert info4["version"] == "v4" and info4["measures"] == two_beat
    versions = json.loads(run_cli("versions", str(work), "--json").stdout)
    assert [r["version"] for r in versions if r["latest"]] == ["v3"]
    assert validate_store(work) == []
    # now v4's configuration is the one found elsewhere
    out = run_cli("segment", str(work), "-q", "--beats-per-measure", "2").stdout
    assert "version v4 already holds this result; the latest version is v3" in out
    # the next writer derives from the checked-out version and takes the next free number
    featurize(work, FeaturizeOptions(audio=False, representations=["quat"]))
    assert layout.latest() == "v5"
    manifest = layout.read_manifest("v5")
    assert manifest["parent"] == "v3"
    assert dancedata.open_store(work).measures.num_rows == four_beat  # v3's measures carried
    # checking out again appends to the log; the current latest is a no-op
    assert checkout(work, "v5").changed is False
    checkout(work, "v4")
    assert [e["version"] for e in checkout_log(work)] == ["v3", "v4"]
    assert checkout_log(work)[-1]["newest"] == "v5" and layout.latest() == "v4"
    assert validate_store(work) == []


def test_a_version_committed_after_a_checkout_still_wins(store, tmp_path):
    """A writer that renamed v5 into place and died before rewriting store.json committed v5:
    the checkout (which saw v4 as newest) no longer holds."""
    work = tmp_path / "store"
    shutil.copytree(store, work)
    checkout(work, "v2")
    assert StoreLayout(work).latest() == "v2"
    shutil.copytree(work / "versions" / "v4", work / "versions" / "v5")
    assert StoreLayout(work).latest() == "v5"


def test_checkout_refuses_what_is_not_a_committed_version(store, tmp_path):
    work = tmp_path / "store"
    shutil.copytree(store, work)
    before = (work / "store.json").read_bytes()
    for bad, words in (("v9", "no committed version 'v9'"), ("latest", "not a version name")):
        proc = run_cli("checkout", str(work), bad, check=False)
        assert proc.returncode == 1 and words in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1
    (work / "versions" / "v2" / "manifest.json").write_text("{")
    with pytest.raises(StoreError, match="version v2 is damaged"):
        checkout(work, "v2")
    assert (work / "store.json").read_bytes() == before


def test_checkout_waits_for_no_one_unless_asked(store, tmp_path):
    from dancedata.store.writer import hold_store_lock

    work = tmp_path / "store"
    shutil.copytree(store, work)
    with hold_store_lock(work):
        proc = run_cli("checkout", str(work), "v1", check=False)
    assert proc.returncode == 1 and "lock" in proc.stderr
    assert StoreLayout(work).latest() == "v4"


# -- object storage ----------------------------------------------------------------------------
BUCKET = "checkout"


@pytest.fixture(scope="module")
def s3_url(raw):
    """A moto S3 server on loopback with v1 ingest, v2 segment 4, v3 segment 2."""
    url = f"s3://{BUCKET}/store"
    with moto_s3(BUCKET):
        ingest_aist(url, raw, AistIngestOptions())
        segment(url, SegmentOptions(beats_per_measure=4))
        segment(url, SegmentOptions(beats_per_measure=2))
        yield url


def test_checkout_on_s3(s3_url):
    layout = StoreLayout(s3_url)
    four_beat = _measures(s3_url, "v2")
    assert layout.latest() == "v3" and _measures(s3_url) > four_beat
    out = run_cli("segment", s3_url, "-q").stdout
    assert f"the latest version is v3; run `dancedata checkout {s3_url} v2`" in out
    run_cli("checkout", s3_url, "v2")
    # v3 stays committed (store.json's log remembers it) while latest names v2
    assert layout.committed_versions() == ["v1", "v2", "v3"] and layout.latest() == "v2"
    assert dancedata.open_store(s3_url).version == "v2" and _measures(s3_url) == four_beat
    assert _measures(s3_url, "v3") > four_beat
    assert [e["version"] for e in checkout_log(s3_url)] == ["v2"]
    # the next writer: parent v2, next free number v4, and the log survives its commit
    result = segment(s3_url, SegmentOptions(beats_per_measure=3))
    assert result.version == "v4" and layout.read_manifest("v4")["parent"] == "v2"
    assert layout.latest() == "v4" and layout.committed_versions()[-1] == "v4"
    assert [e["version"] for e in checkout_log(s3_url)] == ["v2"]
    assert validate_store(s3_url) == []


def test_a_failed_first_ingest_leaves_no_store_on_s3(s3_url, raw, tmp_path):
    """Issue 14, item 7, on object storage: no store.json is left at the new prefix."""
    import s3fs

    bad = tmp_path / "raw-bad"
    shutil.copytree(raw, bad)
    sorted((bad / "motions").glob("*.pkl"))[0].write_bytes(b"garbage")
    url = f"s3://{BUCKET}/fresh"
    proc = run_cli("ingest", "aist", str(bad), "--store", url, "-q", check=False)
    assert proc.returncode == 1 and "unreadable pickle" in proc.stderr
    fs = s3fs.S3FileSystem()
    fs.invalidate_cache()
    assert not fs.exists(f"{BUCKET}/fresh/store.json") and not fs.find(f"{BUCKET}/fresh")
    # the store the fixture made is untouched by the same failure
    proc = run_cli("ingest", "aist", str(bad), "--store", s3_url, "-q", check=False)
    assert proc.returncode == 1 and StoreLayout(s3_url).latest() is not None
