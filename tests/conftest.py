"""Shared fixtures. Real public files come from ../shared/data/real or $DANCEDATA_REAL_DATA.

Tests that use them are marked ``real_data``; they skip only when the folder is absent, and under
``CI=true`` a missing folder is a failure, because CI always has it.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

_DEFAULT_REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"


def real_data_root() -> Path:
    return Path(os.environ.get("DANCEDATA_REAL_DATA", _DEFAULT_REAL))


@pytest.fixture(scope="session")
def real_data() -> Path:
    """Root of the real public test files; skips (or fails under CI) when absent."""
    root = real_data_root()
    if not root.is_dir():
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but the real data folder is missing: {root}")
        pytest.skip(f"real data folder absent: {root}")
    return root
