"""A damaged store does not wedge (issue 11, item 6).

A ``versions/vN`` folder without its manifest, or with a manifest that is not a usable one (a
JSON list, ``skipped=[1]``), used to make every later writer fail at commit with a traceback
(the next name collided with the folder) and ``validate`` itself crash. Now ``validate`` reports
the damaged version (exit 1, one line per problem, no traceback), and writers pass over it with
a one-line warning: they number the next version past it and never choose it as a parent.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from dancedata.errors import StoreError
from dancedata.store.layout import StoreLayout, manifest_problem, parse_manifest
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    """v1 ingest, v2 segment."""
    root = tmp_path_factory.mktemp("damaged")
    synth_aist(root / "raw", n_sequences=2, seed=9)
    store = root / "store"
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(store), "-q")
    run_cli("segment", str(store), "-q")
    return store


@pytest.fixture
def store(pristine: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "store"
    shutil.copytree(pristine, copy)
    return copy


def _edit_manifest(store: Path, version: str, change) -> None:
    path = store / "versions" / version / "manifest.json"
    path.write_text(json.dumps(change(json.loads(path.read_text()))))


def _no_traceback(proc) -> None:
    assert "Traceback" not in proc.stderr, proc.stderr


@pytest.mark.slow
def test_writer_goes_past_a_version_folder_without_manifest(store):
    (store / "versions" / "v3" / "data.zarr").mkdir(parents=True)  # v3 with no manifest
    proc = run_cli("segment", str(store), "--beats-per-measure", "3", "-q")
    _no_traceback(proc)
    assert "wrote version v4" in proc.stdout
    warnings = [line for line in proc.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "versions/v3" in warnings[0] and "manifest" in warnings[0]
    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1", "v2", "v4"]
    assert layout.read_manifest("v4")["parent"] == "v2"  # never the damaged folder
    assert layout.latest() == "v4"


@pytest.mark.slow
def test_validate_reports_a_version_folder_without_manifest(store):
    shutil.copytree(store / "versions" / "v2", store / "versions" / "v3")
    (store / "versions" / "v3" / "manifest.json").unlink()
    proc = run_cli("validate", str(store), check=False)
    _no_traceback(proc)
    assert proc.returncode == 1
    assert "v3" in proc.stdout + proc.stderr and "manifest" in proc.stdout + proc.stderr


@pytest.mark.slow
def test_manifest_that_is_a_list_is_reported_and_skipped(store):
    (store / "versions" / "v2" / "manifest.json").write_text("[1, 2]\n")
    proc = run_cli("validate", str(store), check=False)
    _no_traceback(proc)
    assert proc.returncode == 1
    assert "v2" in proc.stdout + proc.stderr and "list" in proc.stdout + proc.stderr
    # readers and writers fall back to the newest intact version and go on
    info = run_cli("info", str(store), "--json")
    _no_traceback(info)
    seg = run_cli("segment", str(store), "-q")
    _no_traceback(seg)
    assert "wrote version v3" in seg.stdout
    assert StoreLayout(store).read_manifest("v3")["parent"] == "v1"
    # naming the damaged version explicitly is one clear line
    explicit = run_cli("info", str(store), "--version", "v2", check=False)
    _no_traceback(explicit)
    assert explicit.returncode == 1
    assert explicit.stderr.strip().count("\n") == 0
    assert "v2 is damaged" in explicit.stderr and "list" in explicit.stderr


@pytest.mark.slow
def test_manifest_with_non_object_skipped_entries_is_reported(store):
    _edit_manifest(store, "v2", lambda m: {**m, "skipped": [1]})
    proc = run_cli("validate", str(store), check=False)
    _no_traceback(proc)
    assert proc.returncode == 1
    assert "skipped" in proc.stdout + proc.stderr and "v2" in proc.stdout + proc.stderr


@pytest.mark.slow
def test_ingest_numbers_its_version_past_a_damaged_folder(store, tmp_path):
    _edit_manifest(store, "v2", lambda m: {**m, "stages": {"ingest": 7}})
    (store / "versions" / "v5").mkdir()  # an empty stray folder, further on
    synth_aist(tmp_path / "raw2", n_sequences=2, seed=10)
    proc = run_cli("ingest", "aist", str(tmp_path / "raw2"), "--store", str(store), "-q")
    _no_traceback(proc)
    assert "wrote version v6" in proc.stdout
    assert StoreLayout(store).committed_versions() == ["v1", "v6"]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("[]", "JSON list, not an object"),
        ("null", "JSON NoneType"),
        ('{"version": "v1"}', "no 'fingerprint'"),
        ('{"fingerprint": "ab", "skipped": [1]}', "'skipped' entry must be an object"),
        ('{"fingerprint": "ab", "inputs": {"a": 1}}', "'inputs' must be a list"),
        ('{"fingerprint": "ab", "parent": 3}', "'parent' must be a string or null"),
        ('{"fingerprint": "ab", "stages": {"ingest": 1}}', "'stages' must map"),
        ('{"fingerprint": 5}', "'fingerprint' must be a string"),
        ("{not json", "unreadable manifest"),
        (b"\xff\xfe", "unreadable manifest"),
    ],
)
def test_parse_manifest_refuses_what_code_cannot_use(text, expected):
    with pytest.raises(StoreError, match="where") as info:
        parse_manifest(text, "where")
    assert expected in str(info.value)


@pytest.mark.slow
def test_a_written_manifest_passes_the_check(pristine):
    layout = StoreLayout(pristine)
    for name in layout.committed_versions():
        manifest = json.loads((pristine / "versions" / name / "manifest.json").read_text())
        assert manifest_problem(manifest) is None
