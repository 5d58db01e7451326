"""The lint tooling stays in step: `make lint`, the pre-commit hooks and CI check the same."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _mypy_paths() -> list[str]:
    match = re.search(r"^MYPY_PATHS := (.+)$", (ROOT / "Makefile").read_text(), re.MULTILINE)
    assert match, "the Makefile defines MYPY_PATHS"
    return match.group(1).split()


def test_lint_runs_ruff_and_mypy_on_mypy_paths() -> None:
    text = (ROOT / "Makefile").read_text()
    recipe = re.search(r"^lint:.*\n((?:\t.*\n)+)", text, re.MULTILINE)
    assert recipe, "the Makefile has a lint target"
    lines = [line.strip() for line in recipe.group(1).splitlines()]
    assert lines == [
        "$(BIN)/ruff check .",
        "$(BIN)/ruff format --check .",
        "$(BIN)/mypy $(MYPY_PATHS)",
    ]
    assert {"dancedata/io", "dancedata/compute", "dancedata/store"} <= set(_mypy_paths())


def test_pre_commit_mypy_hook_checks_the_same_paths() -> None:
    config = (ROOT / ".pre-commit-config.yaml").read_text()
    entries = re.findall(r"^\s+entry: (.+)$", config, re.MULTILINE)
    mypy = [entry.split() for entry in entries if entry.split()[0].endswith("/mypy")]
    assert len(mypy) == 1, entries
    assert mypy[0][1:] == _mypy_paths()
    tools = {entry.split()[0] + " " + entry.split()[1] for entry in entries}
    assert {".venv/bin/ruff check", ".venv/bin/ruff format"} <= tools
    assert "language: system" in config and "repo: local" in config


def test_ci_runs_lint_after_the_tests() -> None:
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert "set -euo pipefail" in lines
    assert lines.index("make lint") > lines.index("make test")


def test_tests_mirror_the_packages() -> None:
    """Every test module sits in ``tests/<package>/`` for a package of ``dancedata/`` (or the
    command line, ``cli``), or in ``tests/project/`` for checks of the repository as a whole;
    none is left loose at the top of ``tests/``."""
    tests = ROOT / "tests"
    assert not sorted(p.name for p in tests.glob("test_*.py")), "loose test modules in tests/"
    packages = {p.name for p in (ROOT / "dancedata").iterdir() if (p / "__init__.py").is_file()}
    allowed = packages | {"cli", "project"}
    folders = {p.parent.relative_to(tests).parts[0] for p in tests.rglob("test_*.py")}
    folders.discard("data")  # the input corpora: generators, not test modules
    assert folders <= allowed, sorted(folders - allowed)
    assert len(folders) >= 10, sorted(folders)
