"""Hostile names, experiment configs, generated motion, paths and pose files (untrusted-input
corpus, classes ``names``, ``configs``, ``generated``, ``paths``, ``pose-files``).

Each ``plant(work, store)`` writes its hostile thing into the copy of the small featurized store
at ``store`` (re-signing ``checksums.json`` so only the planted value is wrong) or into files
under ``work``, and returns the commands that must refuse it (or, for names, draw it literally).
The store's first sequence is in the crossmodal ``train`` split, so ``evaluate --split train``
scores it alone.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from tests.data.bad.hostile import Command, hostile_case

# -- helpers -----------------------------------------------------------------------------------


def latest(store: Path) -> Path:
    """The store's latest version folder."""
    name = json.loads((store / "store.json").read_text())["latest"]
    return store / "versions" / name


def resign(version: Path) -> None:
    """Re-hash every file of ``version`` listed in its ``checksums.json`` and its digest, so the
    planted change is the only thing wrong with the version (an attacker would do the same)."""
    from dancedata.store.checksums import sha256_file
    from dancedata.store.integrity import _record_digest

    path = version / "checksums.json"
    record = json.loads(path.read_text())
    for rel, entry in record["files"].items():
        file = version / rel
        if file.is_file():
            entry["bytes"] = file.stat().st_size
            entry["sha256"] = sha256_file(file)
    record["digest"] = _record_digest(record)
    path.write_text(json.dumps(record, indent=2))


def edit_tables(store: Path, edit: Any, tables: tuple[str, ...] | None = None) -> None:
    """Rewrite the latest version's parquet tables row by row with ``edit(table, row)``, keep
    their schemas, and re-sign the version."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    version = latest(store)
    for file in sorted(version.glob("*.parquet")):
        if tables is not None and file.stem not in tables:
            continue
        table = pq.read_table(file)
        rows = [edit(file.stem, dict(row)) for row in table.to_pylist()]
        os.unlink(file)  # never through a hard link shared with another version
        pq.write_table(pa.Table.from_pylist(rows, schema=table.schema), file)
    resign(version)


def drop_latest(store: Path) -> None:
    """Remove the latest version (the store then ends at its parent, e.g. before ``segment``)."""
    import shutil

    meta = json.loads((store / "store.json").read_text())
    number = int(meta["latest"].lstrip("v"))
    shutil.rmtree(store / "versions" / meta["latest"])
    meta["latest"] = f"v{number - 1}"
    (store / "store.json").write_text(json.dumps(meta, indent=2))


def seq_ids(store: Path) -> list[str]:
    import pyarrow.parquet as pq

    return pq.read_table(latest(store) / "sequences.parquet", columns=["seq_id"])[
        "seq_id"
    ].to_pylist()


def rename_sequence(store: Path, old: str, new: str) -> None:
    def edit(_table: str, row: dict) -> dict:
        if row.get("seq_id") == old:
            row["seq_id"] = new
        return row

    edit_tables(store, edit)


def good_euler75(n_frames: int, seed: int = 0) -> np.ndarray:
    """(F, 75) plausible thesis Euler rows: root near 0.9 m up, small joint angles."""
    rng = np.random.default_rng(seed)
    rows = rng.normal(0.0, 0.1, (n_frames, 75))
    rows[:, 1] += 0.9
    return rows


def n_frames(store: Path, seq: str) -> int:
    import pyarrow.parquet as pq

    rows = pq.read_table(latest(store) / "sequences.parquet").to_pylist()
    return int(next(r["n_frames"] for r in rows if r["seq_id"] == seq))


def out_folder(work: Path) -> Path:
    """An existing, empty output folder under ``work``."""
    out = work / "out"
    out.mkdir(exist_ok=True)
    return out


def results_folder(work: Path) -> Path:
    """Where ``experiment run`` writes without ``--out``: ``results/`` of the command's working
    folder (the runner's ``cwd``, beside ``work``)."""
    return work.parent / "cwd" / "results"


def evaluate(store: Path, generated: Path, out: Path, **kw: Any) -> Command:
    return Command(
        ["evaluate", str(store), "--generated", str(generated), "--split", "train",
         "--out", str(out), "-q"],
        output=out, **kw,
    )  # fmt: skip


BVH_JOINT = "$\\foo$"


def tiny_bvh(joint: str = "Spine", frames: int = 30) -> str:
    """A 3-joint BVH (cm, 1 m tall) whose second joint is named ``joint``."""
    lines = [
        "HIERARCHY",
        "ROOT Hips",
        "{",
        "  OFFSET 0 0 0",
        "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
        f"  JOINT {joint}",
        "  {",
        "    OFFSET 0 40 0",
        "    CHANNELS 3 Zrotation Xrotation Yrotation",
        "    JOINT Head",
        "    {",
        "      OFFSET 0 40 0",
        "      CHANNELS 3 Zrotation Xrotation Yrotation",
        "      End Site",
        "      {",
        "        OFFSET 0 20 0",
        "      }",
        "    }",
        "  }",
        "}",
        "MOTION",
        f"Frames: {frames}",
        "Frame Time: 0.0333333",
    ]
    for f in range(frames):
        lines.append(" ".join(f"{v:.4f}" for v in [0, 90, f * 0.5, f % 7, 0, 0, 1, 2, 3, 4, 5, 6]))
    return "\n".join(lines) + "\n"


def openpose_frame(people: list[list[float]] | None = None) -> dict:
    """One BODY_25 OpenPose frame with one person (75 numbers)."""
    if people is None:
        people = [[float(100 + j) if j % 3 != 2 else 0.9 for j in range(75)]]
    return {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": p} for p in people]}


def openpose_folder(folder: Path, prefix: str, frames: int = 12) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(frames):
        (folder / f"{prefix}_{f:012d}_keypoints.json").write_text(json.dumps(openpose_frame()))
    return folder


def ingest_video(poses: Path, store: Path, *extra: str, **kw: Any) -> Command:
    return Command(
        ["ingest", "video", "--poses", str(poses), "--store", str(store), "--fps", "30",
         "--no-music", "--bpm", "120", "-q", *extra],
        output=store, **kw,
    )  # fmt: skip


# -- names -------------------------------------------------------------------------------------


@hostile_case("names", note="a genre that is matplotlib mathtext: drawn literally")
def genre_mathtext(work: Path, store: Path) -> list[Command]:
    edit_tables(store, lambda _t, row: {**row, "genre": "$\\foo$"} if "genre" in row else row,
                ("sequences",))  # fmt: skip
    seq = seq_ids(store)[0]
    out = out_folder(work)
    return [
        Command(["plot", str(store), seq, str(out / "plot.png")], expect_exit=0, output=out),
        Command(["report", str(store), str(out / "report.html")], expect_exit=0, output=out),
    ]


@hostile_case("names", note="a genre holding HTML: escaped in the report")
def genre_html(work: Path, store: Path) -> list[Command]:
    edit_tables(store, lambda _t, row: {**row, "genre": "<script>x</script>"}
                if "genre" in row else row, ("sequences",))  # fmt: skip
    out = out_folder(work)
    return [Command(["report", str(store), str(out / "report.html")], expect_exit=0, output=out)]


@hostile_case("names", note="a BVH joint name that is mathtext: drawn literally in plot")
def bvh_joint_mathtext(work: Path, store: Path) -> list[Command]:
    raw = work / "bvh"
    raw.mkdir()
    (raw / "take01.bvh").write_text(tiny_bvh(BVH_JOINT))
    bvh_store = work / "bvhstore"
    out = out_folder(work)
    return [
        Command(
            [
                "ingest",
                "bvh",
                str(raw / "take01.bvh"),
                "--store",
                str(bvh_store),
                "--units",
                "cm",
                "-q",
            ],
            expect_exit=0,
            output=bvh_store,
        ),  # fmt: skip
        Command(
            ["plot", str(bvh_store), "take01", str(out / "plot.png")], expect_exit=0, output=out
        ),  # fmt: skip
    ]


@hostile_case("names", note="a seq_id with ../: refused by validate and on read")
def seq_id_dotdot(work: Path, store: Path) -> list[Command]:
    first = seq_ids(store)[0]
    rename_sequence(store, first, "../outside")
    gen = work / "gen"
    gen.mkdir()
    np.save(work / "outside.npy", good_euler75(2000))  # what a path-built lookup would read
    out = work / "out"
    return [
        Command(["validate", str(store)], expect=r"seq_id", json=True),
        evaluate(store, gen, out, expect=r"seq_id"),
    ]


@hostile_case("names", note="a seq_id with glob characters: refused; files matched exactly")
def seq_id_glob(work: Path, store: Path) -> list[Command]:
    first = seq_ids(store)[0]
    rename_sequence(store, first, "take[12]")
    gen = work / "gen"
    gen.mkdir()
    np.save(gen / "x_take1.npy", good_euler75(2000))  # glob '*_take[12].npy' matches this
    out = work / "out"
    return [
        Command(["validate", str(store)], expect=r"seq_id"),
        evaluate(store, gen, out, expect=r"seq_id", json=True),
        # info counts sequences and builds nothing from their ids: it may show the store
        Command(["info", str(store)], expect_exit=0),
    ]


@hostile_case("names", note="generated files are matched by exact name, never by glob")
def generated_glob_name(work: Path, store: Path) -> list[Command]:
    first = seq_ids(store)[0]
    gen = work / "gen"
    gen.mkdir()
    # A file whose name is a glob pattern matching the sequence is not the sequence's file.
    np.save(gen / f"[a-z]_{first[:-1]}?.npy", good_euler75(n_frames(store, first)))
    out = work / "out"
    return [evaluate(store, gen, out, expect=r"no generated file")]


# -- configs -----------------------------------------------------------------------------------


def _config(work: Path, text: str, name: str = "hostile.toml") -> Path:
    path = work / name
    path.write_text(text)
    return path


def experiment(config: Path, store: Path, *extra: str, **kw: Any) -> Command:
    """``experiment run``; without ``--out`` its results may go to ``results/`` only."""
    kw.setdefault("output", results_folder(config.parent))
    return Command(["experiment", "run", str(config), "--store", str(store), "-q", *extra], **kw)


BASE = 'rows = ["even+linear_slerp"]\nn_keyframes = [3]\n[split]\neval = ["train"]\n'


@hostile_case("configs", note="id an absolute path: results would go there")
def id_absolute(work: Path, store: Path) -> list[Command]:
    target = work / "elsewhere"
    cfg = _config(work, f'id = "{target}"\n' + BASE)
    return [experiment(cfg, store, expect=r"\bid\b", json=True)]


@hostile_case("configs", note="id climbing out of results/")
def id_dotdot(work: Path, store: Path) -> list[Command]:
    cfg = _config(work, 'id = "../../x"\n' + BASE)
    return [experiment(cfg, store, expect=r"\bid\b")]


@hostile_case("configs", note='mse_wrap = "false" is a string, not a bool')
def mse_wrap_string(work: Path, store: Path) -> list[Command]:
    cfg = _config(work, 'id = "w"\n' + BASE + '[metrics]\nmse_wrap = "false"\n')
    return [experiment(cfg, store, expect=r"mse_wrap", json=True)]


@hostile_case("configs", note="a string where an integer goes")
def guard_string(work: Path, store: Path) -> list[Command]:
    cfg = _config(work, 'id = "g"\n' + BASE + '[keyframes]\nG = "six"\n')
    return [experiment(cfg, store, expect=r"keyframes\.G")]


@hostile_case("configs", note="n_keyframes out of range (would allocate per keyframe)")
def n_keyframes_huge(work: Path, store: Path) -> list[Command]:
    cfg = _config(work, 'id = "n"\n' + BASE.replace("[3]", "[3, 1000000000]"))
    return [experiment(cfg, store, expect=r"n_keyframes")]


@hostile_case("configs", note="a float out of range")
def frame_time_range(work: Path, store: Path) -> list[Command]:
    cfg = _config(work, 'id = "f"\n' + BASE + "[metrics]\ngeometric_frame_time = -1e300\n")
    return [experiment(cfg, store, expect=r"geometric_frame_time")]


@hostile_case("configs", note="a deeply nested array value")
def deep_array(work: Path, store: Path) -> list[Command]:
    depth = 50_000
    cfg = _config(work, 'id = "d"\n' + BASE + "[keyframes]\nG = " + "[\n" * depth + "]\n" * depth)
    return [experiment(cfg, store, expect=r"nested too deeply", json=True)]


@hostile_case("configs", note="a deeply nested table")
def deep_table(work: Path, store: Path) -> list[Command]:
    long = _config(work, 'id = "d"\n' + BASE + f"[{'.'.join(['t'] * 50_000)}]\nx = 1\n")
    deep = _config(work, 'id = "d"\n' + BASE + f"[{'.'.join(['t'] * 4_000)}]\nx = 1\n", "b.toml")
    return [
        experiment(long, store, expect=r"a line of \d+ characters"),
        experiment(deep, store, expect=r"nested deeper than"),
    ]


@hostile_case("configs", note="a deeply nested inline table")
def deep_inline_table(work: Path, store: Path) -> list[Command]:
    depth = 20_000
    cfg = _config(work, 'id = "d"\n' + BASE + "x = " + "{a = " * depth + "1" + "}" * depth)
    return [experiment(cfg, store, expect=r"a line of \d+ characters")]


@hostile_case("configs", note="a 60 MB config")
def huge_config(work: Path, store: Path) -> list[Command]:
    path = work / "huge.toml"
    with path.open("w") as fh:
        fh.write('id = "h"\n' + BASE + "# " + "x" * 1000 + "\n")
        fh.truncate(60 << 20)
    return [experiment(path, store, expect=r"bytes|large")]


@hostile_case("configs", note="[generated] value not a string; --set of a bad type")
def generated_table_types(work: Path, store: Path) -> list[Command]:
    cfg = _config(work, 'id = "t"\n' + BASE + '[generated]\n"even+transformer_x@3" = [1, 2]\n')
    cfg2 = _config(work, 'id = "t"\n' + BASE, "two.toml")
    return [
        experiment(cfg, store, expect=r"generated"),
        experiment(cfg2, store, "--set", "metrics.normalize=3", expect=r"metrics\.normalize"),
    ]


# -- generated motion --------------------------------------------------------------------------


def _gen_folder(work: Path, store: Path) -> tuple[Path, str]:
    gen = work / "gen"
    gen.mkdir()
    return gen, seq_ids(store)[0]


def _sparse_npy(path: Path, shape: tuple[int, ...], dtype: str = "<f8") -> None:
    """A .npy whose header declares ``shape`` and whose data is a hole (sparse file)."""
    with path.open("wb") as fh:
        np.lib.format.write_array_header_1_0(
            fh, {"descr": dtype, "fortran_order": False, "shape": shape}
        )
        fh.truncate(fh.tell() + int(np.prod(shape)) * np.dtype(dtype).itemsize)


@hostile_case("generated", note="a 12 kB sparse .npy declaring 1.08 GB")
def sparse_npy(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    _sparse_npy(gen / f"{seq}.npy", (1_800_000, 75))
    out = work / "out"
    cfg = _config(work, 'id = "s"\n' + BASE.replace("even+linear_slerp", "even+transformer_m"))
    return [
        evaluate(store, gen, out, expect=r"frames", json=True),
        experiment(
            cfg,
            store,
            "--generated",
            f"even+transformer_m={gen}",
            "--out",
            str(work / "xout"),
            expect=r"frames",
            output=work / "xout",
        ),  # fmt: skip
    ]


@hostile_case("generated", note="a sparse .npy of FACT rows declaring 1.08 GB")
def sparse_npy_fact(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    _sparse_npy(gen / f"{seq}.npy", (600_000, 225))
    return [evaluate(store, gen, work / "out", expect=r"frames")]


@hostile_case("generated", note="a small .npz holding 1.2 GB of zeros in two members")
def npz_bomb(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    n = 1_000_000
    with zipfile.ZipFile(gen / f"{seq}.npz", "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for name, cols in (("smpl_poses", 72), ("smpl_trans", 3)):
            with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array_header_1_0(
                    member, {"descr": "<f8", "fortran_order": False, "shape": (n, cols)}
                )
                block = bytes(8 * cols * 10_000)
                for _ in range(n // 10_000):
                    member.write(block)
    return [evaluate(store, gen, work / "out", expect=r"frames", json=True)]


@hostile_case("generated", note="an .npz with 100,000 members: a short error")
def npz_many_members(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    tiny = work / "tiny.npy"
    np.save(tiny, np.zeros(1))
    data = tiny.read_bytes()
    with zipfile.ZipFile(gen / f"{seq}.npz", "w", zipfile.ZIP_STORED) as zf:
        for k in range(100_000):
            zf.writestr(f"m{k}.npy", data)
    return [evaluate(store, gen, work / "out", expect=r"members", json=True)]


@hostile_case("generated", note="Bailando's np.save of a dict (a pickled object array)")
def bailando_pickled_npy(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    positions = np.random.default_rng(0).normal(0, 0.3, (n_frames(store, seq), 72))
    np.save(gen / f"{seq}.npy", {"pred_position": positions}, allow_pickle=True)
    # Read through the restricted unpickler: its positions are scored (exit 0).
    return [evaluate(store, gen, work / "out", expect=r"positions", expect_exit=0)]


@hostile_case("generated", note="a pickled object .npy that is not Bailando's: refused")
def object_npy_exploit(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    marker = work / "pwned"

    class Boom:
        def __reduce__(self):  # noqa: ANN204 - the pickle's payload
            return (os.system, (f"touch {marker}",))

    array = np.empty((), dtype=object)
    array[()] = {"pred_position": Boom()}
    np.save(gen / f"{seq}.npy", array, allow_pickle=True)
    return [evaluate(store, gen, work / "out", expect=r"pickle|refused")]


@hostile_case("generated", note="far more frames than the ground truth (dense, small dtype)")
def too_many_frames(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    np.save(gen / f"{seq}.npy", np.zeros((200_000, 24, 3), dtype=np.float16))  # positions
    return [evaluate(store, gen, work / "out", expect=r"frames")]


def ingest_generated(gen: Path, like: Path, out: Path, **kw: Any) -> Command:
    """``ingest generated`` of ``gen`` into a new store ``out`` (its output folder)."""
    argv = ["ingest", "generated", str(gen), "--store", str(out), "--like", str(like), "-q"]
    return Command(argv, output=out, **kw)


@hostile_case("generated", note="ingest generated: a sparse .npy declaring 10.8 GB")
def ingest_sparse_npy(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    _sparse_npy(gen / f"{seq}.npy", (6_000_000, 225))
    small = work / "gen-small"
    small.mkdir()
    with (small / f"{seq}.npy").open("wb") as fh:  # the same claim in a 4 kB file
        np.lib.format.write_array_header_1_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (6_000_000, 225)}
        )
        fh.write(bytes(4096))
    return [
        ingest_generated(gen, store, work / "gstore", expect=r"at most \d+ frames", json=True),
        ingest_generated(small, store, work / "gstore", expect=r"frames declared", json=True),
    ]


@hostile_case("generated", note="ingest generated: a file name that is no sequence id")
def ingest_traversal_name(work: Path, store: Path) -> list[Command]:
    gen, _ = _gen_folder(work, store)
    np.save(gen / "..%2f..%2fetc.npy", np.zeros((10, 225)))
    return [ingest_generated(gen, store, work / "gstore", expect=r"not a plain name", json=True)]


@hostile_case("generated", note="ingest generated: a file of the wrong shape, a foreign id")
def ingest_wrong_shape(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    np.save(gen / f"{seq}.npy", np.zeros((n_frames(store, seq), 7)))
    other = work / "gen2"
    other.mkdir()
    np.save(other / "gZZ_not_in_store.npy", np.zeros((10, 225)))
    return [
        ingest_generated(gen, store, work / "gstore", expect=r"unknown generated-motion layout"),
        ingest_generated(other, store, work / "gstore", expect=r"no sequence 'gZZ_not_in_store'"),
    ]


@hostile_case("generated", note="ingest generated: a symbolic link to a file outside")
def ingest_symlink(work: Path, store: Path) -> list[Command]:
    gen, seq = _gen_folder(work, store)
    os.symlink("/etc/hostname", gen / f"{seq}.npy")
    return [ingest_generated(gen, store, work / "gstore", expect=r"not a regular file")]


# -- paths and processes -----------------------------------------------------------------------


@hostile_case("paths", note="a path component over 255 bytes")
def long_component(work: Path, store: Path) -> list[Command]:
    long = work / ("a" * 300) / "store"
    gen = work / "gen"
    gen.mkdir()
    return [
        Command(["info", str(long)], expect=r"too long|File name"),
        Command(["validate", str(long)], expect=r"too long|File name", json=True),
        Command(
            [
                "evaluate",
                str(store),
                "--generated",
                str(work / ("g" * 300)),
                "--split",
                "train",
                "--out",
                str(work / "out"),
            ],
            expect=r"too long|File name",
            output=work / "out",
        ),  # fmt: skip
        Command(
            ["plot", str(store), seq_ids(store)[0], str(work / ("p" * 300) / "x.png")],
            expect=r"too long|File name",
        ),  # fmt: skip
    ]


@hostile_case("paths", note="a BVH file name that is not UTF-8")
def non_utf8_bvh_name(work: Path, store: Path) -> list[Command]:
    raw = work / "bvh"
    raw.mkdir()
    bad = os.fsencode(raw) + b"/take\xff\xfe.bvh"
    with open(bad, "w") as fh:
        fh.write(tiny_bvh())
    bvh_store = work / "bvhstore"
    return [
        Command(
            ["ingest", "bvh", os.fsdecode(bad), "--store", str(bvh_store), "--units", "cm", "-q"],
            expect=r"UTF-8|name",
            output=bvh_store,
        ),  # fmt: skip
        Command(
            ["ingest", "bvh", str(raw), "--store", str(bvh_store), "--units", "cm", "-q"],
            expect=r"UTF-8|name",
            output=bvh_store,
            json=True,
        ),  # fmt: skip
    ]


@hostile_case("paths", note="a 5 MB joint CSV with 100,000 joints", timeout_s=60)
def joints_csv_wide(work: Path, store: Path) -> list[Command]:
    csv = work / "clip.csv"
    header = ",".join(f"j{k}_{a}" for k in range(100_000) for a in "xyz")
    csv.write_text(header + "\n" + ",".join(["0"] * 300_000) + "\n")
    out = work / "vstore"
    return [
        Command(
            [
                "ingest",
                "video",
                "--joints-csv",
                str(csv),
                "--store",
                str(out),
                "--fps",
                "30",
                "--no-music",
                "--bpm",
                "120",
                "-q",
            ],
            expect=r"joints",
            output=out,
        ),  # fmt: skip
    ]


@hostile_case("paths", note="segment with no positive BPM: its JSON error, then exit 1 (never 134)")
def segment_no_bpm(work: Path, store: Path) -> list[Command]:
    drop_latest(store)  # back to the featurized version, not yet segmented
    edit_tables(store, lambda _t, row: {**row, "bpm": 0.0} if "bpm" in row else row,
                ("sequences", "music"))  # fmt: skip
    cmd = Command(["segment", str(store), "-q"], expect=r"BPM|bpm|tempo", json=True)
    return [cmd, cmd, cmd]


# -- pose files --------------------------------------------------------------------------------


@hostile_case("pose-files", note="OpenPose JSON nested 100,000 deep; --on-error skip skips it")
def openpose_deep(work: Path, store: Path) -> list[Command]:
    poses = openpose_folder(work / "poses", "clip")
    depth = 100_000
    (poses / "clip_000000000003_keypoints.json").write_text("[" * depth + "]" * depth)
    out = work / "vstore"
    return [
        ingest_video(poses, out, expect=r"nest|deep"),
        ingest_video(poses, out, "--on-error", "skip", expect_exit=0, json=True),
    ]


@hostile_case("pose-files", note="OpenPose JSON with a 5,000-digit number")
def openpose_long_number(work: Path, store: Path) -> list[Command]:
    poses = openpose_folder(work / "poses", "clip")
    doc = json.dumps(openpose_frame()).replace("100.0", "1" * 5000, 1)
    (poses / "clip_000000000004_keypoints.json").write_text(doc)
    out = work / "vstore"
    return [
        ingest_video(poses, out, expect=r"digits|number", json=True),
        ingest_video(poses, out, "--on-error", "skip", expect_exit=0),
    ]


@hostile_case("pose-files", note="OpenPose JSON of 16 MiB of empty lists (5.6 million values)")
def openpose_many_values(work: Path, store: Path) -> list[Command]:
    poses = openpose_folder(work / "poses", "clip")
    count = (16 << 20) // 3 - 10  # just under the 16 MiB size limit; parsed it took 535 MB
    doc = b'{"people": [' + b"[]," * (count - 1) + b"[]]}"
    (poses / "clip_000000000003_keypoints.json").write_bytes(doc)
    out = work / "vstore"
    return [
        ingest_video(poses, out, expect=r"values", json=True),
        ingest_video(poses, out, "--on-error", "skip", expect_exit=0),
    ]


@hostile_case("pose-files", note="a frame index of 3e8 in an OpenPose file name")
def openpose_huge_index(work: Path, store: Path) -> list[Command]:
    poses = openpose_folder(work / "poses", "clip")
    (poses / "clip_000300000000_keypoints.json").write_text(json.dumps(openpose_frame()))
    out = work / "vstore"
    return [ingest_video(poses, out, expect=r"frame", json=True)]


@hostile_case("pose-files", note="a frame number of 3e8 in a joint CSV row")
def csv_huge_frame(work: Path, store: Path) -> list[Command]:
    csv = work / "clip.csv"
    names = ["Nose", "Neck", "RShoulder"]
    header = "frame," + ",".join(f"{n}_{a}" for n in names for a in "xyz")
    rows = [f"{f}," + ",".join(["0.1"] * 9) for f in (0, 1, 2, 300_000_000)]
    csv.write_text(header + "\n" + "\n".join(rows) + "\n")
    out = work / "vstore"
    return [
        Command(
            [
                "ingest",
                "video",
                "--joints-csv",
                str(csv),
                "--store",
                str(out),
                "--fps",
                "30",
                "--no-music",
                "--bpm",
                "120",
                "-q",
            ],
            expect=r"frame",
            output=out,
            json=True,
        ),  # fmt: skip
    ]
