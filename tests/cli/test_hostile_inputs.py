"""The hostile cases of the store classes that cost the most commands (store metadata, values)
through the real command line; the runner and what it checks: ``tests/hostile_runner.py``.
The other classes: ``tests/cli/test_hostile_inputs_files.py``."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.hostile_runner import CASES, featurized_store_for, run_case

# slow: the hostile corpus: one CLI subprocess per case, with memory limits
pytestmark = pytest.mark.slow

# Classes run here; test_hostile_inputs_files.py runs every other class (about half the
# command runs each, so two xdist workers share the corpus).
SHARE = ("store-metadata", "values")


@pytest.fixture(scope="module")
def featurized_store(request: pytest.FixtureRequest) -> Path:
    """The session's small featurized store, or ``$HOSTILE_STORE``."""
    return featurized_store_for(request)


@pytest.mark.parametrize("name", sorted(n for n, c in CASES.items() if c.klass in SHARE))
def test_hostile_case(name: str, featurized_store: Path, tmp_path: Path) -> None:
    run_case(name, featurized_store, tmp_path)


def test_every_class_has_cases() -> None:
    """Each class of the untrusted-input issue has cases in the corpus, and every case runs in
    one of the two runner files."""
    from tests.cli.test_hostile_inputs_files import SHARE as FILES_SHARE
    from tests.data.bad.hostile import CLASSES

    assert not set(SHARE) & set(FILES_SHARE) and set(SHARE) | set(FILES_SHARE) == set(CLASSES)
    have = {case.klass for case in CASES.values()}
    mine = {"names", "configs", "generated", "paths", "pose-files"}
    assert mine <= have, sorted(mine - have)
    assert have <= set(CLASSES)


def test_store_strings_are_escaped_in_the_report(featurized_store: Path, tmp_path: Path) -> None:
    """A genre holding HTML and mathtext: the report shows it as text (escaped), the gallery
    figure draws it literally (exit 0, no mathtext error)."""
    from tests.data.bad.hostile_inputs import edit_tables
    from tests.helpers import run_cli

    store = tmp_path / "store"
    shutil.copytree(featurized_store, store, symlinks=True)
    hostile = "<script>alert(1)</script> $\\foo$"
    edit_tables(store, lambda _t, row: {**row, "genre": hostile} if "genre" in row else row,
                ("sequences",))  # fmt: skip
    out = tmp_path / "report.html"
    run_cli("report", str(store), str(out))
    page = out.read_text(encoding="utf-8")
    assert "&lt;script&gt;alert(1)&lt;/script&gt; $\\foo$" in page
    assert "<script>alert" not in page
