"""The array part of ``schemas/store.schema.json``, generated from the declared arrays.

``arrays`` (checked by ``validate``) and ``extension_arrays`` (not yet checked) are made from
the arrays ingest writes (:data:`dancedata.featurize.source_arrays.SOURCE_ARRAYS`) and every
registered family's ``outputs`` (:mod:`dancedata.featurize.family`), so an array is declared
once, in the code that writes it. The rest of the schema file is left as it is::

    python -m dancedata.featurize.schema_arrays          # rewrite the two sections
    python -m dancedata.featurize.schema_arrays --check  # exit 1 when the file differs

An array declared twice (``positions`` by ingest and by the ``positions`` family) must be
declared alike; the first declaration (ingest's, then the motion and the audio families in
registration order) is kept.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.featurize.family import INDEX_OF_GROUP, ArraySpec, registered
from dancedata.featurize.source_arrays import SOURCE_ARRAYS

__all__ = ["SCHEMA_PATH", "array_sections", "generated_schema_text", "main"]

SCHEMA_PATH = Path(__file__).resolve().parents[2] / "schemas" / "store.schema.json"
EXTENSION_COMMENT = (
    "Arrays some sources add (docs/STORE.md). Not yet checked by validate: pose2d holds NaN "
    "where a joint is missing, which the NaN check of `arrays` would refuse. Mask codes: 0 "
    "missing, 1 detected, 2 gap-filled."
)


def _entry(group: str, spec: ArraySpec, owner: tuple[str, str] | None) -> dict[str, Any]:
    """The schema entry of a declared array; ``owner`` (``family``/``source``, name) is named
    on extension arrays."""
    entry: dict[str, Any] = {
        "dtype": np.dtype(spec.dtype).name,
        "row_shape": list(spec.row_shape),
        "index": INDEX_OF_GROUP[group],
    }
    if spec.required_attrs:
        entry["attrs"] = list(spec.required_attrs)
    if spec.nan_allowed:
        entry["nan_allowed"] = True
    if spec.extension and owner is not None:
        entry[owner[0]] = owner[1]
    if spec.note:
        entry["$comment"] = spec.note
    return entry


def _declared() -> list[tuple[str, ArraySpec, tuple[str, str] | None]]:
    out: list[tuple[str, ArraySpec, tuple[str, str] | None]] = []
    for source, specs in SOURCE_ARRAYS.items():
        out += [("motion", spec, ("source", source) if source else None) for spec in specs]
    for group in INDEX_OF_GROUP:  # motion, then audio
        for name, family in registered(group).items():
            out += [(group, spec, ("family", name)) for spec in family.outputs]
    return out


def array_sections() -> tuple[dict[str, Any], dict[str, Any]]:
    """The schema's ``arrays`` and ``extension_arrays`` objects.

    Raises:
        ValueError: when one array is declared twice, differently.
    """
    checked: dict[str, Any] = {}
    extension: dict[str, Any] = {"$comment": EXTENSION_COMMENT}
    for group, spec, owner in _declared():
        key = f"{group}/{spec.path}"
        section = extension if spec.extension else checked
        entry = _entry(group, spec, owner)
        known = checked.get(key) or extension.get(key)
        if known is not None:
            same = {k: v for k, v in known.items() if k not in ("family", "source")}
            if same != {k: v for k, v in entry.items() if k not in ("family", "source")}:
                raise ValueError(f"{key} is declared twice, differently: {known} and {entry}")
            continue
        section[key] = entry
    return checked, extension


def _section_text(section: dict[str, Any]) -> str:
    """One line per entry, two-space indented as the rest of the file."""
    lines = [
        f"    {json.dumps(k)}: {json.dumps(v, ensure_ascii=False)}" for k, v in section.items()
    ]
    return "{\n" + ",\n".join(lines) + "\n  }"


def _value_span(text: str, key: str) -> tuple[int, int]:
    """[start, stop) of the value of the top-level ``key`` in the schema text."""
    marker = f'\n  "{key}": '
    at = text.find(marker)
    if at < 0:
        raise ValueError(f"the schema has no top-level {key!r}")
    start = at + len(marker)
    _, stop = json.JSONDecoder().raw_decode(text, start)
    return start, stop


def generated_schema_text(text: str) -> str:
    """``text`` (the schema file) with its ``arrays`` and ``extension_arrays`` generated."""
    checked, extension = array_sections()
    for key, section in (("arrays", checked), ("extension_arrays", extension)):
        start, stop = _value_span(text, key)
        text = text[:start] + _section_text(section) + text[stop:]
    json.loads(text)  # still one JSON document
    return text


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    check = "--check" in args
    paths = [a for a in args if a != "--check"]
    path = Path(paths[0]) if paths else SCHEMA_PATH
    current = path.read_text(encoding="utf-8")
    wanted = generated_schema_text(current)
    if check:
        if wanted != current:
            print(
                f"{path}: array sections differ from the declared arrays; run "
                "python -m dancedata.featurize.schema_arrays",
                file=sys.stderr,
            )
            return 1
        return 0
    if wanted != current:
        path.write_text(wanted, encoding="utf-8")
        print(f"{path}: array sections rewritten")
    return 0


if __name__ == "__main__":
    sys.exit(main())
