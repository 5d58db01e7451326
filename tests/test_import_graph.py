"""The package's imports run one way: no import cycle between modules, no upward import.

Allowed direction, lowest first (a module may import its own layer and the layers below it,
never one above):

    foundation  →  io  →  compute  →  store  →  exec  →  read  →  ingest/pipeline  →  api  →  cli

* foundation: ``dancedata/errors.py``, ``_version.py`` (and ``progress.py``); they import
  nothing of dancedata at all.
* io → compute → store → ingest/pipeline → cli is the project's rule (docs, issue 15): formats
  parse, operations compute, the store persists, ingest and the pipeline write stores, the CLI is
  a thin shell. ``dancedata/`` never imports ``cli``.
* exec (executors for work units) sits between store and the engines that use it; read (the
  store reader and the window datasets) sits below what reads stores to compute or draw;
  api is the ``dancedata`` package's own ``__init__`` (``open_store``).
* The top-level modules are placed one by one in :data:`LAYER_OF`, each with its reason; a new
  module without a place fails :func:`test_every_module_has_a_layer`.
* Sideways: ``pipeline/`` does not reach into ``ingest/`` (issue 15 item 3), although they
  share a layer.

The graph is built from the source with :mod:`ast`: every ``import`` and ``from ... import``
anywhere in a file (module level, inside functions, under ``if TYPE_CHECKING``), because a
function-level import is still a dependency and a circle through one is still a circle.
``from pkg import name`` counts as an import of ``pkg.name`` when that is a module, else of
``pkg``; relative imports are resolved. ``cli/`` is installed as ``dancedata.cli``.

One cycle is allowed by rule, not listed as a debt: a circle wholly inside ``dancedata.cli``
is Typer's command registration (``main`` imports ``commands`` to register every command
module, which import the ``app`` from ``main``/``apps``).

Known violations that are not fixed yet are listed in :data:`KNOWN_VIOLATIONS`, each with the
issue-15 item that removes it. The list can only shrink: a listed violation that no longer
exists fails :func:`test_known_violations_still_exist`, so whoever fixes one deletes its line.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SOURCES = ((REPO / "dancedata", "dancedata"), (REPO / "cli", "dancedata.cli"))

LAYERS: tuple[str, ...] = (
    "foundation",
    "io",
    "compute",
    "store",
    "exec",
    "read",
    "ingest/pipeline",
    "api",
    "cli",
)

# Module or package → (layer, why it belongs there). A module takes the entry of its longest
# dotted prefix; the bare package name matches only the package's own __init__.
LAYER_OF: dict[str, tuple[str, str]] = {
    "dancedata.errors": ("foundation", "the one error type every layer raises"),
    "dancedata._version": ("foundation", "the version string, recorded in every manifest"),
    "dancedata.progress": ("foundation", "console progress lines for any layer; imports nothing"),
    "dancedata.io": ("io", "formats: read and write files, nothing above errors"),
    "dancedata.safe_pickle": ("io", "the restricted unpickler that io's model readers use"),
    "dancedata.compute": ("compute", "pure array-in, array-out functions"),
    "dancedata.smpl": ("compute", "SMPL-24 joint names and parents: constant tables"),
    "dancedata.smpl_skeletons": (
        "compute",
        "picks an SMPL model file (io) or the built-in rest skeleton (compute) for joint positions",
    ),
    "dancedata.bvh_ops": ("compute", "operations on a parsed BVH clip: io.bvh + compute arrays"),
    "dancedata.aist_names": ("compute", "AIST++ sequence-name parsing: pure string functions"),
    "dancedata.seq_ids": ("compute", "the seq_id character set, checked at ingest and on read"),
    "dancedata.batching": ("compute", "length bucketing of windows: pure index arithmetic"),
    "dancedata.window_fit": ("compute", "crop/pad a window to a fixed length: pure arrays"),
    "dancedata.window_augment": ("compute", "mirror/yaw a window's columns: pure arrays"),
    "dancedata.windows": ("compute", "slices the arrays it is given; never reads a store"),
    "dancedata.cameras": ("compute", "camera sets and projection from parsed camera files"),
    "dancedata.store": ("store", "the versioned Zarr + Parquet store: layout, writer, reader"),
    "dancedata.feature_cache": ("store", "per-track feature cache on disk, keyed like the store"),
    "dancedata.exec": ("exec", "executors for work units (serial, process pool, Dask)"),
    "dancedata.sequence_reader": ("read", "the thin reader: tables, sequence slices, audio"),
    "dancedata.views": ("read", "paper views, measure windows, AIST++ cameras over the reader"),
    "dancedata.loader": ("read", "the store reader users open (DanceStore, views)"),
    "dancedata.window_spans": ("read", "window spans of a split, from the reader's tables"),
    "dancedata.window_dataset": ("read", "windows of a store as numpy items, for data loaders"),
    "dancedata.torch_data": ("read", "torch datasets over window_dataset"),
    "dancedata.torch_batching": ("read", "torch batch sampler over batching"),
    "dancedata.ingest": ("ingest/pipeline", "sources → a new store version"),
    "dancedata.pipeline": ("ingest/pipeline", "featurize, segment, evaluate: store → new version"),
    "dancedata.synth": ("ingest/pipeline", "writes synthetic raw inputs in the sources' formats"),
    "dancedata.experiments": ("ingest/pipeline", "scores experiments on stores, with pipeline"),
    "dancedata.viz": ("ingest/pipeline", "plots, renders and reports read from stores"),
    "dancedata": ("api", "the package's __init__: open_store and the version, for users"),
    "dancedata.cli": ("cli", "the thin Typer CLI, installed as dancedata.cli"),
}

# (importer's package, imported package) pairs forbidden although they share a layer.
FORBIDDEN_SIDEWAYS: dict[tuple[str, str], str] = {
    ("dancedata.pipeline", "dancedata.ingest"): "issue 15 item 3: pipeline does not reach into "
    "ingest",
}

# Not fixed yet. Each line names the issue-15 item that removes it; delete the line when it does.
KNOWN_VIOLATIONS: tuple[str, ...] = ()


def module_files(sources: tuple[tuple[Path, str], ...]) -> dict[str, Path]:
    """Dotted module name → file, for every .py under each (folder, package name)."""
    modules: dict[str, Path] = {}
    for folder, package in sources:
        for path in sorted(folder.rglob("*.py")):
            parts = [p for p in path.relative_to(folder).with_suffix("").parts if p != "__init__"]
            modules[".".join([package, *parts])] = path
    return modules


def from_source(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute module a ``from ... import`` statement in ``module`` imports from."""
    if not node.level:
        return node.module or ""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    base = package[: len(package) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def import_graph(sources: tuple[tuple[Path, str], ...], root: str) -> dict[str, set[str]]:
    """Module → the modules of the ``root`` package it imports (itself excluded).

    ``from pkg import name`` is an edge to ``pkg.name`` when that is a module, otherwise to
    ``pkg``; a name that is no module is cut back to its nearest module ancestor."""
    modules = module_files(sources)
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for name in _edge_targets(module, path, node, modules):
                if name != module and (name == root or name.startswith(root + ".")):
                    graph[module].add(name)
    return graph


def _edge_targets(
    module: str, path: Path, node: ast.Import | ast.ImportFrom, modules: dict[str, Path]
) -> list[str]:
    if isinstance(node, ast.Import):
        wanted = [alias.name for alias in node.names]
    else:
        source = from_source(module, path, node)
        wanted = []
        for alias in node.names:
            full = f"{source}.{alias.name}"
            wanted.append(full if full in modules else source)
    found = []
    for name in wanted:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        if name:
            found.append(name)
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph) + 100))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return found


def layer_entry(module: str, table: dict[str, tuple[str, str]]) -> str | None:
    """The key of ``table`` that places ``module``: its longest dotted prefix (the bare root
    package only for the root's own __init__)."""
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        key = ".".join(parts[:n])
        if key in table and (n > 1 or module == key):
            return key
    return None


def violations(
    graph: dict[str, set[str]],
    table: dict[str, tuple[str, str]],
    layers: tuple[str, ...],
    sideways: dict[tuple[str, str], str],
    registration_package: str,
) -> list[str]:
    """Every cycle (except those wholly inside ``registration_package``), upward import,
    forbidden sideways import and foundation module importing anything, one line each."""
    found = [
        "cycle: " + " <-> ".join(c)
        for c in cycles(graph)
        if not all(m.startswith(registration_package + ".") for m in c)
    ]
    for module in sorted(graph):
        own = table[layer_entry(module, table)][0]  # type: ignore[index]
        for target in sorted(graph[module]):
            theirs = table[layer_entry(target, table)][0]  # type: ignore[index]
            if layers.index(theirs) > layers.index(own):
                found.append(f"upward: {module} ({own}) imports {target} ({theirs})")
            elif own == "foundation":
                found.append(f"foundation imports dancedata: {module} imports {target}")
            for (importer, imported), _why in sideways.items():
                if _under(module, importer) and _under(target, imported):
                    found.append(f"sideways: {module} imports {target}")
    return found


def _under(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(SOURCES, "dancedata")


@pytest.fixture(scope="module")
def found(graph: dict[str, set[str]]) -> list[str]:
    return violations(graph, LAYER_OF, LAYERS, FORBIDDEN_SIDEWAYS, "dancedata.cli")


def test_every_module_has_a_layer(graph):
    unplaced = sorted(m for m in graph if layer_entry(m, LAYER_OF) is None)
    assert not unplaced, f"modules with no entry in LAYER_OF (add one, with its reason): {unplaced}"
    assert all(layer in LAYERS for layer, _ in LAYER_OF.values())
    stale = sorted(k for k in LAYER_OF if not any(layer_entry(m, LAYER_OF) == k for m in graph))
    assert not stale, f"LAYER_OF entries that place no module (remove them): {stale}"


def test_no_import_cycle(found):
    new = [v for v in found if v.startswith("cycle") and v not in KNOWN_VIOLATIONS]
    assert not new, "import cycles:\n" + "\n".join(new)


def test_no_upward_or_sideways_import(found):
    new = [v for v in found if not v.startswith("cycle") and v not in KNOWN_VIOLATIONS]
    allowed = " → ".join(LAYERS)
    assert not new, f"imports against the direction {allowed}:\n" + "\n".join(new)


def test_known_violations_still_exist(found):
    fixed = [v for v in KNOWN_VIOLATIONS if v not in found]
    assert not fixed, "fixed, so delete from KNOWN_VIOLATIONS:\n" + "\n".join(fixed)
    assert len(set(KNOWN_VIOLATIONS)) == len(KNOWN_VIOLATIONS)


def test_graph_sees_function_level_and_type_checking_imports(graph):
    # TYPE_CHECKING: loader names MeasureWindows only in DanceStore.measure_windows' annotation.
    assert "dancedata.windows" in graph["dancedata.loader"]
    # Function-level: the thesis curves import their compute function inside the function.
    assert "dancedata.compute.stem_features" in graph["dancedata.views.thesis"]
    # cli/ is installed as dancedata.cli: main registers the commands inside a function.
    assert "dancedata.cli.commands" in graph["dancedata.cli.main"]
    assert not any(t.startswith("dancedata.cli") for t in graph["dancedata.loader"])


def test_checker_catches_cycles_upward_and_sideways_imports(tmp_path):
    """The checker itself, on a small package written to disk: a function-level upward
    import, a cycle through a TYPE_CHECKING import and a relative one, a sideways import,
    a foundation module importing, and a registration circle that is allowed."""
    files = {
        "pkg/__init__.py": "",
        "pkg/errors.py": "from pkg.io import reader\n",
        "pkg/version.py": "from pkg import errors\n",
        "pkg/io/__init__.py": "",
        "pkg/io/reader.py": "def read():\n    from pkg.compute import maths\n    return maths\n",
        "pkg/compute/__init__.py": "",
        "pkg/compute/maths.py": "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from pkg.compute.more import thing\n",
        "pkg/compute/more.py": "from . import maths\nthing = 1\n",
        "pkg/ingest/__init__.py": "",
        "pkg/ingest/source.py": "import pkg.compute.more\n",
        "pkg/pipeline/__init__.py": "",
        "pkg/pipeline/step.py": "from ..ingest.source import x\n",
        "pkg/cli/__init__.py": "",
        "pkg/cli/main.py": "def register():\n    from pkg.cli import command\n",
        "pkg/cli/command.py": "from pkg.cli.main import register\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    layers = ("foundation", "io", "compute", "ingest/pipeline", "cli")
    table = {
        "pkg": ("cli", ""),
        "pkg.errors": ("foundation", ""),
        "pkg.version": ("foundation", ""),
        "pkg.io": ("io", ""),
        "pkg.compute": ("compute", ""),
        "pkg.ingest": ("ingest/pipeline", ""),
        "pkg.pipeline": ("ingest/pipeline", ""),
        "pkg.cli": ("cli", ""),
    }
    graph = import_graph(((tmp_path / "pkg", "pkg"),), "pkg")
    found = violations(graph, table, layers, {("pkg.pipeline", "pkg.ingest"): ""}, "pkg.cli")
    assert sorted(found) == sorted(
        [
            "cycle: pkg.compute.maths <-> pkg.compute.more",
            "upward: pkg.errors (foundation) imports pkg.io.reader (io)",
            "upward: pkg.io.reader (io) imports pkg.compute.maths (compute)",
            "sideways: pkg.pipeline.step imports pkg.ingest.source",
            "foundation imports dancedata: pkg.version imports pkg.errors",
        ]
    )
    assert sorted(cycles(graph)) == [
        ["pkg.cli.command", "pkg.cli.main"],
        ["pkg.compute.maths", "pkg.compute.more"],
    ]
