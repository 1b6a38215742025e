"""Issue 23 items 5-6: what the analysis commands show: the summary sorted by a column outside
``--columns``, which it then shows, and the physical unit of every axis path (every material parameter
as the docs give it; results, plots and summary carry them).

The study of most tests is described in analysis_study.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.cli.main import main
from crashstudy.results.store import open_results

# ---- item 5: sort by any column, and show it ----------------------------------------------------------------------


def test_summary_sorts_by_a_column_outside_columns_and_shows_it(
    tied: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before: ``--sort peak_g.body --columns clip3ms`` exited 2 "no column 'peak_g.body'"."""
    monkeypatch.setenv("COLUMNS", "400")  # one line per row
    capsys.readouterr()
    assert main(["summary", str(tied), "--sort", "peak_g.body", "--columns", "clip3ms"]) == 0
    lines = capsys.readouterr().out.splitlines()
    header = next(ln for ln in lines if "peak_g.body" in ln)
    assert "clip3ms.body" in header and "peak_force" not in header
    peaks = open_results(tied).summary["peak_g.body"].to_numpy()
    rows = [ln.split() for ln in lines if ln.split() and ln.split()[0].isdigit()]
    assert [int(r[0]) for r in rows] == list(np.argsort(-peaks, kind="stable"))  # descending by default
    shown = [float(r[1 + header.split().index("peak_g.body")]) for r in rows]  # rows begin with the index
    assert shown == pytest.approx(sorted(peaks, reverse=True), rel=1e-6)


# ---- item 6: every axis path has its physical unit ----------------------------------------------------------------

DOC_FORMAT = Path(__file__).resolve().parents[1] / "docs" / "format.md"
CURVE = {"x": [-1.0, 0.0, 1.0], "y": [-1.0e3, 0.0, 1.0e3]}
MATERIALS = {
    "linear_elastic": {"stiffness": 1.0e5},
    "nonlinear_elastic": {"curve": "c"},
    "general_nonlinear": {
        "loading": "c",
        "unloading": "c",
        "tension_yield": 1.0e3,
        "compression_yield": -1.0e3,
    },
    "crush": {"loading": "c", "unloading_stiffness": 1.0e5},
    "damper": {"damping": 100.0},
    "elastoplastic": {"stiffness": 1.0e5, "tangent_stiffness": 1.0e4, "yield_force": 1.0e3},
    "nonlinear_damper": {"curve": "c"},
    "rate_elastic": {"curves": [{"rate": 0.0, "curve": "c"}, {"rate": 2.0, "curve": "c"}]},
}


def _doc_material_units() -> dict[str, dict[str, str]]:
    """type -> parameter -> unit expression, from the spring materials table of docs/format.md: each
    `parameter` takes the next parenthesised unit of its row ("`tangent_stiffness` ... (force/length)")."""
    import re

    text = DOC_FORMAT.read_text()
    table = text[text.index("## Spring materials") :].split("\n\n", 2)[1]
    out: dict[str, dict[str, str]] = {}
    for row in table.splitlines()[2:]:
        cells = row.split("|")
        kind, params = cells[1].strip().strip("`"), cells[2]
        out[kind] = {}
        for m in re.finditer(r"`([a-z_]+)`", params):
            unit = re.search(r"\(([a-z·/]+)\)", params[m.end() :])
            if unit:  # curve ids have none (only numeric fields are looked up)
                out[kind][m.group(1)] = unit.group(1)
    return out


def _unit_of(expression: str, system: str) -> str:
    from crashstudy.units import UNIT_SYSTEMS

    u = UNIT_SYSTEMS[system]
    names = {"force": u.force, "length": u.length, "time": u.time, "mass": u.mass}
    return "".join(
        names.get(p, "*" if p == "·" else p) for p in __import__("re").split(r"([a-z]+|·)", expression) if p
    )


def _numeric_fields(cls: type) -> list[str]:
    import typing

    def numeric(a: object) -> bool:
        return a is float or any(numeric(x) for x in typing.get_args(a))

    return [n for n, f in cls.model_fields.items() if numeric(f.annotation)]  # type: ignore[attr-defined]


@pytest.mark.parametrize("system", ["SI", "mm-s-t-N", "mm-ms-kg-kN"])
def test_every_material_parameter_axis_has_the_unit_the_docs_give(system: str, tmp_path: Path) -> None:
    """Walk every class of the Material union and every numeric field of it: a study axis on it gets the
    unit docs/format.md's material table gives (before: `1` for yield_force, tangent_stiffness, ...)."""
    import typing

    from crashstudy.results.attributes import axis_unit, units_of
    from crashstudy.schema.model import Material, Spring
    from crashstudy.study.plan import load_study

    docs = _doc_material_units()
    classes = typing.get_args(typing.get_args(Material)[0])
    assert len(classes) == len(MATERIALS) and Spring.model_fields["material"].annotation is not None
    checked = 0
    for cls in classes:
        kind = typing.get_args(cls.model_fields["type"].annotation)[0]
        model = {
            "name": "m",
            "units": system,
            "curves": {"c": CURVE},
            "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
            "springs": {"s": {"nodes": ["a", "b"], "material": {"type": kind, **MATERIALS[kind]}}},
            "end_time": 0.01,
        }
        file = tmp_path / f"{kind}.yaml"
        file.write_text(yaml.safe_dump(model))
        for field in _numeric_fields(cls):
            v = MATERIALS[kind][field]
            plan = load_study(
                {"name": "u", "model": str(file), "matrix": {f"springs.s.material.{field}": [v, 1.1 * v]}}
            )
            got = units_of(plan)[axis_unit(plan.axes[0].path, plan)]
            assert got == _unit_of(docs[kind][field], system), (kind, field, got, docs[kind][field])
            checked += 1
        if kind == "rate_elastic":  # a rate of its list: an elongation rate
            plan = load_study(
                {"name": "u", "model": str(file), "matrix": {"springs.s.material.curves.1.rate": [2.0, 3.0]}}
            )
            assert units_of(plan)[axis_unit(plan.axes[0].path, plan)] == _unit_of("length/time", system)
        if {"curve", "loading", "curves"} & set(MATERIALS[kind]):  # a point of its curve
            plan = load_study(
                {
                    "name": "u",
                    "model": str(file),
                    "matrix": {"curves.c.x.0": [-1.0, -1.1], "curves.c.y.2": [1e3, 2e3]},
                }
            )
            x_unit = "length/time" if kind == "nonlinear_damper" else "length"
            assert [units_of(plan)[axis_unit(a.path, plan)] for a in plan.axes] == [
                _unit_of(x_unit, system),
                _unit_of("force", system),
            ], kind
    assert (
        checked == 8
    )  # stiffness x2, tension/compression_yield, unloading_stiffness, damping, elastoplastic x3


def test_results_plot_and_summary_carry_the_axis_units(
    tied: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    res = open_results(tied)
    try:
        ds = res.dataset
        got = {
            a: ds[a].attrs["units"]
            for a in (
                "springs.ep.material.yield_force",
                "springs.ep.material.tangent_stiffness",
                "nodes.body.mass",
            )
        }
    finally:
        res.close()
    assert got == {
        "springs.ep.material.yield_force": "N",
        "springs.ep.material.tangent_stiffness": "N/m",
        "nodes.body.mass": "kg",
    }
    capsys.readouterr()
    assert main(["summary", str(tied), "--columns", "peak_g"]) == 0
    out = capsys.readouterr().out
    assert "[N]" in out and "[N/m]" in out
