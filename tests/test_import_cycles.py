"""No import cycle among crashstudy's modules, nor among its packages (a package that imports another
which imports it back: the kernel knowing the metrics that use it, results importing run, cli.main and
cli.explore importing each other).

The truth is the import graph read from the source with ``ast``: every ``import`` and ``from ... import``
of a module, at module level or deferred inside a function (a deferred import is a dependency too, only a
later one), except those under ``if TYPE_CHECKING:`` (annotations only) and those inside a package's
``__getattr__`` (PEP 562: its lazy re-export of its public API, as ``crashstudy.open_results``; a plain
module's lazy ``__getattr__`` counts, as ``analysis.plot`` offering ``plot_matrix``).
A package here is ``crashstudy.<name>`` (a subpackage, or a top-level module such as ``crashstudy.errors``).

There are no exceptions: the graph must have no cycle at module level, nor at package level. The five
back edges of the last session (and ``arrays.batch -> kernel.preload``) each went to the floor that owns the
shared thing: ``vocabulary.summary`` (the summary columns), ``study.values`` (an axis's values),
``schema.study`` (a distribution's parameters), ``arrays.vibration`` (the first natural period),
``results.plot_tag`` (the mark of our PNGs), ``arrays.preload`` and ``arrays.material_laws`` (the state at
t = 0 and the NumPy laws it walks). :data:`BACK_EDGES` keeps them, so that the test can show it still sees
each of them.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: the back edges that closed a package cycle until this layering (importer, imported, then and now)
BACK_EDGES = (
    ("crashstudy.schema.plausible", "crashstudy.arrays.timestep"),  # first_period: arrays.vibration
    ("crashstudy.schema.study", "crashstudy.study.design"),  # why_invalid: schema.study
    ("crashstudy.study.blocks", "crashstudy.results.tables"),  # SUMMARY_META: vocabulary.summary
    ("crashstudy.study.blocks", "crashstudy.study.plan"),  # the axis value checks: study.values
    ("crashstudy.results.outdir", "crashstudy.analysis.plot"),  # is_crashstudy_plot: results.plot_tag
)


def modules() -> dict[str, Path]:
    out = {}
    for path in sorted((SRC / "crashstudy").rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


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
        if isinstance(node, ast.FunctionDef) and node.name == "__getattr__" and path.name == "__init__.py":
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
    """(module graph, package graph)."""
    mods = modules()
    graph = {m: imports_of(m, p, mods) for m, p in mods.items()}
    return graph, package_graph(graph)


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The packages' graph: an edge where some module of one imports some module of another."""
    packages: dict[str, set[str]] = {}
    for m, deps in graph.items():
        for d in deps:
            if package(m) != package(d) and "crashstudy" not in (package(m), package(d)):
                packages.setdefault(package(m), set()).add(package(d))
    return packages


def test_the_import_graph_is_read_from_the_source() -> None:
    """The reader sees deferred imports, relative imports and `from pkg import module`, and skips
    TYPE_CHECKING blocks and PEP 562 ``__getattr__`` (checked on modules known to have each)."""
    mods = modules()
    runner = imports_of("crashstudy.run.runner", mods["crashstudy.run.runner"], mods)
    assert {"crashstudy.kernel.choice", "crashstudy.kernel.entry", "crashstudy.interrupt"} <= runner
    plot = imports_of("crashstudy.cli.results_cmd", mods["crashstudy.cli.results_cmd"], mods)
    assert "crashstudy.cli.plot" in plot  # deferred, inside a function
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


def test_arrays_and_schema_import_nothing_of_the_kernel() -> None:
    """The pipeline below the kernel: schema/ and arrays/ (the model, its arrays over variants, the state at
    t = 0) import no kernel module; the kernel reads them (``kernel.reference`` the NumPy laws)."""
    _, packages = graphs()
    for below in ("crashstudy.schema", "crashstudy.arrays", "crashstudy.vocabulary"):
        assert "crashstudy.kernel" not in packages.get(below, set()), below


@pytest.mark.parametrize("edge", BACK_EDGES, ids=lambda e: f"{e[0][11:]}->{e[1][11:]}")
def test_each_old_back_edge_would_be_a_package_cycle_again(edge: tuple[str, str]) -> None:
    """The test can fail: each old back edge, put back into today's graph, closes a cycle again (a package
    cycle, or a module cycle inside ``study``), and the importer no longer has it."""
    graph, packages = graphs()
    importer, imported = edge
    assert imported not in graph[importer]
    assert cycles(graph) == [] and cycles(packages) == []
    graph[importer] = graph[importer] | {imported}
    if package(importer) == package(imported):
        found, a, b = cycles(graph), importer, imported
    else:
        found, a, b = cycles(package_graph(graph)), package(importer), package(imported)
    assert any(a in c and b in c for c in found), found
