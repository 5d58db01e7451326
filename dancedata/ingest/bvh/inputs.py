"""Which BVH files to ingest, and the music, tempo, genre and split that go with each.

Sources, later ones overriding earlier ones per file:

* command line: ``PATH...`` with ``--bpm B`` and ``--genre G`` for every file, ``--music F``
  for a single file. A PATH that is a folder stands for every file below it (recursively) whose
  name matches ``--glob`` (default ``*.bvh``), in sorted path order;
* ``--manifest CSV``: a header row, then one row per BVH file. Columns: ``bvh`` (required; the
  file, relative to the CSV's folder unless absolute), ``music`` (audio file, same rule),
  ``bpm``, ``genre``, ``split`` (train / val / test, stored under the ``custom`` scheme). Empty
  cells mean "not given". With no PATH, every row is ingested; with PATHs, only those, each
  matched to its row by path (or, failing that, by file name).

Each file becomes one sequence named after its file stem; stems must be unique.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

from dancedata.errors import InputError

__all__ = [
    "DEFAULT_GLOB",
    "MANIFEST_COLUMNS",
    "MAX_MANIFEST_BYTES",
    "BvhInput",
    "expand_folders",
    "resolve_inputs",
]

MANIFEST_COLUMNS = ("bvh", "music", "bpm", "genre", "split")
MAX_MANIFEST_BYTES = 64 * 2**20
_SPLITS = ("train", "val", "test")
DEFAULT_GLOB = "*.bvh"


@dataclass(frozen=True)
class BvhInput:
    """One BVH file and what pairs with it."""

    path: Path
    music: Path | None = None
    bpm: float | None = None
    genre: str | None = None
    split: str | None = None

    @property
    def seq_id(self) -> str:
        return self.path.stem


def _bpm(text: str | float | None, where: str) -> float | None:
    if text is None or (isinstance(text, str) and not text.strip()):
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{where}: bpm must be a positive number, not {text!r}")
    return value


def _cell(row: dict[str, str | None], key: str) -> str | None:
    value = row.get(key)
    return value.strip() or None if isinstance(value, str) else None


def read_manifest(path: Path) -> list[BvhInput]:
    """Rows of a manifest CSV (see the module docstring); at most MAX_MANIFEST_BYTES, UTF-8."""
    try:
        size = path.stat().st_size
        if size > MAX_MANIFEST_BYTES:
            raise InputError(
                f"manifest is {size:,} bytes, more than the {MAX_MANIFEST_BYTES // 2**20} MiB "
                "a list of BVH files can need",
                path,
            )
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"cannot read manifest: {exc.strerror or exc}", path) from None
    except UnicodeDecodeError as exc:
        raise InputError(f"manifest is not UTF-8 text (byte {exc.start})", path) from None
    reader = csv.DictReader(text.splitlines())
    try:
        return _manifest_rows(reader, path)
    except csv.Error as exc:
        raise InputError(f"line {reader.line_num + 1}: not a CSV row: {exc}", path) from None


def _manifest_rows(reader: csv.DictReader, path: Path) -> list[BvhInput]:
    columns = [c.strip() for c in reader.fieldnames or []]
    if "bvh" not in columns:
        raise InputError(f"manifest needs a 'bvh' column; columns: {columns}", path)
    unknown = sorted(set(columns) - set(MANIFEST_COLUMNS))
    if unknown:
        raise InputError(f"unknown manifest columns {unknown}; known: {MANIFEST_COLUMNS}", path)
    rows = []
    base = path.parent
    for number, raw in enumerate(reader, start=2):
        row = {(k or "").strip(): v for k, v in raw.items()}
        bvh = _cell(row, "bvh")
        if bvh is None:
            if any(_cell(row, c) for c in MANIFEST_COLUMNS):
                raise InputError(f"line {number}: empty 'bvh' cell", path)
            continue
        music = _cell(row, "music")
        split = _cell(row, "split")
        if split is not None and split not in _SPLITS:
            raise InputError(f"line {number}: split {split!r} not in {_SPLITS}", path)
        rows.append(
            BvhInput(
                path=base / bvh,
                music=None if music is None else base / music,
                bpm=_bpm(_cell(row, "bpm"), f"{path}: line {number}"),
                genre=_cell(row, "genre"),
                split=split,
            )
        )
    if not rows:
        raise InputError("manifest lists no BVH file", path)
    return rows


def _match(path: Path, rows: list[BvhInput]) -> BvhInput | None:
    resolved = path.resolve()
    for row in rows:
        if row.path.resolve() == resolved:
            return row
    named = [row for row in rows if row.path.name == path.name]
    return named[0] if len(named) == 1 else None


def expand_folders(paths: list[Path], glob: str = DEFAULT_GLOB) -> list[Path]:
    """Each folder in ``paths`` replaced by the files below it (any depth) matching ``glob``,
    sorted by path; files stay as given, in order. A folder with no match is an error."""
    found: list[Path] = []
    for path in paths:
        if not path.is_dir():
            found.append(path)
            continue
        files = sorted(p for p in path.rglob(glob) if p.is_file())
        if not files:
            raise InputError(f"no file matching {glob!r} in this folder or below it", path)
        found.extend(files)
    return found


def resolve_inputs(
    paths: list[Path],
    *,
    music: Path | None = None,
    bpm: float | None = None,
    genre: str | None = None,
    manifest: Path | None = None,
    glob: str = DEFAULT_GLOB,
) -> list[BvhInput]:
    """The files to ingest with their pairing (see the module docstring)."""
    bpm = _bpm(bpm, "--bpm")
    paths = expand_folders(paths, glob)
    if music is not None and manifest is not None:
        raise InputError("--music pairs one file; with --manifest give music in the CSV")
    rows = read_manifest(manifest) if manifest is not None else []
    if not paths and not rows:
        raise InputError("no BVH file given (PATH... or --manifest CSV)")
    if music is not None and len(paths) != 1:
        raise InputError(
            f"--music pairs exactly one BVH file, {len(paths)} given; use --manifest CSV to "
            "pair several"
        )
    found: list[BvhInput] = []
    if paths:
        for path in paths:
            row = _match(path, rows) if rows else None
            found.append(
                BvhInput(
                    path=path,
                    music=music if row is None else row.music,
                    bpm=bpm if row is None or row.bpm is None else row.bpm,
                    genre=genre if row is None or row.genre is None else row.genre,
                    split=None if row is None else row.split,
                )
            )
    else:
        found = [
            BvhInput(
                r.path,
                r.music,
                bpm if r.bpm is None else r.bpm,
                genre if r.genre is None else r.genre,
                r.split,
            )
            for r in rows
        ]
    seen: dict[str, Path] = {}
    for item in found:
        if item.seq_id in seen:
            raise InputError(
                f"two inputs give sequence {item.seq_id!r} ({seen[item.seq_id]} and "
                f"{item.path}); sequence ids are file stems and must be unique"
            )
        seen[item.seq_id] = item.path
    return found
