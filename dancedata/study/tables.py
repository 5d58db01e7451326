"""Render the seed's results tables from result rows (docs/EXPERIMENTS.md §5.5–5.6).

The layout of every table comes from ``seed-tables.json`` (a copy ships as
``dancedata/study/seed_tables.json``): caption verbatim, row and column order, number
format. Two layouts hold experiment results:

* ``rows=keyframe strategy, cols=number of keyframes`` (000 Tables 4.1–4.3): one metric, a
  column per N;
* ``rows=keyframe/in-between combination, cols=metrics`` (4.4–4.13): one N, a column per
  metric.

The 004 tables (CG-1, CG-2, CG-4) compare trained generators; their cells render "—" with the
reason unless results carry the method's row key. A cell with no result renders "—" and a
footnote gives the run's recorded reason (or "not in the results"). ``compare_seed`` renders
each cell as ``ours (seed)``. A table id that is not a seed table (e.g. ``demo``) renders every
row key × N of the results for the metric(s) found, so any config has a table.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

from dancedata.errors import InputError

DASH = "—"
FORMATS = ("md", "latex", "csv")
METRIC_HEADERS = {"mse": "MSE", "fid_g": "FID_g", "fid_k": "FID_k"}


@lru_cache(maxsize=1)
def seed_tables() -> dict[str, Any]:
    """The parsed ``seed-tables.json`` (row registry + tables by id)."""
    text = resources.files("dancedata.study").joinpath("seed_tables.json").read_text("utf-8")
    data = json.loads(text)
    return {"row_registry": data["row_registry"], "tables": {t["id"]: t for t in data["tables"]}}


@dataclass
class Cell:
    value: float | None
    seed: float | None
    note: str | None = None  # why there is no value


@dataclass
class Rendered:
    """A table's cells before formatting."""

    table_id: str
    caption: str
    header: list[str]
    labels: list[str]
    cells: list[list[Cell]]
    fmt: list[list[str]]  # printf format per cell
    notes: list[str] = field(default_factory=list)


def _lookup(results: list[dict[str, Any]]) -> dict[tuple[str, int | None, str], dict[str, Any]]:
    """(row_key, N, metric) → result row; the first of duplicates wins. Rows without N (a
    ``dancedata evaluate --row-key`` record) are keyed with N = None and serve that row at
    any N that has no result of its own."""
    out: dict[tuple[str, int | None, str], dict[str, Any]] = {}
    for r in results:
        n = r.get("n_keyframes")
        out.setdefault((r["row_key"], None if n is None else int(n), r["metric"]), r)
    return out


def _reasons(skipped: list[dict[str, Any]]) -> dict[tuple[str, int | None, str | None], str]:
    return {(s["row_key"], s.get("n_keyframes"), s.get("metric")): s["reason"] for s in skipped}


def _why(reasons: dict, row_key: str, n: int, metric: str) -> str:
    for key in ((row_key, n, metric), (row_key, n, None), (row_key, None, metric),
                (row_key, None, None)):  # fmt: skip
        if key in reasons:
            return reasons[key]
    registry = seed_tables()["row_registry"]
    if registry.get(row_key, {}).get("class") == "M":
        return f"class M ({row_key}): needs a trained model's outputs (--generated)"
    return "not in the results (no run of this row, N and metric)"


def _demo_layout(results: list[dict[str, Any]], table_id: str,
                 skipped: list[dict[str, Any]] | None = None) -> dict[str, Any]:  # fmt: skip
    """Every row key × N of the results for the metric(s) found; rows the run skipped
    entirely stay in the table (their cells footnoted with the recorded reason)."""
    metrics = sorted({r["metric"] for r in results})
    ns = sorted({int(r["n_keyframes"]) for r in results})
    rows = list(dict.fromkeys(r["row_key"] for r in results))
    rows += [k for k in dict.fromkeys(s["row_key"] for s in skipped or []) if k not in rows]
    if not results:
        raise InputError(f"no seed table {table_id!r} and no results to lay out")
    return {
        "id": table_id,
        "caption": f"{', '.join(METRIC_HEADERS.get(m, m) for m in metrics)} per keyframe "
        f"strategy + in-betweener and keyframes per measure N.",
        "layout": "rows=keyframe strategy, cols=number of keyframes",
        "metric": metrics[0] if len(metrics) == 1 else None,
        "metrics": metrics,
        "columns": [{"key": n, "header": f"{n} keyframes"} for n in ns],
        "rows": [{"label": key, "row_key": key, "values": {}} for key in rows],
        "format": "%.4g",
    }


def build(table_id: str, results: list[dict[str, Any]], skipped: list[dict[str, Any]]
          ) -> Rendered:  # fmt: skip
    """The cells of ``table_id`` from result rows and the recorded skips."""
    tables = seed_tables()["tables"]
    spec = tables.get(table_id)
    if spec is None:
        if not table_id or table_id.upper().startswith(("CG", "4.")):
            known = ", ".join(tables)
            raise InputError(f"unknown seed table {table_id!r}; known: {known}")
        spec = _demo_layout(results, table_id, skipped)
    found = _lookup(results)
    reasons = _reasons(skipped)
    layout = spec["layout"]
    header = ["", *[c["header"] for c in spec["columns"]]]
    labels, cells, fmts = [], [], []
    for row in spec["rows"]:
        label = row["label"] if "group" not in row else f"{row['group']}: {row['label']}"
        line, line_fmt = [], []
        metrics = spec.get("metrics") or [spec.get("metric")]
        for column in spec["columns"]:
            key = column["key"]
            seed = row["values"].get(str(key))
            fmt = spec["format"]
            if isinstance(fmt, dict):
                fmt = fmt.get(row["row_key"], "%.4f")
            if layout.startswith("rows=keyframe strategy"):
                sub = [(row["row_key"], int(key), m) for m in metrics]
            elif layout.startswith("rows=keyframe/in-between"):
                sub = [(row["row_key"], int(spec["n_keyframes"]), str(key))]
            else:  # 004 tables: methods are trained generators
                line.append(Cell(None, seed, f"class M ({spec['id']}): needs the outputs of "
                                 "trained generators (and, for CG-2, the Label Distances that "
                                 "spec §4.6 finds underspecified)"))  # fmt: skip
                line_fmt.append(fmt)
                continue
            keys = [*sub, *((k[0], None, k[2]) for k in sub)]
            hit = next((found[k] for k in keys if k in found), None)
            if hit is not None and hit["value"] is not None:
                line.append(Cell(float(hit["value"]), seed))
            else:
                line.append(Cell(None, seed, _why(reasons, *sub[0])))
            line_fmt.append(fmt)
        labels.append(label)
        cells.append(line)
        fmts.append(line_fmt)
    return Rendered(spec["id"], spec["caption"], header, labels, cells, fmts)


MIN_SIGNIFICANT = 2  # a fixed-point format showing fewer digits of a value falls back to %.4g


def _number(value: float | None, fmt: str) -> str:
    """``fmt % value``, except that a fixed-point format (``%.2f``) that would show fewer
    than :data:`MIN_SIGNIFICANT` significant digits of a non-zero value (4.954e-05 as 0.00,
    0.01712 as 0.02) gives ``%.4g`` instead."""
    if value is None:
        return DASH
    import math
    import re

    fixed = re.fullmatch(r"%\.(\d+)f", fmt)
    if fixed and value != 0 and math.isfinite(value):
        shown = int(fixed[1]) + math.floor(math.log10(abs(value))) + 1
        if shown < MIN_SIGNIFICANT:
            return f"{value:.4g}"
    return fmt % value


def _cell_text(cell: Cell, fmt: str, notes: list[str], compare_seed: bool,
               marker: str) -> str:  # fmt: skip
    if cell.value is None:
        if cell.note not in notes:
            notes.append(cell.note or "")
        ours = f"{DASH}{marker.format(notes.index(cell.note or '') + 1)}"
    else:
        ours = _number(cell.value, fmt)
    if compare_seed:
        return f"{ours} ({_number(cell.seed, fmt)})"
    return ours


def _relative(cell: Cell) -> str:
    """The relative difference block of ``compare_seed`` (docs/EXPERIMENTS.md §5.5), in percent."""
    if cell.value is None or cell.seed is None or cell.seed == 0:
        return DASH
    change = 100.0 * (cell.value - cell.seed) / abs(cell.seed)
    text = f"{change:+.0f}%"
    if text in ("-100%", "+0%", "-0%") and change not in (-100.0, 0.0):
        text = f"{change:+.2f}%"  # -99.96%, not -100% (ours is not zero); +0.40%, not +0%
    return text


def render_table(table_id: str, results: list[dict[str, Any]],
                 skipped: list[dict[str, Any]] | None = None, fmt: str = "md",
                 compare_seed: bool = False) -> str:  # fmt: skip
    """``table_id`` rendered as Markdown (``md``), LaTeX or CSV; footnotes give the reason of
    every "—"."""
    if fmt not in FORMATS:
        raise InputError(f"unknown table format {fmt!r}; known: {', '.join(FORMATS)}")
    table = build(table_id, results, skipped or [])
    notes: list[str] = []
    marker = {"md": "[{}]", "latex": "\\textsuperscript{{{}}}", "csv": "[{}]"}[fmt]
    body = [
        [_cell_text(c, f, notes, compare_seed, marker) for c, f in zip(line, fl, strict=True)]
        for line, fl in zip(table.cells, table.fmt, strict=True)
    ]
    title = f"Table {table.table_id}: {table.caption}"
    if compare_seed:
        title += " Cells: ours (seed); Δ: (ours − seed) / seed."
        table.header = [*table.header, *(f"Δ {h}" for h in table.header[1:])]
        body = [
            [*line, *(_relative(c) for c in cells)]
            for line, cells in zip(body, table.cells, strict=True)
        ]
    if fmt == "md":
        out = [f"**{title}**", "", "| " + " | ".join(table.header) + " |",
               "|" + "---|" + "---:|" * (len(table.header) - 1)]  # fmt: skip
        for label, line in zip(table.labels, body, strict=True):
            out.append("| " + " | ".join([label, *line]) + " |")
        if notes:
            out.append("")
            out.extend(f"- [{i}] {note}" for i, note in enumerate(notes, 1))
        return "\n".join(out) + "\n"
    if fmt == "csv":
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(["row", *table.header[1:]])
        for label, line in zip(table.labels, body, strict=True):
            writer.writerow([label, *line])
        for i, note in enumerate(notes, 1):
            writer.writerow([f"[{i}]", note])
        return buffer.getvalue()
    body = [[cell.replace("%", "\\%") for cell in line] for line in body]
    return _latex(table, body, notes, title)


def _tex(text: str) -> str:
    for a, b in (("\\", "\\textbackslash{}"), ("&", "\\&"), ("%", "\\%"), ("#", "\\#"),
                 ("_", "\\_")):  # fmt: skip
        text = text.replace(a, b)
    return text


def _latex(table: Rendered, body: list[list[str]], notes: list[str], title: str) -> str:
    registry = seed_tables()["row_registry"]
    seed_spec = seed_tables()["tables"].get(table.table_id, {})
    rows = seed_spec.get("rows", [])
    header = " & ".join(_tex(h).replace("Δ", "$\\Delta$") for h in table.header)
    out = ["\\begin{table}[ht]", "\\centering",
           f"\\caption{{{_tex(table.caption)}}}",
           "\\begin{tabular}{l" + "r" * (len(table.header) - 1) + "}", "\\hline",
           header + " \\\\", "\\hline"]  # fmt: skip
    for i, (label, line) in enumerate(zip(table.labels, body, strict=True)):
        raw = rows[i]["label"] if i < len(rows) else label
        if raw in (v["label"] for v in registry.values()) or raw.startswith("KF_"):
            shown = f"${raw}$"  # the seed's own LaTeX label
        else:
            shown = _tex(label)
        out.append(" & ".join([shown, *line]) + " \\\\")
    out += ["\\hline", "\\end{tabular}"]
    for i, note in enumerate(notes, 1):
        out.append(f"\\par\\footnotesize\\textsuperscript{{{i}}} {_tex(note)}")
    out.append("\\end{table}")
    return "\n".join(out) + "\n"


def run_tables(folders: list[str | Path]) -> dict[str, list[str]]:
    """Per experiment run in ``folders``: its config id → the table ids its config lists."""
    from dancedata.study.runner import read_results

    out: dict[str, list[str]] = {}
    for folder in folders:
        _, record = read_results(Path(folder))
        config_id = record.get("config_id")
        tables = record.get("tables")
        if isinstance(config_id, str):
            listed = [t for t in tables if isinstance(t, str)] if isinstance(tables, list) else []
            out.setdefault(config_id, listed or [config_id])
    return out


def table_ids(runs: dict[str, list[str]] | None = None) -> list[str]:
    """What ``experiment table`` accepts: the seed tables' ids, then each run's config id and
    the tables it lists."""
    ids = list(seed_tables()["tables"])
    for config_id, listed in (runs or {}).items():
        ids += [i for i in (config_id, *listed) if i not in ids]
    return ids


def list_tables(runs: dict[str, list[str]] | None = None) -> str:
    """``experiment table --list``: one line per id with what it is."""
    lines = []
    for table_id, spec in seed_tables()["tables"].items():
        caption = spec.get("caption", "")
        lines.append(f"{table_id:<8} {caption[:90]}{'…' if len(caption) > 90 else ''}")
    for config_id, listed in (runs or {}).items():
        lines.append(f"{config_id:<8} the run of config {config_id}: tables {', '.join(listed)}")
    return "\n".join(lines) + "\n"


def resolve_table(table_id: str, runs: dict[str, list[str]]) -> list[str]:
    """The tables ``table_id`` stands for: a run's config id → each table its config lists; a
    seed table or a table a run lists → itself; anything else: InputError with the list."""
    if table_id in runs:
        return runs[table_id]
    if table_id in table_ids(runs):
        return [table_id]
    raise InputError(
        f"unknown table {table_id!r}; known: {', '.join(table_ids(runs))} "
        "(`dancedata experiment table --list` says what each is)"
    )


def load_results(folders: list[str | Path]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Result rows and skips of one or more results folders (earlier folders win a cell)."""
    from dancedata.study.runner import read_results

    rows: list[dict[str, Any]] = []
    skipped: list[dict[str, Any]] = []
    for folder in folders:
        found, record = read_results(Path(folder))
        rows.extend(r for r in found if r.get("row_key") and r.get("value") is not None)
        listed = record.get("skipped", [])
        skipped.extend(
            s
            for s in (listed if isinstance(listed, list) else [])
            if isinstance(s, dict) and {"row_key", "reason"} <= set(s)
        )
    return rows, skipped
