"""Hostile stores: metadata, arrays, links and special files, values.

Each case edits a copy of a small featurized store (v1 ingest, v2 featurize, v3 segment; the
files of v3 are hard links to v2's, so every edit replaces a file instead of writing into it)
and names the commands that must refuse it. Where an attacker would, the case also rewrites
``checksums.json`` of the edited version (:func:`reseal`): the record is self-digested, so a
planted value must be caught by the reader's own checks, not by a checksum mismatch.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
import time
from pathlib import Path

from tests.data.bad.hostile import Command, hostile_case

REPO = Path(__file__).resolve().parents[3]
DEMO_CONFIG = REPO / "experiments" / "demo.toml"
SEQ = "gBR_sBM_cAll_d01_mBR1_ch01"
LATEST = "v3"
# the small store's pose:test split holds one sequence (the demo config's crossmodal test + val
# are empty there)
EXPERIMENT_SPLIT = ["--set", "split.scheme=pose", "--set", 'split.eval=["test"]']
ROTMAT = "data.zarr/motion/rotmat"


# -- planting helpers --------------------------------------------------------------------------
def version(store: Path, name: str = LATEST) -> Path:
    return store / "versions" / name


def replace(path: Path, data: bytes) -> None:
    """Write ``path`` as a new file (never into a file that may be a hard link of another
    version's)."""
    tmp = path.with_name(path.name + ".plant")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def edit_json(path: Path, change) -> None:
    value = json.loads(path.read_text())
    change(value)
    replace(path, json.dumps(value, indent=2).encode())


def edit_array_meta(vdir: Path, array: str, change) -> None:
    """Apply ``change`` to an array's zarr.json and to its copy in the consolidated metadata of
    the root zarr.json (zarr reads the latter)."""
    edit_json(vdir / "data.zarr" / array / "zarr.json", change)

    def consolidated(root):
        node = root["consolidated_metadata"]["metadata"][array]
        change(node)

    edit_json(vdir / "data.zarr" / "zarr.json", consolidated)


def edit_group_attrs(vdir: Path, group: str, change) -> None:
    """Apply ``change`` to a group's attributes, in its zarr.json and the consolidated copy."""
    edit_json(vdir / "data.zarr" / group / "zarr.json", lambda m: change(m["attributes"]))
    edit_json(
        vdir / "data.zarr" / "zarr.json",
        lambda r: change(r["consolidated_metadata"]["metadata"][group]["attributes"]),
    )


def edit_table(vdir: Path, name: str, change) -> None:
    """Rewrite ``<name>.parquet`` with ``change(rows)`` applied, keeping its schema."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = vdir / f"{name}.parquet"
    table = pq.read_table(path)
    rows = table.to_pylist()
    change(rows)
    new = pa.Table.from_pylist(rows, schema=table.schema)
    tmp = path.with_name(path.name + ".plant")
    pq.write_table(new, tmp)
    os.replace(tmp, path)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def reseal(vdir: Path) -> None:
    """Rewrite ``checksums.json`` of ``vdir`` over its files as they are now, digest included:
    what an attacker editing a store does so that the cheap and deep checks pass."""
    from dancedata.store.checksums import canonical_json

    path = vdir / "checksums.json"
    record = json.loads(path.read_text())
    files = {}
    for dirpath, dirnames, filenames in os.walk(vdir):
        dirnames[:] = [d for d in dirnames if d != ".build"]
        for name in filenames:
            full = Path(dirpath) / name
            rel = full.relative_to(vdir).as_posix()
            if rel in ("manifest.json", "checksums.json") or not full.is_file():
                continue
            files[rel] = {"bytes": full.lstat().st_size, "sha256": _sha256(full)}
    record["files"] = files
    manifest = vdir / "manifest.json"
    record["manifest"] = {"bytes": manifest.stat().st_size, "sha256": _sha256(manifest)}
    body = {k: v for k, v in record.items() if k != "digest"}
    record["digest"] = hashlib.sha256(canonical_json(body).encode()).hexdigest()
    replace(path, json.dumps(record, indent=2).encode())


def nested(depth: int) -> bytes:
    return b"[" * depth + b"]" * depth


# -- the commands ------------------------------------------------------------------------------
def readers(
    work: Path,
    store: Path,
    expect: str = "",
    *,
    write: bool = True,
    skip: tuple[str, ...] = (),
    passes: tuple[str, ...] = (),
    expects: dict[str, str] | None = None,
) -> list[Command]:
    """Every command that reads a store, each expected to refuse it (exit 1), except those
    in ``skip`` (left out: they never read the hostile file) and ``passes`` (exit 0: they pass
    over it, e.g. a damaged version with a one-line warning, or never decode the chunk).
    ``expects`` gives a command its own message pattern (still exit 1). The writing commands
    run segment, featurize, then checkout: a checkout that succeeds moves latest to v2, and
    segment and featurize would then never meet what was planted in v3."""
    out = work / "out"
    out.mkdir(exist_ok=True)
    s = str(store)
    commands = [
        Command(["validate", s], expect=expect, json=True),
        Command(["info", s], expect=expect, json=True),
        Command(["report", s, str(out / "card.html")], expect=expect, output=out),
        Command(["render", s, SEQ, str(out / "seq.mp4")], expect=expect, output=out),
        Command(["plot", s, SEQ, str(out / "seq.png")], expect=expect, output=out),
        Command(["export", "bvh", s, SEQ, str(out / "seq.bvh")], expect=expect, output=out),
        Command(
            ["evaluate", s, "--generated", s, "--split", "train", "--out", str(out / "ev")],
            expect=expect,
            json=True,
            output=out,
        ),
        Command(
            [
                "experiment",
                "run",
                str(DEMO_CONFIG),
                "--store",
                s,
                "-q",
                "-o",
                str(out / "ex"),
                *EXPERIMENT_SPLIT,
            ],
            expect=expect,
            json=True,
            output=out,
        ),
    ]
    if write:
        commands += [
            Command(["segment", s, "-q", "--beats-per-measure", "3"], expect=expect, json=True),
            Command(["featurize", s, "-q"], expect=expect, json=True),
            Command(["checkout", s, "v2"], expect=expect, json=True),
        ]
    kept = []
    for command in commands:
        name = " ".join(command.argv[:2]) if command.argv[0] == "export" else command.argv[0]
        if name in skip:
            continue
        if name in passes:
            command = Command(command.argv, expect_exit=0, json=command.json, output=command.output)
        elif expects and name in expects:
            command = Command(
                command.argv, expect=expects[name], json=command.json, output=command.output
            )
        kept.append(command)
    return kept


def validate_only(store: Path, expect: str = "", deep: bool = False) -> list[Command]:
    argv = ["validate", str(store)] + (["--deep"] if deep else [])
    return [Command(argv, expect=expect, json=True)]


# -- store metadata ----------------------------------------------------------------------------
@hostile_case("store-metadata", note="store.json nested 100,000 deep")
def nested_store_json(work: Path, store: Path) -> list[Command]:
    replace(store / "store.json", nested(100_000))
    return readers(work, store, "store.json")


@hostile_case("store-metadata", note="manifest.json of the latest version nested 100,000 deep")
def nested_manifest_json(work: Path, store: Path) -> list[Command]:
    replace(version(store) / "manifest.json", nested(100_000))
    # a version with an unusable manifest is damaged: validate reports it; readers pass over it
    # with a one-line warning naming the file and read v2
    return readers(
        work,
        store,
        "manifest",
        write=False,
        passes=("info", "report", "render", "plot", "export bvh", "evaluate"),
        # experiment passes over v3 too, then refuses v2 (featurized, not segmented: no measures)
        expects={"experiment": "manifest|measures table"},
    )


@hostile_case("store-metadata", note="checksums.json nested 100,000 deep")
def nested_checksums_json(work: Path, store: Path) -> list[Command]:
    replace(version(store) / "checksums.json", nested(100_000))
    return validate_only(store, "checksums.json") + validate_only(store, "checksums.json", True)


@hostile_case("store-metadata", note="an array's zarr.json nested 100,000 deep")
def nested_zarr_json(work: Path, store: Path) -> list[Command]:
    replace(version(store) / ROTMAT / "zarr.json", nested(100_000))
    replace(version(store) / "data.zarr" / "zarr.json", nested(100_000))
    # checkout v2 never reads v3's metadata (segment and featurize, run first, refuse it)
    return readers(work, store, "zarr.json", passes=("checkout",))


@hostile_case("store-metadata", note="a 2 GB sparse store.json")
def sparse_store_json(work: Path, store: Path) -> list[Command]:
    path = store / "store.json"
    text = path.read_bytes()
    with path.open("r+b") as handle:
        handle.truncate(2 << 30)
        handle.seek(0)
        handle.write(text)
    return readers(work, store, "store.json")


@hostile_case("store-metadata", note="manifest counts of the wrong type")
def manifest_counts_wrong_type(work: Path, store: Path) -> list[Command]:
    def change(m):
        m["counts"]["splits"] = "x"
        m["counts"]["sequences"] = [[[2]]]
        m["counts"]["measures"] = {"a": {"b": 1}}

    for name in ("v1", "v2", "v3"):
        edit_json(version(store, name) / "manifest.json", change)
    return readers(work, store, "manifest")


@hostile_case("store-metadata", note="manifest counts nested where numbers go (v1 only)")
def manifest_splits_nested(work: Path, store: Path) -> list[Command]:
    def change(m):
        m["counts"]["splits"] = {"schemes": {"crossmodal": {"train": "x"}}, "ignore_list": []}

    edit_json(version(store, "v1") / "manifest.json", change)
    (work / "out").mkdir(exist_ok=True)
    return [
        Command(["info", str(store), "--version", "v1"], expect="manifest", json=True),
        Command(
            ["report", str(store), str(work / "out" / "c.html"), "--version", "v1"],
            expect="manifest",
            output=work / "out",
        ),
        Command(["validate", str(store)], expect="manifest", json=True),
    ]


@hostile_case("store-metadata", note="store.json latest naming a path out of the store")
def latest_traversal(work: Path, store: Path) -> list[Command]:
    edit_json(store / "store.json", lambda p: p.update(latest="v1/../../.."))
    return validate_only(store, "latest")


@hostile_case("store-metadata", note="a manifest number of 5,000 digits")
def manifest_huge_number(work: Path, store: Path) -> list[Command]:
    path = version(store) / "manifest.json"
    text = path.read_text().replace('"measures": 8', '"measures": ' + "9" * 5000)
    replace(path, text.encode())
    return readers(
        work,
        store,
        "manifest",
        write=False,
        passes=("info", "report", "render", "plot", "export bvh", "evaluate"),
        # experiment passes over v3 too, then refuses v2 (featurized, not segmented: no measures)
        expects={"experiment": "manifest|measures table"},
    )


@hostile_case("store-metadata", note="references.json naming a file outside the store")
def references_outside(work: Path, store: Path) -> list[Command]:
    record = {
        "format": "dancedata-references",
        "format_version": 1,
        "files": {"sequences.parquet": "../../../../etc"},
    }
    replace(version(store) / "references.json", json.dumps(record).encode())
    # a local store shares files by hard link, never through references.json: readers ignore
    # it (validate reports it as a file not recorded at commit); the object-store reader
    # refuses it (tests/store/test_store_untrusted.py)
    return validate_only(store, "references.json")


@hostile_case("store-metadata", note="references.json nested 100,000 deep")
def nested_references_json(work: Path, store: Path) -> list[Command]:
    replace(version(store) / "references.json", nested(100_000))
    return validate_only(store, "references.json")


@hostile_case("store-metadata", note="motion group attributes that are not an object")
def group_attrs_wrong_type(work: Path, store: Path) -> list[Command]:
    edit_group_attrs(version(store), "motion", lambda a: a.update(skeleton="smpl", fps="60"))
    reseal(version(store))
    # checkout v2 never reads v3's attributes (segment and featurize, run first, refuse them)
    return readers(work, store, "fps|skeleton", passes=("checkout",))


# -- arrays ------------------------------------------------------------------------------------
def _chunks(count: int):
    def change(meta):
        meta["shape"] = [count, 24, 3, 3]
        meta["chunk_grid"]["configuration"]["chunk_shape"] = [1, 24, 3, 3]

    return change


@hostile_case("arrays", note="zarr.json declaring 3e6 chunks", timeout_s=60)
def zarr_3e6_chunks(work: Path, store: Path) -> list[Command]:
    edit_array_meta(version(store), "motion/rotmat", _chunks(3_000_000))
    reseal(version(store))
    return readers(work, store, "chunks", write=False)


@hostile_case("arrays", note="zarr.json declaring 1e15 chunks")
def zarr_1e15_chunks(work: Path, store: Path) -> list[Command]:
    edit_array_meta(version(store), "motion/rotmat", _chunks(10**15))
    reseal(version(store))
    # refused from the shape already: 1e15 frames is over the 2**40 bound of one dimension
    return readers(work, store, "chunks|shape", write=False)


@hostile_case("arrays", note="zarr.json with a zero and a negative chunk shape")
def zarr_bad_chunk_shape(work: Path, store: Path) -> list[Command]:
    def change(meta):
        meta["chunk_grid"]["configuration"]["chunk_shape"] = [0, -24, 3, 3]

    edit_array_meta(version(store), "motion/rotmat", change)
    reseal(version(store))
    return readers(work, store, "chunk", write=False)


@hostile_case("arrays", note="zarr.json shape of 1e12 elements in one chunk")
def zarr_huge_chunk(work: Path, store: Path) -> list[Command]:
    def change(meta):
        meta["shape"] = [10**12 // 216, 24, 3, 3]
        meta["chunk_grid"]["configuration"]["chunk_shape"] = [10**12 // 216, 24, 3, 3]

    edit_array_meta(version(store), "motion/rotmat", change)
    reseal(version(store))
    return readers(work, store, "chunk|shape", write=False)


@hostile_case("arrays", note="zarr.json with a shape of the wrong rank / type")
def zarr_shape_wrong_type(work: Path, store: Path) -> list[Command]:
    edit_array_meta(version(store), "motion/rotmat", lambda m: m.update(shape="1164"))
    reseal(version(store))
    return readers(work, store, "shape", write=False)


@hostile_case("arrays", note="an unknown codec")
def unknown_codec(work: Path, store: Path) -> list[Command]:
    def change(meta):
        meta["codecs"][1] = {"name": "evil", "configuration": {}}

    edit_array_meta(version(store), "motion/rotmat", change)
    reseal(version(store))
    return readers(work, store, "codec", write=False)


@hostile_case("arrays", note="an unknown data type")
def unknown_dtype(work: Path, store: Path) -> list[Command]:
    edit_array_meta(version(store), "motion/rotmat", lambda m: m.update(data_type="evil128"))
    reseal(version(store))
    return readers(work, store, "data type|dtype", write=False)


def zstd_rle_bomb(content: int, byte: int = 0) -> bytes:
    """One zstd frame of ``content`` bytes of ``byte``, made of RLE blocks (4 bytes each per
    128 KiB): a few kB that decode to ``content`` bytes."""
    block = 128 * 1024
    out = bytearray(struct.pack("<I", 0xFD2FB528))
    out.append(0xE0)  # frame content size in 8 bytes, single segment
    out += struct.pack("<Q", content)
    left = content
    while left > 0:
        size = min(block, left)
        left -= size
        header = (1 if left == 0 else 0) | (1 << 1) | (size << 3)  # last flag, RLE, size
        out += struct.pack("<I", header)[:3] + bytes([byte])
    return bytes(out)


def with_crc32c(data: bytes) -> bytes:
    import google_crc32c

    return data + struct.pack("<I", google_crc32c.value(data))


@hostile_case("arrays", note="a zstd chunk of 25 kB that decodes to 800 MB, crc32c matching")
def zstd_bomb(work: Path, store: Path) -> list[Command]:
    # Every motion array but the keypoints declared zstd (a store may use any standard codec;
    # dancedata writes blosc), its first chunk the bomb: whichever one a command reads.
    for meta in (version(store) / "data.zarr" / "motion").glob("*/zarr.json"):
        if meta.parent.name.startswith(("keypoints", "det_scores")):
            continue

        def to_zstd(m: dict) -> None:
            m["codecs"][1] = {"name": "zstd", "configuration": {"level": 0, "checksum": False}}

        edit_array_meta(version(store), f"motion/{meta.parent.name}", to_zstd)
        for chunk in (meta.parent / "c").rglob("*"):
            if chunk.is_file():
                replace(chunk, with_crc32c(zstd_rle_bomb(800 * 1024 * 1024)))
                break
    reseal(version(store))
    # info reads metadata and tables only, render draws the (blosc) keypoints: nothing to
    # refuse there
    return readers(work, store, "chunk", write=False, passes=("info", "render")) + validate_only(
        store, "chunk", True
    )


@hostile_case("arrays", note="a zstd frame in place of a blosc chunk, crc32c matching")
def blosc_chunk_not_blosc(work: Path, store: Path) -> list[Command]:
    meta = version(store) / "data.zarr" / "motion" / "keypoints3d" / "zarr.json"
    chunk = next(p for p in (meta.parent / "c").rglob("*") if p.is_file())
    replace(chunk, with_crc32c(zstd_rle_bomb(1000)))
    reseal(version(store))
    # render and report (its gallery) draw keypoints3d (refused); info, plot, export bvh
    # (euler/axis_angle, trans), evaluate and experiment (rotations) never decode it
    return readers(
        work,
        store,
        "blosc",
        write=False,
        passes=("info", "plot", "export bvh", "evaluate", "experiment"),
    )


@hostile_case("arrays", note="a chunk that is a FIFO", timeout_s=60)
def chunk_fifo(work: Path, store: Path) -> list[Command]:
    chunk = version(store) / ROTMAT / "c" / "0" / "0" / "0" / "0"
    chunk.unlink()
    os.mkfifo(chunk)
    return readers(work, store, "FIFO|regular|special", write=False) + validate_only(
        store, "FIFO|regular|special", True
    )


@hostile_case("arrays", note="a 2 GB sparse sequences.parquet")
def sparse_table(work: Path, store: Path) -> list[Command]:
    path = version(store) / "sequences.parquet"
    data = path.read_bytes()
    path.unlink()
    with path.open("wb") as handle:
        handle.truncate(2 << 30)
        handle.seek((2 << 30) - len(data))
        handle.write(data)
    return readers(work, store, "over the reader's limit", write=False)


# -- links and special files -------------------------------------------------------------------
@hostile_case("links", note="versions/v3 a symbolic link to a folder outside the store")
def version_symlink(work: Path, store: Path) -> list[Command]:
    import shutil

    outside = work / "elsewhere-v3"
    shutil.copytree(version(store), outside)
    shutil.rmtree(version(store))
    version(store).symlink_to(outside, target_is_directory=True)
    return readers(work, store, "symbolic link")


@hostile_case("links", note="sequences.parquet a symbolic link to a file outside the store")
def table_symlink(work: Path, store: Path) -> list[Command]:
    outside = work / "elsewhere.parquet"
    path = version(store) / "sequences.parquet"
    outside.write_bytes(path.read_bytes())
    path.unlink()
    path.symlink_to(outside)
    # checkout v2 never opens v3's tables (segment and featurize, run first, refuse the link)
    return readers(work, store, "symbolic link", passes=("checkout",))


@hostile_case("links", note="a chunk a symbolic link (to a file outside the store)")
def chunk_symlink(work: Path, store: Path) -> list[Command]:
    chunk = version(store) / ROTMAT / "c" / "0" / "0" / "0" / "0"
    outside = work / "elsewhere-chunk"
    outside.write_bytes(chunk.read_bytes())
    chunk.unlink()
    chunk.symlink_to(outside)
    return readers(work, store, "symbolic link", write=False)


@hostile_case("links", note="store.json a symbolic link to /dev/zero")
def store_json_dev_zero(work: Path, store: Path) -> list[Command]:
    (store / "store.json").unlink()
    (store / "store.json").symlink_to("/dev/zero")
    # under --json the file is a field of its own; the error text says what it is
    return readers(work, store, "store.json|symbolic link")


@hostile_case("links", note=".lock a symbolic link to /dev/zero")
def lock_dev_zero(work: Path, store: Path) -> list[Command]:
    (store / ".lock").symlink_to("/dev/zero")
    s = str(store)
    return [
        # validate checks the store; a lock it cannot read is a note naming it (exit 0)
        Command(["validate", s], expect_exit=0, json=True),
        Command(["segment", s, "-q"], expect="lock file", json=True),
        Command(["checkout", s, "v2"], expect="lock file", json=True),
        Command(["unlock", s], expect="lock file"),
    ]


@hostile_case("links", note=".lock a FIFO")
def lock_fifo(work: Path, store: Path) -> list[Command]:
    os.mkfifo(store / ".lock")
    # a minute old: a young unreadable lock file is waited on for 5 s as one a writer may still
    # be filling (that wait: tests/store/test_lock.py); here the refusal itself is the case
    old = time.time() - 60
    os.utime(store / ".lock", (old, old))
    s = str(store)
    return [
        Command(["validate", s], expect_exit=0, json=True),
        Command(["segment", s, "-q"], expect="lock file", json=True),
    ]


@hostile_case("links", note="versions/v4 a FIFO")
def version_fifo(work: Path, store: Path) -> list[Command]:
    os.mkfifo(version(store, "v4"))
    return readers(work, store, "not a version folder")


@hostile_case("links", note="a planted symbolic link in the build area of a resumable featurize")
def build_area_symlink(work: Path, store: Path) -> list[Command]:
    """The build area an interrupted featurize leaves (``versions/.tmp-<fingerprint>``, arrays
    prepared), whose data.zarr/audio is a link to a folder outside the store: the resumed
    featurize must refuse it before writing anything there."""
    import shutil

    fingerprint = json.loads((version(store, "v2") / "manifest.json").read_text())["fingerprint"]
    tmp = store / "versions" / f".tmp-{fingerprint[:16]}"
    shutil.copytree(version(store, "v2"), tmp)
    (tmp / "manifest.json").unlink()
    (tmp / "checksums.json").unlink()
    outside = work / "elsewhere-audio"
    shutil.move(tmp / "data.zarr" / "audio", outside)
    (tmp / "data.zarr" / "audio").symlink_to(outside, target_is_directory=True)
    (tmp / ".build").mkdir()
    (tmp / ".build" / "prepared.json").write_text("{}")
    shutil.rmtree(version(store, "v3"))
    shutil.rmtree(version(store, "v2"))
    edit_json(store / "store.json", lambda p: p.update(latest="v1"))
    s = str(store)
    return [
        Command(["featurize", s, "-q", "--stems", "offline"], expect="symbolic link", json=False)
    ]


@hostile_case("links", note="the music table naming a FIFO as a track", timeout_s=60)
def music_fifo(work: Path, store: Path) -> list[Command]:
    fifo = work / "music.fifo"
    os.mkfifo(fifo)
    edit_table(version(store, "v1"), "music", lambda rows: rows[0].update(path=str(fifo)))
    return [
        Command(
            ["featurize", str(store), "-q", "--version", "v1", "--no-cache"],
            expect="regular|FIFO",
            json=True,
        )
    ]


@hostile_case("links", note="the music table naming /dev/zero as a track", timeout_s=60)
def music_dev_zero(work: Path, store: Path) -> list[Command]:
    edit_table(version(store, "v1"), "music", lambda rows: rows[0].update(path="/dev/zero"))
    return [
        Command(
            ["featurize", str(store), "-q", "--version", "v1", "--no-cache"],
            expect="regular|device",
            json=True,
        )
    ]


# -- values ------------------------------------------------------------------------------------
def _fps(value: float):
    def case(work: Path, store: Path) -> list[Command]:
        for name in ("v1", "v2", "v3"):
            edit_table(version(store, name), "sequences", lambda rows: rows[0].update(fps=value))
            reseal(version(store, name))
        return readers(work, store, "fps", write=False)

    return case


for _name, _value in (
    ("fps_zero", 0.0),
    ("fps_nan", float("nan")),
    ("fps_huge", 1e300),
    ("fps_negative", -60.0),
):
    _fps_case = _fps(_value)
    _fps_case.__name__ = _name
    hostile_case("values", note=f"sequences fps = {_value}")(_fps_case)


@hostile_case("values", note="motion fps attribute 0")
def motion_attr_fps_zero(work: Path, store: Path) -> list[Command]:
    edit_group_attrs(version(store), "motion", lambda a: a.update(fps=0.0))
    reseal(version(store))
    return readers(work, store, "fps", write=False)


@hostile_case("values", note="a skeleton whose parents form a cycle")
def skeleton_cycle(work: Path, store: Path) -> list[Command]:
    def change(attrs):
        parents = attrs["skeleton"]["parents"]
        parents[0], parents[1] = 1, 0  # pelvis <-> left_hip, no root

    edit_group_attrs(version(store), "motion", change)
    reseal(version(store))
    return readers(work, store, "skeleton", write=False)


@hostile_case("values", note="a skeleton with two roots and a parent out of range")
def skeleton_two_roots(work: Path, store: Path) -> list[Command]:
    def change(attrs):
        parents = attrs["skeleton"]["parents"]
        parents[3] = -1
        parents[4] = 99

    edit_group_attrs(version(store), "motion", change)
    reseal(version(store))
    return readers(work, store, "skeleton", write=False)


@hostile_case("values", note="a measures table with frame numbers of 1e17")
def measures_huge_frames(work: Path, store: Path) -> list[Command]:
    def change(rows):
        rows[0]["frame_stop"] = 10**17
        rows[1]["frame_start"] = -(10**17)

    edit_table(version(store), "measures", change)
    reseal(version(store))
    return readers(work, store, "measures", write=False, skip=("export bvh",))


@hostile_case("values", note="a BPM of 1e300 in the sequences table")
def bpm_huge(work: Path, store: Path) -> list[Command]:
    for name in ("v1", "v2", "v3"):
        edit_table(version(store, name), "sequences", lambda rows: rows[0].update(bpm=1e300))
        reseal(version(store, name))
    s = str(store)
    return readers(work, store, "bpm", write=False) + [
        Command(["segment", s, "-q", "--beats-per-measure", "3"], expect="bpm", json=True)
    ]


@hostile_case("values", note="a BPM of 1e300 in the measures table")
def measures_bpm_huge(work: Path, store: Path) -> list[Command]:
    edit_table(version(store), "measures", lambda rows: rows[0].update(bpm=1e300))
    reseal(version(store))
    return readers(work, store, "bpm", write=False, skip=("export bvh",))


@hostile_case("values", note="n_frames of 1e15 in the sequences table")
def n_frames_huge(work: Path, store: Path) -> list[Command]:
    for name in ("v1", "v2", "v3"):
        edit_table(
            version(store, name),
            "sequences",
            lambda rows: rows[0].update(n_frames=10**15, frame_stop=10**15),
        )
        reseal(version(store, name))
    return readers(work, store, "n_frames|frame", write=False)


def rle_bomb_parquet(path: Path, rows: int = 300_000_000) -> None:
    """A Parquet file of ``rows`` rows of zeros in a few MB (run-length encoded): decoding it
    whole would allocate gigabytes. Written in row groups of 10 million (bounded memory)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    block = pa.table({"n_frames": pa.array(np.zeros(10_000_000, np.int64))})
    with pq.ParquetWriter(path, block.schema) as writer:
        for _ in range(rows // 10_000_000):
            writer.write_table(block)


@hostile_case("arrays", note="a 2 MB sequences.parquet declaring 300 million rows")
def parquet_row_bomb(work: Path, store: Path) -> list[Command]:
    path = version(store) / "sequences.parquet"
    tmp = path.with_name("bomb.plant")
    rle_bomb_parquet(tmp)
    os.replace(tmp, path)
    reseal(version(store))
    return readers(work, store, "rows", write=False)


# -- an attacker's review of the readers (cases beyond the list) -----------------------
def many_values(count: int) -> bytes:
    """A JSON object holding one list of ``count`` empty lists: 3 bytes of text a value, 50-100
    bytes each once parsed (30 MB of it took 1.5 GB and 90 s before the value limit)."""
    return b'{"x": [' + b"[]," * (count - 1) + b"[]]}"


@hostile_case("store-metadata", note="checksums.json of 120 MB of empty lists (40 million values)")
def checksums_many_values(work: Path, store: Path) -> list[Command]:
    replace(version(store) / "checksums.json", many_values(40_000_000))
    return validate_only(store, "values") + validate_only(store, "values", True)


@hostile_case("store-metadata", note="manifest.json of 30 MB of empty lists (10 million values)")
def manifest_many_values(work: Path, store: Path) -> list[Command]:
    replace(version(store) / "manifest.json", many_values(10_000_000))
    # as a nested manifest: validate reports the damaged version, readers pass over it to v2
    return readers(
        work,
        store,
        "manifest",
        write=False,
        passes=("info", "report", "render", "plot", "export bvh", "evaluate"),
        expects={"experiment": "manifest|measures table"},
    )


@hostile_case("store-metadata", note="the root zarr.json of 30 MB of empty lists")
def zarr_json_many_values(work: Path, store: Path) -> list[Command]:
    replace(version(store) / "data.zarr" / "zarr.json", many_values(10_000_000))
    return readers(work, store, "zarr.json", write=False)


@hostile_case("store-metadata", note="checksums.json listing ../../etc/passwd and /dev/zero")
def checksums_outside(work: Path, store: Path) -> list[Command]:
    from dancedata.store.checksums import canonical_json

    path = version(store) / "checksums.json"
    record = json.loads(path.read_text())
    record["files"]["../../../../../etc/passwd"] = {"bytes": 1, "sha256": "0" * 64}
    record["files"]["/dev/zero"] = {"bytes": 1, "sha256": "0" * 64}
    body = {k: v for k, v in record.items() if k != "digest"}
    record["digest"] = hashlib.sha256(canonical_json(body).encode()).hexdigest()
    replace(path, json.dumps(record).encode())
    # only files found inside the version are opened: the two names are reported missing
    return validate_only(store, "missing") + validate_only(store, "missing", True)


def retype_column(vdir: Path, name: str, column: str, convert) -> None:
    """Rewrite ``<name>.parquet`` with ``column`` replaced by ``convert(values)`` (its type
    following the new values)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = vdir / f"{name}.parquet"
    table = pq.read_table(path)
    index = table.column_names.index(column)
    table = table.set_column(index, column, pa.array(convert(table.column(column).to_pylist())))
    tmp = path.with_name(path.name + ".plant")
    pq.write_table(table, tmp)
    os.replace(tmp, path)


@hostile_case("values", note="the sequences fps column of strings ('60.0')")
def fps_column_strings(work: Path, store: Path) -> list[Command]:
    for name in ("v1", "v2", "v3"):
        retype_column(version(store, name), "sequences", "fps", lambda v: [str(x) for x in v])
        reseal(version(store, name))
    return readers(work, store, "fps", write=False)


@hostile_case("values", note="the sequences seq_id column of integers")
def seq_id_column_ints(work: Path, store: Path) -> list[Command]:
    for name in ("v1", "v2", "v3"):
        retype_column(version(store, name), "sequences", "seq_id", lambda v: list(range(len(v))))
        reseal(version(store, name))
    return readers(work, store, "seq_id", write=False)


@hostile_case("values", note="the measures frame_start column of strings")
def measures_column_strings(work: Path, store: Path) -> list[Command]:
    retype_column(version(store), "measures", "frame_start", lambda v: [str(x) for x in v])
    reseal(version(store))
    return readers(work, store, "frame_start", write=False, skip=("export bvh",))
