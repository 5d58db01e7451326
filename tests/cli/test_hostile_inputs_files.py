"""The hostile cases of every class but store metadata and values (arrays, links and special
files, names, configs, generated motion, paths, pose files) through the real command line; the
runner: ``tests/hostile_runner.py``; the other share: ``tests/cli/test_hostile_inputs.py``."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.data.bad.hostile import CLASSES
from tests.hostile_runner import CASES, featurized_store_for, run_case

# slow: the hostile corpus: one CLI subprocess per case, with memory limits
pytestmark = pytest.mark.slow

SHARE = tuple(k for k in CLASSES if k not in ("store-metadata", "values"))


@pytest.fixture(scope="module")
def featurized_store(request: pytest.FixtureRequest) -> Path:
    """The session's small featurized store, or ``$HOSTILE_STORE``."""
    return featurized_store_for(request)


@pytest.mark.parametrize("name", sorted(n for n, c in CASES.items() if c.klass in SHARE))
def test_hostile_case(name: str, featurized_store: Path, tmp_path: Path) -> None:
    run_case(name, featurized_store, tmp_path)
