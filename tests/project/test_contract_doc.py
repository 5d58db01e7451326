"""docs/CONTRACT.md stays in step with schemas/store.schema.json and the CLI: every table, every
required column, every array (checked or extension) and every command is named on the page."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CONTRACT = ROOT / "docs" / "CONTRACT.md"
SCHEMA = json.loads((ROOT / "schemas" / "store.schema.json").read_text())


def _named(text: str) -> set[str]:
    """Every `code span` of the page."""
    parts = text.split("`")
    return {parts[i] for i in range(1, len(parts), 2)}


def test_every_schema_table_column_and_array_is_in_the_contract():
    named = _named(CONTRACT.read_text())
    missing = []
    for table, spec in SCHEMA["tables"].items():
        missing += [f"table {table}"] if table not in named else []
        missing += [f"{table}.{c}" for c in spec["columns"] if c not in named]
    for section in ("arrays", "extension_arrays"):
        missing += [name for name in SCHEMA[section] if "/" in name and name not in named]
    for group, attrs in SCHEMA["group_attrs"].items():
        missing += [f"{group} attr {a}" for a in attrs if a not in named]
    assert not missing, f"docs/CONTRACT.md does not name: {missing}"
    assert f"`format_version` is **{SCHEMA['format_version']}**" in CONTRACT.read_text()


def test_every_command_is_in_the_contract():
    code = (
        "from dancedata.cli.main import build_command\n"
        "def walk(cmd, path):\n"
        "    subs = getattr(cmd, 'commands', None)\n"
        "    if not subs:\n"
        "        print(path)\n"
        "    for name, sub in (subs or {}).items():\n"
        "        walk(sub, (path + ' ' + name).strip())\n"
        "walk(build_command(), '')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    commands = out.stdout.split()
    paths = [line for line in out.stdout.splitlines() if line]
    assert "featurize" in commands and "ingest aist" in paths
    named = _named(CONTRACT.read_text())
    missing = [p for p in paths if f"dancedata {p}" not in named]
    assert not missing, f"docs/CONTRACT.md does not list: {missing}"


def test_docs_point_at_the_contract_in_the_repository():
    for doc in ("README.md", "docs/STORE.md"):
        text = (ROOT / doc).read_text()
        assert "../shared/CONTRACT.md" not in text, doc
        assert "CONTRACT.md" in text, doc
