"""A small real store for the plot and report tests: 2 synthetic AIST++ sequences through the
real commands (ingest, featurize with offline stems and NMFD, segment)."""

from __future__ import annotations

from pathlib import Path

from tests.helpers import run_cli


def build_small_store(root: Path, sequences: int = 2, seed: int = 0) -> Path:
    """``root/store`` with versions v1 (ingest), v2 (featurize), v3 (segment)."""
    raw, store = root / "raw", root / "store"
    run_cli("synth", "aist", str(raw), "--sequences", str(sequences), "--seed", str(seed), "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    run_cli("featurize", str(store), "-q", "--stems", "offline")
    run_cli("segment", str(store), "-q")
    return store


def write_keyframes_table(version_dir: Path) -> list[dict]:
    """Write a ``keyframes.parquet`` (docs/EXPERIMENTS.md §2.5 columns) into a COPY of a version:
    strategies ``even`` N=3 and ``peaks:onset`` N=5 over every measure. Returns the rows."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    measures = pq.read_table(version_dir / "measures.parquet").to_pylist()
    rows = []
    for strategy, n in (("even", 3), ("peaks:onset", 5)):
        for m in measures:
            length = m["frame_stop"] - m["frame_start"]
            local = np.floor(np.arange(n) * (length - 1) / (n - 1) + 0.5).astype(int)
            if strategy != "even":
                local[1:-1] += 1  # any distinct interior frames will do
            for k, f in enumerate(local):
                edge = k in (0, n - 1)
                rows.append(
                    {
                        "run_id": f"run-{strategy}",
                        "seq_id": m["seq_id"],
                        "measure": m["measure"],
                        "strategy": strategy,
                        "n_keyframes": n,
                        "k": k,
                        "frame": int(f),
                        "frame_in_sequence": m["frame_start"] + int(f),
                        "source": "edge" if edge else ("even" if strategy == "even" else "peak"),
                        "score": float("nan"),
                    }
                )
    pq.write_table(pa.Table.from_pylist(rows), version_dir / "keyframes.parquet")
    return rows
