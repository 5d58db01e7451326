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
