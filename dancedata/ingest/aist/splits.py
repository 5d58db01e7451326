"""AIST++ split files and ignore list → rows of the splits table, and per-split counts.

Counts come from the files themselves, so they hold even for sequences the store lacks:
``listed`` names in the file, ``ignored`` of them on the ignore list, ``usable`` = listed −
ignored, ``in_store`` / ``usable_in_store`` of them present in the store, and
``missing_from_store`` listed names the store does not hold (reported and skipped, never an
error: the store may hold a genre selection or a partial download).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from dancedata.io.aist import read_name_list


def split_rows(
    split_files: dict[tuple[str, str], Path], ignore_file: Path | None, present: set[str]
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows ``{scheme, split, listed_split, seq_id}`` for the stored sequences each split file
    lists (``split`` is ``ignored`` for ignore-listed names) and the counts described above."""
    ignored = set(read_name_list(ignore_file)) if ignore_file is not None else set()
    rows: list[dict[str, Any]] = []
    counts: dict[str, Any] = {
        "ignore_list": len(ignored),
        "ignore_list_in_store": len(ignored & present),
        "schemes": {},
    }
    for (scheme, split), path in sorted(split_files.items()):
        listed = read_name_list(path)
        n_ignored = sum(name in ignored for name in listed)
        in_store = [name for name in listed if name in present]
        for name in in_store:
            rows.append(
                {
                    "scheme": scheme,
                    "split": "ignored" if name in ignored else split,
                    "listed_split": split,
                    "seq_id": name,
                }
            )
        n_usable_in_store = sum(name not in ignored for name in in_store)
        counts["schemes"].setdefault(scheme, {})[split] = {
            "listed": len(listed),
            "ignored": n_ignored,
            "usable": len(listed) - n_ignored,
            "in_store": len(in_store),
            "usable_in_store": n_usable_in_store,
            "missing_from_store": len(listed) - len(in_store),
        }
    return rows, counts
