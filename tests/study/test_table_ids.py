"""``experiment table`` ids and numbers (issue 23, item 2): a run's config id renders each of
its tables with seed values and Δ, unknown ids are refused with the list, skipped rows are
footnoted, small numbers keep their significant digits. Real results folders of a real run."""

from __future__ import annotations

from pathlib import Path

import pytest

from dancedata.errors import InputError
from dancedata.study.tables import Cell, _number, _relative, render_table, resolve_table
from tests.helpers import run_cli

# slow: a 24-sequence demo store through an experiment run
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]


def test_small_numbers_keep_significant_digits() -> None:
    assert _number(4.954e-05, "%.2f") == "4.954e-05"  # was 0.00
    assert _number(0.01712, "%.2f") == "0.01712"  # was 0.02
    assert _number(0.8349, "%.2f") == "0.83" and _number(16.75, "%.2f") == "16.75"
    assert _number(0.0, "%.2f") == "0.00" and _number(None, "%.2f") == "—"
    assert _number(4.954e-05, "%.4g") == "4.954e-05"
    assert _relative(Cell(4.954e-05, 0.12)) == "-99.96%"  # was -100%
    assert _relative(Cell(0.0, 0.12)) == "-100%" and _relative(Cell(0.0171, 0.25)) == "-93%"
    assert _relative(Cell(0.1205, 0.12)) == "+0.42%"  # was +0%


def test_unknown_id_is_refused_with_the_list() -> None:
    with pytest.raises(InputError) as err:
        resolve_table("9.9", {"thesis-no-music": ["4.4", "4.5"]})
    assert str(err.value) == (
        "unknown table '9.9'; known: 4.1, 4.2, 4.3, 4.4, 4.5, 4.6, 4.7, 4.8, 4.9, 4.10, 4.11, "
        "4.12, 4.13, CG-1, CG-2, CG-4, thesis-no-music (`dancedata experiment table --list` "
        "says what each is)"
    )
    assert resolve_table("thesis-no-music", {"thesis-no-music": ["4.4", "4.5"]}) == ["4.4", "4.5"]
    assert resolve_table("demo", {"demo": ["demo"]}) == ["demo"]


def test_demo_layout_keeps_a_skipped_row_with_its_footnote() -> None:
    rows = [{"row_key": "even+linear_slerp", "n_keyframes": 3, "metric": "mse", "value": 0.5}]
    skipped = [{"row_key": "even+transformer_motion", "n_keyframes": 3, "metric": None,
                "reason": "class M (trained model): no outputs given"}]  # fmt: skip
    text = render_table("demo", rows, skipped)
    assert "| even+transformer_motion | —[1] |" in text
    assert "- [1] class M (trained model): no outputs given" in text


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("tables")
    run_cli("synth", "aist", str(root / "raw"), "--sequences", "24", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "s"), "-q")
    run_cli("featurize", str(root / "s"), "--stems", "none", "-q")
    run_cli("segment", str(root / "s"), "-q")
    config = REPO / "experiments" / "thesis-no-music.toml"
    run_cli("experiment", "run", str(config), "--store", str(root / "s"), "--out", str(root / "r"),
            "-q")  # fmt: skip
    return root / "r"


def test_run_id_renders_each_table_with_seed_values(results: Path) -> None:
    out = run_cli("experiment", "table", "thesis-no-music", "--results", str(results),
                  "--compare-seed").stdout  # fmt: skip
    titles = [line for line in out.splitlines() if line.startswith("**Table")]
    assert [t.split(":")[0] for t in titles] == ["**Table 4.4", "**Table 4.5"]
    rows = [line for line in out.splitlines() if line.startswith("| KF_")]
    assert len(rows) == 8  # 4 rows each, the class M row footnoted, not dropped
    motion = [r for r in rows if "D}_{motion}" in r]
    assert len(motion) == 2 and all("| —[" in r for r in motion)
    mark = motion[0].split("| —[", 1)[1].split("]", 1)[0]
    assert f"- [{mark}] class M (trained model)" in out  # footnoted, with its reason
    # every ours (seed) cell has its seed; MSE cells have a Δ
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")][1:4]
        assert all(c.endswith(")") and "(—)" not in c for c in cells), row
    dp = next(r for r in rows if "KF_{dp}" in r and "(0.12)" in r)
    assert "0.00 (" not in dp and "-100%" not in dp


def test_table_cli_refuses_unknown_ids_and_lists_them(results: Path) -> None:
    proc = run_cli("experiment", "table", "9.9", "--results", str(results), check=False)
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr.strip().startswith("error: unknown table '9.9'; known: 4.1, 4.2")
    assert "thesis-no-music" in proc.stderr
    listed = run_cli("experiment", "table", "--list", "--results", str(results)).stdout
    assert listed.splitlines()[0].startswith("4.1      Evaluate FID_g")
    assert listed.splitlines()[-1] == (
        "thesis-no-music the run of config thesis-no-music: tables 4.4, 4.5"
    )
