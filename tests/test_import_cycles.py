"""No import cycle among crashstudy's modules, nor among its packages (a package that imports another
which imports it back: the kernel knowing the metrics that use it, results importing run, cli.main and
cli.explore importing each other).

The truth is the import graph read from the source with ``ast``: every ``import`` and ``from ... import``
of a module, at module level or deferred inside a function (a deferred import is a dependency too, only a
later one), except those under ``if TYPE_CHECKING:`` (annotations only) and those inside a module's
``__getattr__`` (PEP 562: a package's lazy re-export of its public API, as ``crashstudy.open_results``).
A package here is ``crashstudy.<name>`` (a subpackage, or a top-level module such as ``crashstudy.errors``).

``KNOWN`` lists the back edges that still close a package cycle, each named with where it goes; the graph
without them must have no cycle, so a new back stair fails this test, and so does one of these grown into
a module cycle. Remove an entry when its edge is gone.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

#: (importer, imported) edges that still close a package cycle; each is for another change to remove
KNOWN = {
    ("crashstudy.schema.plausible", "crashstudy.arrays.timestep"),  # schema <-> arrays (the critical step)
    ("crashstudy.schema.study", "crashstudy.study.design"),  # schema <-> study (design method names)
    ("crashstudy.study.blocks", "crashstudy.results.tables"),  # study <-> results (summary column names)
    ("crashstudy.results.outdir", "crashstudy.analysis.plot"),  # results <-> analysis (which PNGs are ours)
}


def modules() -> dict[str, Path]:
    out = {}
    for path in sorted((SRC / "crashstudy").rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")  # fmt: skip


def imports_of(name: str, path: Path, known: Iterable[str]) -> set[str]:
    """The crashstudy modules that module ``name`` (file ``path``) imports (see the module docstring)."""
    known = set(known)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.FunctionDef) and node.name == "__getattr__":
            return
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            for a in node.names:  # `from pkg import module` imports the module
                found.add(f"{base}.{a.name}" if f"{base}.{a.name}" in known else base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(encoding="utf-8")))
    out = set()
    for mod in found:
        while mod and mod not in known:
            mod = mod.rpartition(".")[0]
        if mod and mod != name:
            out.add(mod)
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def package(module: str) -> str:
    return ".".join(module.split(".")[:2])


def graphs() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """(module graph, package graph), both without the ``KNOWN`` edges."""
    mods = modules()
    graph = {m: {d for d in imports_of(m, p, mods) if (m, d) not in KNOWN} for m, p in mods.items()}
    packages: dict[str, set[str]] = {}
    for m, deps in graph.items():
        for d in deps:
            if package(m) != package(d) and "crashstudy" not in (package(m), package(d)):
                packages.setdefault(package(m), set()).add(package(d))
    return graph, packages


def test_the_import_graph_is_read_from_the_source() -> None:
    """The reader sees deferred imports, relative imports and `from pkg import module`, and skips
    TYPE_CHECKING blocks and PEP 562 ``__getattr__`` (checked on modules known to have each)."""
    mods = modules()
    runner = imports_of("crashstudy.run.runner", mods["crashstudy.run.runner"], mods)
    assert {"crashstudy.kernel.choice", "crashstudy.kernel.entry", "crashstudy.interrupt"} <= runner
    main = imports_of("crashstudy.cli.main", mods["crashstudy.cli.main"], mods)
    assert "crashstudy.cli.plot" in main  # deferred, inside a function
    entry = imports_of("crashstudy.kernel.entry", mods["crashstudy.kernel.entry"], mods)
    assert "crashstudy.arrays.batch" not in entry  # under TYPE_CHECKING
    root = imports_of("crashstudy", mods["crashstudy"], mods)
    assert "crashstudy.results.store" not in root and "crashstudy.kernel.cache" in root  # __getattr__ skipped


def test_no_import_cycle_between_modules() -> None:
    graph, _ = graphs()
    assert cycles(graph) == []


def test_no_import_cycle_between_packages() -> None:
    """In particular: the kernel imports nothing of the metrics (the crash criteria compile beside a kernel
    through ``kernel.choice.Companion``), results nothing of run (provenance lives in ``study``)."""
    _, packages = graphs()
    assert cycles(packages) == []
    assert "crashstudy.metrics" not in packages["crashstudy.kernel"]
    assert "crashstudy.run" not in packages["crashstudy.results"]


def test_every_known_back_edge_is_still_there() -> None:
    """``KNOWN`` names only edges that exist (a removed one is taken off the list)."""
    mods = modules()
    for a, b in KNOWN:
        assert b in imports_of(a, mods[a], mods), (a, b)
