"""Rendering the seed tables (docs/EXPERIMENTS.md §5.5–5.6) from result rows.

The reference is ``../shared/seed-tables.json`` itself (read directly here, not through the
package copy): captions verbatim, row and column order, number formats and seed values.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from dancedata.errors import InputError
from dancedata.study.tables import build, render_table, seed_tables

SHARED = Path(__file__).resolve().parents[3] / "shared" / "seed-tables.json"


def result(row_key: str, n: int, metric: str, value: float) -> dict:
    return {"row_key": row_key, "n_keyframes": n, "metric": metric, "value": value}


def test_the_package_copy_equals_the_shared_seed_tables() -> None:
    if not SHARED.is_file():
        pytest.skip("../shared/seed-tables.json not present")
    shared = json.loads(SHARED.read_text())
    assert seed_tables()["row_registry"] == shared["row_registry"]
    assert list(seed_tables()["tables"].values()) == shared["tables"]


def test_markdown_layout_caption_order_and_format() -> None:
    rows = [
        result("onset+linear_slerp", 3, "mse", 0.904),
        result("even+linear_slerp", 3, "mse", 0.8349),
        result("even+linear_slerp", 9, "mse", 0.25),
        result("dp+bezier_oracle", 5, "mse", 0.2849),
        result("even+linear_slerp", 5, "fid_g", 99.0),  # another metric: not in 4.3
    ]
    text = render_table("4.3", rows, [])
    lines = text.splitlines()
    assert lines[0] == "**Table 4.3: Evaluate MSE with three, five, and nine keyframes.**"
    assert lines[2] == "|  | 3 keyframes | 5 keyframes | 9 keyframes |"
    assert lines[4] == "| KF_{even_rotmat} | 0.83 | —[1] | 0.25 |"
    assert lines[5] == "| KF_{dp} | —[1] | 0.28 | —[1] |"
    assert lines[6] == "| KF_{onset} | 0.90 | —[1] | —[1] |"
    assert lines[-1] == "- [1] not in the results (no run of this row, N and metric)"


def test_metric_columns_and_recorded_reasons_as_footnotes() -> None:
    rows = [result("even+linear_slerp", 9, "mse", 0.251), result("dp+bezier_oracle", 9, "mse", 1)]
    skipped = [
        {"row_key": "even+linear_slerp", "n_keyframes": 9, "metric": "fid_g", "reason": "no A"},
        {"row_key": "even+linear_slerp", "n_keyframes": 9, "metric": "fid_k", "reason": "no A"},
        {
            "row_key": "even+bezier_train_mean",
            "n_keyframes": None,
            "metric": None,
            "reason": "no B",
        },  # fmt: skip
    ]
    table = build("4.4", rows, skipped)
    assert table.header == ["", "MSE", "FID_g", "FID_k"]
    assert [c.value for c in table.cells[0]] == [0.251, None, None]
    assert table.cells[0][1].note == "no A"
    assert {c.note for c in table.cells[1]} == {"no B"}
    assert "class M" in table.cells[2][0].note  # transformer row, nothing recorded
    text = render_table("4.4", rows, skipped)
    assert "- [1] no A" in text and "- [2] no B" in text and "[3] class M" in text
    assert "| KF_{dp}/\\hat{D}_{bezier} | 1.00 | —[" in text


def test_compare_seed_cells_read_ours_then_seed() -> None:
    rows = [result("even+linear_slerp", 3, "fid_g", 40.0)]
    line = render_table("4.1", rows, [], compare_seed=True).splitlines()[4]
    assert line == "| KF_{even_rotmat} | 40.00 (42.73) | —[1] (20.89) | —[1] (6.75) | -6% | — | — |"
    # 4.9 has no merged_full row in the seed: the layout keeps 4 rows
    assert len(build("4.9", [], []).labels) == 4


def test_csv_and_latex() -> None:
    rows = [result("even+linear_slerp", 9, "mse", 0.25)]
    parsed = list(csv.reader(io.StringIO(render_table("4.10", rows, [], "csv"))))
    assert parsed[0] == ["row", "MSE", "FID_g", "FID_k"]
    assert parsed[1][:2] == ["KF_{even_eulers}/\\hat{D}_{eulers_linear}", "0.25"]
    assert parsed[-1][0] == "[1]"
    latex = render_table("4.10", rows, [], "latex")
    caption = seed_tables()["tables"]["4.10"]["caption"]
    assert f"\\caption{{{caption}}}" in latex
    assert "$KF_{even_eulers}/\\hat{D}_{eulers_linear}$ & 0.25 & ---" not in latex
    assert "$KF_{even_eulers}/\\hat{D}_{eulers_linear}$ & 0.25 & —\\textsuperscript{1}" in latex
    assert latex.count("\\\\") == 1 + 4  # header + 4 rows
    compared = render_table("4.10", rows, [], "latex", compare_seed=True)
    assert "0.25 (0.25) & —\\textsuperscript{1} (16.75)" in compared
    assert "& +0\\% & —" in compared and "$\\Delta$ MSE" in compared


def test_choreograph_tables_render_dashes_with_the_reason() -> None:
    text = render_table("CG-1", [], [], compare_seed=True)
    assert "| Realism Metrics: FPD↓ | —[1] (9.8821) |" in text
    assert "class M (CG-1)" in text


def test_any_other_id_lays_out_the_results_and_unknown_seed_ids_fail() -> None:
    rows = [result("even+linear_slerp", 3, "mse", 0.07051), result("dp+linear_slerp", 9, "mse", 1)]
    lines = render_table("demo", rows, []).splitlines()
    assert lines[2] == "|  | 3 keyframes | 9 keyframes |"
    assert lines[4] == "| even+linear_slerp | 0.07051 | —[1] |"
    with pytest.raises(InputError, match="unknown seed table '4.14'"):
        render_table("4.14", rows, [])
    with pytest.raises(InputError, match="unknown table format"):
        render_table("4.3", rows, [], "html")


def test_rows_without_n_from_evaluate_fill_their_row_at_any_n() -> None:
    """`dancedata evaluate --row-key even+transformer_motion` records no N: its values serve
    that row in the N = 9 and the N = 3 tables, unless a result with its own N exists."""
    evaluated = {"row_key": "even+transformer_motion", "n_keyframes": None, "metric": "mse",
                 "value": 0.5}  # fmt: skip
    own = result("even+transformer_motion", 3, "mse", 0.75)
    assert build("4.4", [evaluated], []).cells[2][0].value == 0.5
    assert build("4.5", [evaluated, own], []).cells[2][0].value == 0.75
    assert build("4.5", [evaluated, own], []).cells[0][0].value is None
