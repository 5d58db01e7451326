"""The long-format results table (docs/EXPERIMENTS.md §5.5): its columns and types, written once.

``dancedata experiment run`` (:mod:`dancedata.study.runner`) and ``dancedata evaluate``
(:mod:`dancedata.study.evaluate`) both write ``results.parquet``, one row per (row key,
keyframe count, metric). Evaluate adds two columns after ``variant``: how many sequences could
not be scored, and which (:data:`UNSCORED_COLUMNS`). pyarrow is imported when a table is built.
"""

from __future__ import annotations

from typing import Any

# (column, pyarrow type name) in file order; the run-level columns come last.
ROW_COLUMNS: tuple[tuple[str, str], ...] = (
    ("run_id", "string"),
    ("row_key", "string"),
    ("n_keyframes", "int16"),
    ("metric", "string"),
    ("value", "float64"),
    ("n_units", "int32"),
    ("n_frames", "int32"),
    ("split", "string"),
    ("genres_excluded", "string"),
    ("variant", "string"),
)
UNSCORED_COLUMNS: tuple[tuple[str, str], ...] = (
    ("n_unscored", "int32"),
    ("unscored", "string"),
)
RUN_COLUMNS: tuple[tuple[str, str], ...] = (
    ("store_version", "string"),
    ("dancedata_version", "string"),
    ("created_at", "string"),
)


def results_columns(unscored: bool = False) -> tuple[tuple[str, str], ...]:
    """(column, type name) of the table; with ``unscored`` the evaluate columns too."""
    return ROW_COLUMNS + (UNSCORED_COLUMNS if unscored else ()) + RUN_COLUMNS


def results_schema(unscored: bool = False) -> Any:
    """The table's ``pyarrow.Schema`` (see :func:`results_columns`)."""
    import pyarrow as pa

    return pa.schema([(name, getattr(pa, kind)()) for name, kind in results_columns(unscored)])


def results_table(rows: list[dict[str, Any]], unscored: bool = False) -> Any:
    """``rows`` (dicts keyed by column; a missing key is null) as a ``pyarrow.Table`` with the
    results schema."""
    import pyarrow as pa

    schema = results_schema(unscored)
    columns = {f.name: [r.get(f.name) for r in rows] for f in schema}
    return pa.table(columns, schema=schema)
