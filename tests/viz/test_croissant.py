"""The Croissant record of a store version (issue 23 item 8): ``dancedata card`` and
``report --croissant``.

The record is validated by ``mlcroissant`` (MLCommons' reference implementation), and its
``sequences``, ``splits`` and ``arrays`` record sets are loaded through it from the version's
real parquet files and compared with the store read directly (pyarrow, zarr). The store is
the shared small featurized synthetic store (real pipeline, real Zarr and Parquet).
"""

from __future__ import annotations

import hashlib
import json
import shutil

import pytest

from tests.helpers import run_cli

# slow: mlcroissant reads the record sets of the session's featurized store
pytestmark = pytest.mark.slow

mlc = pytest.importorskip("mlcroissant")


def _published(store, tmp_path, *args: str):
    """The latest version folder copied as it would be published, with its record inside."""
    from dancedata.store.layout import StoreLayout

    version = StoreLayout(store).latest()
    folder = tmp_path / version
    shutil.copytree(store / "versions" / version, folder)
    out = folder / "croissant.json"
    proc = run_cli("card", str(store), "--out", str(out), *args)
    assert proc.stdout.strip() == f"card: wrote {out}"
    return version, folder, out


def test_card_validates_and_loads_through_mlcroissant(small_featurized_store, tmp_path) -> None:
    import pyarrow.parquet as pq

    from dancedata.store.reader import _VersionReader

    store = small_featurized_store
    version, folder, out = _published(
        store, tmp_path, "--license", "CC-BY-4.0", "--citation", "@misc{demo, title={Demo}}"
    )
    record = json.loads(out.read_text())
    dataset = mlc.Dataset(jsonld=str(out))  # raises on validation errors
    assert not dataset.metadata.ctx.issues.errors, dataset.metadata.ctx.issues.report()
    assert dataset.metadata.license == ["CC-BY-4.0"] or dataset.metadata.license == "CC-BY-4.0"
    assert record["citeAs"] == "@misc{demo, title={Demo}}"

    reader = _VersionReader(store)
    manifest = reader.manifest
    assert record["identifier"] == f"{version}:{manifest['fingerprint']}"
    assert manifest["dancedata_version"] in record["description"]
    assert record["version"] == f"{version[1:]}.0.0"

    files = {f["@id"]: f for f in record["distribution"]}
    for name in ("sequences.parquet", "splits.parquet", "checksums.json"):
        assert files[name]["sha256"] == hashlib.sha256((folder / name).read_bytes()).hexdigest()
    assert files["data-zarr"]["@type"] == "cr:FileSet"

    sequences = [
        {k.split("/", 1)[1]: v for k, v in row.items()} for row in dataset.records("sequences")
    ]
    expected = pq.read_table(folder / "sequences.parquet").to_pylist()
    assert len(sequences) == len(expected) > 0
    for got, want in zip(sequences, expected, strict=True):
        seq_id = got["seq_id"]
        assert (seq_id.decode() if isinstance(seq_id, bytes) else seq_id) == want["seq_id"]
        assert int(got["frame_start"]) == want["frame_start"]
        assert int(got["n_frames"]) == want["n_frames"]

    splits = list(dataset.records("splits"))
    assert len(splits) == pq.read_table(folder / "splits.parquet").num_rows
    arrays = {row["arrays/name"]: row for row in dataset.records("arrays")}
    names = reader.array_names()
    assert sorted(_text(n) for n in arrays) == sorted(names)
    rotmat = next(row for key, row in arrays.items() if _text(key) == "motion/rotmat")
    zarr_rotmat = reader.array("motion/rotmat")
    assert _text(rotmat["arrays/shape"]) == ",".join(map(str, zarr_rotmat.shape))
    assert _text(rotmat["arrays/dtype"]) == "float32"


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def test_card_refuses_a_table_that_does_not_match_its_checksum(
    small_featurized_store, tmp_path
) -> None:
    work = tmp_path / "store"
    shutil.copytree(small_featurized_store, work)
    from dancedata.store.layout import StoreLayout

    table = work / "versions" / StoreLayout(work).latest() / "splits.parquet"
    data = bytearray(table.read_bytes())
    data[len(data) // 2] ^= 0xFF
    table.write_bytes(bytes(data))
    proc = run_cli("card", str(work), "--json", check=False)
    assert proc.returncode == 1
    error = json.loads(proc.stdout)
    assert "splits.parquet does not match its sha256" in error["error"]
    assert error["file"].endswith("splits.parquet")


def test_report_links_its_croissant_record(small_featurized_store, tmp_path) -> None:
    pytest.importorskip("matplotlib")
    out = tmp_path / "card.html"
    run_cli("report", str(small_featurized_store), str(out), "--gallery", "0", "--croissant")
    record = tmp_path / "card.croissant.json"
    assert '<a href="card.croissant.json">Croissant JSON-LD</a>' in out.read_text()
    assert json.loads(record.read_text())["conformsTo"] == "http://mlcommons.org/croissant/1.0"


def test_card_refuses_to_write_into_a_version_folder(small_featurized_store, tmp_path) -> None:
    """A committed version holds only the files its checksums record: a record written into
    versions/vN/ made validate fail ('file not recorded at commit'), so card refuses it."""
    from dancedata.store.layout import StoreLayout

    work = tmp_path / "store"
    shutil.copytree(small_featurized_store, work)
    version = StoreLayout(work).latest()
    out = work / "versions" / version / "croissant.json"
    proc = run_cli("card", str(work), "--out", str(out), check=False)
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr.strip() == (
        f"error: {out}: the Croissant record would go inside the store's version folder "
        f"versions/{version}, which holds only the files recorded at its commit (validate would "
        f"report it); write it outside the store, e.g. next to a published copy of "
        f"versions/{version}/"
    )
    assert not out.exists()
    assert run_cli("validate", str(work)).returncode == 0
    beside = work / "card.json"  # the store's own folder, outside every version: allowed
    assert (
        run_cli("card", str(work), "--out", str(beside)).stdout.strip() == f"card: wrote {beside}"
    )
    assert run_cli("validate", str(work)).returncode == 0
