"""What ``dancedata evaluate`` prints (issue 23, item 3): counts per metric, columns named for
what they are, every ratio-like value outside [0, 1] explained, notes citing shipped docs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dancedata.study.evaluate import EvaluateSummary
from tests.helpers import run_cli

# slow: a 24-sequence demo store featurized and evaluated
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]


def _row(metric: str, value: float, unscored: int, n_units: int, frames: int, **details) -> dict:
    return {
        "metric": metric,
        "value": value,
        "n_units": n_units,
        "n_frames": frames,
        "details": details,
        "unscored": [{"seq_id": f"s{i}", "reason": "r"} for i in range(unscored)],
    }


def test_headline_counts_metrics_and_notes_explain_values() -> None:
    record = {
        "store_version": "v3",
        "split": "crossmodal:test",
        "n_sequences": 6,
        "results": [
            _row("mse", 0.25, 0, 6, 3384),
            _row("fid_k", 31.5, 2, 4, 2000, constant_ref_columns=3),
            _row("beat_coverage", 1.69, 2, 4, 2000),
            _row("beat_hit_rate", 0.42, 2, 4, 2000),
        ],
        "skipped_metrics": {"fpd": "no rotations"},
        "unscored_sequences": [],
        "config": {"params": {}},
    }
    text = EvaluateSummary(record, Path("out")).message("evaluate").splitlines()
    assert text[0] == (
        "evaluate: v3 crossmodal:test, 4 of 5 metrics scored (on 6 or 4 of 6 sequences); "
        "record in out"
    )
    assert "sequences scored" not in text[0]
    assert text[1] == "metric                         value  sequences  n_items   frames"
    assert text[2] == "mse                             0.25        6/6        6     3384"
    assert text[4] == "beat_coverage                   1.69        4/6        4     2000"
    assert text[6] == f"{'fpd':<22}{'—':>14}{'0/6':>11}{0:>9}{0:>9}  (no rotations)"
    assert text[7].startswith("sequences: scored of the split's; n_items: the sequences, ")
    assert text[8] == (
        "note: fid_k: 3 feature column(s) constant in the ground truth, z-scored by 1e-10 "
        "(docs/STORE.md, Scoring generated motion); --drop-constant-ref-columns leaves them out"
    )
    assert text[9] == (
        "note: beat_coverage 1.69 = motion beats / music beats (B_k / B_m), not a fraction: "
        "above 1 the motion has more kinematic beats than the music has beats"
    )
    assert len(text) == 10  # no note for values inside [0, 1]
    # every document a note cites ships with the repository
    for line in text:
        for word in line.replace("(", " ").replace(",", " ").split():
            if word.endswith(".md"):
                assert (REPO / word).is_file(), word


def test_cli_headline_on_a_store_scored_against_itself(tmp_path: Path) -> None:
    raw, store = tmp_path / "raw", tmp_path / "s"
    run_cli("synth", "aist", str(raw), "--sequences", "24", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    run_cli("featurize", str(store), "--stems", "none", "-q")
    proc = run_cli("evaluate", str(store), "--generated", str(store), "--split", "test",
                   "--out", str(tmp_path / "ev"), "-q")  # fmt: skip
    lines = proc.stdout.splitlines()
    record = json.loads((tmp_path / "ev" / "results.json").read_text())
    scored, total = len(record["results"]), len(record["results"]) + len(record["skipped_metrics"])
    assert total == 20  # the 16 metrics of before, pfc, pfc_gt and mm_k, mm_g (skipped here)
    assert lines[0] == (
        f"evaluate: v2 crossmodal:test, {scored} of {total} metrics scored (on 6 of 6 "
        f"sequences); record in {tmp_path / 'ev'}"
    )
    assert lines[1].split() == ["metric", "value", "sequences", "n_items", "frames"]
    assert [line.split()[0] for line in lines[2 : 2 + scored]] == [
        r["metric"] for r in record["results"]
    ]
