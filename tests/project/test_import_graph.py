"""The package's imports run one way: no import cycle between modules or between packages, no
upward import; the folders are the layers.

Allowed direction, lowest first (a module may import its own layer and the layers below it,
never one above):

    foundation → io → compute → ops → methods → store → exec → read → steps → study → api → cli

* Every module takes the layer of its top folder (:data:`LAYER_OF`): a new module in a folder
  needs no entry; a new folder does, with its reason. Only the foundation modules
  (``errors``, ``progress``, ``_version``) sit loose in ``dancedata/``
  (:func:`test_only_foundation_modules_are_loose`).
* foundation imports nothing of dancedata; io parses and writes files; compute is pure array
  code (no files, no formats) and imports nothing of io; ops is where the two meet (the BVH
  clip operations on compute's FK and resampling, the SMPL skeleton from a model file);
  methods and metrics are the pure keyframe, in-betweening and scoring code; store persists;
  exec runs work units; read reads stores; the steps (ingest, featurize, synth, export, viz)
  write stores or files from them; study runs keyframes, evaluations and experiments over
  stores with the methods and metrics; api is ``dancedata/__init__`` (``open_store``); the CLI
  is a thin shell. ``dancedata/`` never imports ``cli``.
* Sideways: featurize and study do not reach into ingest (they read what it wrote through the
  store), although they share or sit above its layer.
* Packages: the graph collapsed onto the children of every package (each subpackage one node)
  has no cycle either (:func:`test_no_package_cycle`); a cycle between two packages is invisible
  to the module-level check when no single module closes it.

The graph is built from the source with :mod:`ast`: every ``import`` and ``from ... import``
anywhere in a file (module level, inside functions, under ``if TYPE_CHECKING``), because a
function-level import is still a dependency and a circle through one is still a circle.
``from pkg import name`` counts as an import of ``pkg.name`` when that is a module, else of
``pkg``; relative imports are resolved. ``cli/`` is installed as ``dancedata.cli``.

Registration imports are allowed by rule, not listed as debts (:data:`REGISTRATION_EDGES`):
a registry that imports the modules which register themselves with it; the cycle checks run on
the graph without those edges, so any other circle through the same modules still fails. In
``dancedata.cli`` that is Typer's command registration (``main`` imports ``commands`` to
register every command module, which import the ``app`` from ``main``/``apps``); in featurize,
``family.registered()`` imports every module of ``families/``, whose classes subclass
``family``'s base.

Known violations that are not fixed yet are listed in :data:`KNOWN_VIOLATIONS`, each with the
issue item that removes it. The list can only shrink: a listed violation that no longer exists
fails :func:`test_known_violations_still_exist`, so whoever fixes one deletes its line.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SOURCES = ((REPO / "dancedata", "dancedata"), (REPO / "cli", "dancedata.cli"))

LAYERS: tuple[str, ...] = (
    "foundation",
    "io",
    "compute",
    "ops",
    "methods",
    "store",
    "exec",
    "read",
    "steps",
    "study",
    "api",
    "cli",
)

# Top-level module or folder → (layer, what it holds). Every module below a folder takes the
# folder's layer; the bare package name is the package's own __init__.
LAYER_OF: dict[str, tuple[str, str]] = {
    "dancedata.errors": ("foundation", "the one error type every layer raises"),
    "dancedata._version": ("foundation", "the version string, recorded in every manifest"),
    "dancedata.progress": ("foundation", "console progress lines for any layer; imports nothing"),
    "dancedata.io": ("io", "file formats: parse and write files (BVH, AIST++, audio, SMPL, ...)"),
    "dancedata.compute": ("compute", "pure array-in, array-out functions (FK, IK, features, ...)"),
    "dancedata.ops": ("ops", "a parsed file meets the maths: BVH clip FK, SMPL skeleton"),
    "dancedata.methods": ("methods", "keyframe selection, in-betweening, Bézier: pure arrays"),
    "dancedata.metrics": ("methods", "the metrics: pure, arrays in, MetricResult out"),
    "dancedata.store": ("store", "the versioned Zarr + Parquet store: layout, writer, reader"),
    "dancedata.exec": ("exec", "executors for work units (serial, process pool, Dask)"),
    "dancedata.read": ("read", "the store reader users open, its views, windows, datasets"),
    "dancedata.ingest": ("steps", "sources → a new store version, one folder per source"),
    "dancedata.featurize": ("steps", "featurize (the families), segment, stats: new versions"),
    "dancedata.synth": ("steps", "writes synthetic raw inputs in the sources' formats"),
    "dancedata.export": ("steps", "stored sequences written back out as files (BVH)"),
    "dancedata.viz": ("steps", "plots, renders and reports read from stores"),
    "dancedata.study": ("study", "keyframes, evaluate, experiment runs: stores → results"),
    "dancedata": ("api", "the package's __init__: open_store and the version, for users"),
    "dancedata.cli": ("cli", "the thin Typer CLI, installed as dancedata.cli"),
}

# Modules that may sit loose in dancedata/ (everything else lives in a layer's folder).
LOOSE_MODULES = ("dancedata.errors", "dancedata._version", "dancedata.progress")

# (importer's package, imported package) pairs forbidden although the layers allow them.
FORBIDDEN_SIDEWAYS: dict[tuple[str, str], str] = {
    ("dancedata.featurize", "dancedata.ingest"): "featurize reads what ingest wrote through the "
    "store, never ingest's code",
    ("dancedata.study", "dancedata.ingest"): "the study reads stores, never ingest's code",
}

# Registration imports, allowed by rule: (importer, imported) → why. A registry imports the
# modules that register themselves with it, and they import the registry; the checks below run
# on the graph without these edges, so any other circle still fails.
REGISTRATION_EDGES: dict[tuple[str, str], str] = {
    ("dancedata.cli.main", "dancedata.cli.commands"): "Typer's command registration: main "
    "imports commands, which import every command module, which import the app",
    ("dancedata.featurize.family", "dancedata.featurize.families"): "family.registered() imports "
    "every module of families/, whose classes subclass family's base",
}

# Not fixed yet. Each line names the issue item that removes it; delete the line when it does.
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
    """Strongly connected components of more than one node (Tarjan), each sorted."""
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


def top_of(module: str, root: str, cli: str) -> str:
    """The top-level folder or loose module of ``root`` that holds ``module`` (``cli`` counts as
    one folder; ``root`` itself is its own __init__)."""
    if module == cli or module.startswith(cli + "."):
        return cli
    return ".".join(module.split(".")[:2])


def packages_of(modules: set[str]) -> set[str]:
    """Every package among ``modules``: a name some other module's name continues."""
    return {p for p in modules for m in modules if m.startswith(p + ".")}


def package_cycles(graph: dict[str, set[str]]) -> list[tuple[str, list[str]]]:
    """For every package, the cycles of its children (each subpackage collapsed into one node):
    (package, sorted nodes of one strongly connected component)."""
    packages = packages_of(set(graph))
    found = []
    for package in sorted(packages):
        depth = package.count(".") + 1

        def child(module: str, package: str = package, depth: int = depth) -> str | None:
            if not module.startswith(package + "."):
                return None
            return ".".join(module.split(".")[: depth + 1])

        collapsed: dict[str, set[str]] = {}
        for module, targets in graph.items():
            a = child(module)
            if a is None:
                continue
            collapsed.setdefault(a, set())
            for target in targets:
                b = child(target)
                if b is not None and b != a:
                    collapsed[a].add(b)
                    collapsed.setdefault(b, set())
        if not any(n in packages for n in collapsed):
            continue  # no subpackage: module cycles are test_no_import_cycle's
        found += [(package, c) for c in cycles(collapsed) if any(n in packages for n in c)]
    return found


def layer_entry(module: str, table: dict[str, tuple[str, str]], cli: str) -> str | None:
    """The key of ``table`` that places ``module``: its top folder or loose module."""
    root = cli.split(".")[0]
    key = root if module == root else top_of(module, root, cli)
    return key if key in table else None


def violations(
    graph: dict[str, set[str]],
    table: dict[str, tuple[str, str]],
    layers: tuple[str, ...],
    sideways: dict[tuple[str, str], str],
    registrations: dict[tuple[str, str], str],
    cli: str,
) -> list[str]:
    """Every module cycle, package cycle (both without the registration edges), upward
    import, forbidden sideways import and foundation module importing anything, one line each."""
    unregistered = {m: {t for t in ts if (m, t) not in registrations} for m, ts in graph.items()}
    found = ["cycle: " + " <-> ".join(c) for c in cycles(unregistered)]
    found += [
        f"package cycle in {package}: " + " <-> ".join(c)
        for package, c in package_cycles(unregistered)
    ]
    for module in sorted(graph):
        own = table[layer_entry(module, table, cli)][0]  # type: ignore[index]
        for target in sorted(graph[module]):
            theirs = table[layer_entry(target, table, cli)][0]  # type: ignore[index]
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
    return violations(
        graph, LAYER_OF, LAYERS, FORBIDDEN_SIDEWAYS, REGISTRATION_EDGES, "dancedata.cli"
    )


def test_every_module_has_a_layer(graph):
    unplaced = sorted(m for m in graph if layer_entry(m, LAYER_OF, "dancedata.cli") is None)
    assert not unplaced, (
        "modules in a folder LAYER_OF does not name (add the folder, with its layer and "
        f"reason): {unplaced}"
    )
    assert all(layer in LAYERS for layer, _ in LAYER_OF.values())
    used = {layer_entry(m, LAYER_OF, "dancedata.cli") for m in graph}
    stale = sorted(k for k in LAYER_OF if k not in used)
    assert not stale, f"LAYER_OF entries that place no module (remove them): {stale}"


def test_only_foundation_modules_are_loose():
    loose = sorted(
        f"dancedata.{path.stem}"
        for path in (REPO / "dancedata").glob("*.py")
        if path.name != "__init__.py"
    )
    assert loose == sorted(LOOSE_MODULES), (
        "only the foundation modules sit loose in dancedata/; put a new module in its layer's "
        f"folder: {sorted(set(loose) - set(LOOSE_MODULES))}"
    )


def test_no_import_cycle(found):
    new = [v for v in found if v.startswith("cycle") and v not in KNOWN_VIOLATIONS]
    assert not new, "import cycles:\n" + "\n".join(new)


def test_no_package_cycle(found):
    new = [v for v in found if v.startswith("package cycle") and v not in KNOWN_VIOLATIONS]
    assert not new, "cycles between packages:\n" + "\n".join(new)


def test_no_upward_or_sideways_import(found):
    new = [v for v in found if "cycle" not in v.split(":")[0] and v not in KNOWN_VIOLATIONS]
    allowed = " → ".join(LAYERS)
    assert not new, f"imports against the direction {allowed}:\n" + "\n".join(new)


def test_known_violations_still_exist(found):
    fixed = [v for v in KNOWN_VIOLATIONS if v not in found]
    assert not fixed, "fixed, so delete from KNOWN_VIOLATIONS:\n" + "\n".join(fixed)
    assert len(set(KNOWN_VIOLATIONS)) == len(KNOWN_VIOLATIONS)


def test_graph_sees_function_level_and_type_checking_imports(graph):
    # TYPE_CHECKING: loader names MeasureWindows only in DanceStore.measure_windows' annotation.
    assert "dancedata.read.windows" in graph["dancedata.read.loader"]
    # Function-level: the thesis curves import their compute function inside the function.
    assert "dancedata.compute.stem_features" in graph["dancedata.read.views.thesis"]
    # cli/ is installed as dancedata.cli: main registers the commands inside a function.
    assert "dancedata.cli.commands" in graph["dancedata.cli.main"]
    assert not any(t.startswith("dancedata.cli") for t in graph["dancedata.read.loader"])


def test_checker_catches_cycles_upward_and_sideways_imports(tmp_path):
    """The checker itself, on a small package written to disk: a function-level upward
    import, a cycle through a TYPE_CHECKING import and a relative one, a sideways import,
    a foundation module importing, a cycle between two packages that no module cycle shows,
    a subpackage in the middle of its parent's modules (no cycle), and a registration circle
    that is allowed."""
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
        "pkg/featurize/__init__.py": "",
        "pkg/featurize/step.py": "from ..ingest.source import x\n",
        # steps a → steps b → steps a, through different modules: a package cycle only
        "pkg/study/__init__.py": "",
        "pkg/study/run.py": "from pkg.featurize import step\n",
        "pkg/featurize/report.py": "from pkg.study import tables\n",
        "pkg/study/tables.py": "x = 1\n",
        # read: base ← views/ ← loader, a subpackage between its parent's modules: no cycle
        "pkg/read/__init__.py": "",
        "pkg/read/base.py": "",
        "pkg/read/views/__init__.py": "",
        "pkg/read/views/fact.py": "from pkg.read import base\n",
        "pkg/read/loader.py": "from pkg.read.views import fact\n",
        "pkg/cli/__init__.py": "",
        "pkg/cli/main.py": "def register():\n    from pkg.cli import command\n",
        "pkg/cli/command.py": "from pkg.cli.main import register\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    layers = ("foundation", "io", "compute", "read", "steps", "cli")
    table = {
        "pkg": ("cli", ""),
        "pkg.errors": ("foundation", ""),
        "pkg.version": ("foundation", ""),
        "pkg.io": ("io", ""),
        "pkg.compute": ("compute", ""),
        "pkg.read": ("read", ""),
        "pkg.ingest": ("steps", ""),
        "pkg.featurize": ("steps", ""),
        "pkg.study": ("steps", ""),
        "pkg.cli": ("cli", ""),
    }
    graph = import_graph(((tmp_path / "pkg", "pkg"),), "pkg")
    registrations = {("pkg.cli.main", "pkg.cli.command"): ""}
    sideways = {("pkg.featurize", "pkg.ingest"): ""}
    found = violations(graph, table, layers, sideways, registrations, "pkg.cli")
    assert sorted(found) == sorted(
        [
            "cycle: pkg.compute.maths <-> pkg.compute.more",
            "package cycle in pkg: pkg.featurize <-> pkg.study",
            "upward: pkg.errors (foundation) imports pkg.io.reader (io)",
            "upward: pkg.io.reader (io) imports pkg.compute.maths (compute)",
            "sideways: pkg.featurize.step imports pkg.ingest.source",
            "foundation imports dancedata: pkg.version imports pkg.errors",
        ]
    )
    assert sorted(cycles(graph)) == [
        ["pkg.cli.command", "pkg.cli.main"],
        ["pkg.compute.maths", "pkg.compute.more"],
    ]
    # a module in a new folder is placed by the folder alone; a folder not in the table is not
    assert layer_entry("pkg.featurize.anything.new", table, "pkg.cli") == "pkg.featurize"
    assert layer_entry("pkg.cli.deep.command", table, "pkg.cli") == "pkg.cli"
    assert layer_entry("pkg.unknown.mod", table, "pkg.cli") is None
