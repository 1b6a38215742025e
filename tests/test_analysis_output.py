"""Issue 23 items 5-10: what the analysis commands show (summary sort column, axis units, calibration
uncertainty, exceedance on a matrix, zip groups as one factor, the signed pulse).

The study of most tests: a 100 kg body at 3 or 5 m/s on a fixed wall through a linear pad (k) and an
elastoplastic spring in parallel; one zip group moves three paths together. The body is tied to the wall,
so it decelerates while the springs compress and is pulled back (an acceleration along its travel) once
they stretch: the signed pulse changes sign, its resultant does not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.cli.main import main
from crashstudy.results.store import open_results
from helpers import noisy_spring_force

MODEL = """\
name: tied-body
units: SI
nodes:
  wall: {position: [0.0], fixed: true}
  body: {position: [1.0], mass: 100.0}
springs:
  pad: {nodes: [wall, body], material: {type: linear_elastic, stiffness: 1.0e5}}
  ep: {nodes: [wall, body], material: {type: elastoplastic, stiffness: 2.0e5, tangent_stiffness: 1.0e4, yield_force: 5.0e3}}
initial_velocity: {body: [-4.0]}
end_time: 0.12
output: {interval: 5.0e-4}
metrics:
  - {node: body, cfc: 180, criteria: [peak_g, clip3ms]}
"""
ZIP = {
    "springs.ep.material.yield_force": [4.0e3, 6.0e3],
    "springs.ep.material.tangent_stiffness": [1.0e4, 2.0e4],
    "nodes.body.mass": [100.0, 120.0],
}


@pytest.fixture(scope="module")
def tied(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from crashstudy.run.runner import run_study

    root = tmp_path_factory.mktemp("tied")
    (root / "model.yaml").write_text(MODEL)
    study = {"name": "tied", "model": "model.yaml", "matrix": {"impact_velocity": [3.0, 5.0]}, "zip": [ZIP]}
    (root / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    run_study(root / "study.yaml", root / "out")
    return root / "out"


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


# ---- item 8: an exceedance fraction of a matrix is no probability --------------------------------------------------


def test_exceed_on_a_matrix_warns_that_it_is_not_a_random_sample(
    tied: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: 'P(peak_g.body > 15) = 0.5  (95% CI 0.06759 .. 0.9324, exact binomial; 2 of 4 variants)', no remark."""
    capsys.readouterr()
    assert main(["summary", str(tied), "--exceed", "peak_g.body", "15"]) == 0
    out, err = capsys.readouterr()
    assert "2 of 4 variants" in out and "NOT a random sample" in out
    assert "warning: this study has no sampled design" in err and "not a confidence interval" in err


@pytest.mark.parametrize(
    ("design", "axes", "warned"),
    [
        ("{method: lhs, n: 8, axes: {a: {uniform: [0, 1]}}}", ["a"], ""),
        ("{method: random, n: 8, axes: {a: {uniform: [0, 1]}}}", ["a"], ""),
        ("{method: saltelli, n: 8, axes: {a: {uniform: [0, 1]}}}", ["a"], "design method saltelli"),
        ("{method: morris, n: 8, axes: {a: {uniform: [0, 1]}}}", ["a"], "design method morris"),
        (
            "{method: lhs, n: 8, axes: {a: {uniform: [0, 1]}}}",
            ["a", "b"],
            "crossed with matrix/zip axes ['b']",
        ),
    ],
)
def test_sample_caveat_only_for_a_plain_sampled_design(design: str, axes: list[str], warned: str) -> None:
    import json

    from crashstudy.analysis.sensitivity import sample_caveat

    got = sample_caveat({"study_yaml": f"name: s\ndesign: {design}\n", "crashstudy_axes": json.dumps(axes)})
    assert (warned in got) if warned else got == ""


# ---- item 7: what a calibration does not determine ----------------------------------------------------------------

LINEAR_IDLE = """\
name: lin
units: SI
nodes:
  anchor: {position: [0.0], fixed: true}
  body: {position: [0.1], mass: 2.0}
  idle: {position: [0.3], mass: 1.0}
springs:
  s: {nodes: [anchor, body], material: {type: linear_elastic, stiffness: 2.0e4}}
  never: {nodes: [anchor, idle], material: {type: elastoplastic, stiffness: 1.0e4, tangent_stiffness: 0.0, yield_force: 50.0}}
initial_velocity: {body: [1.0]}
end_time: 0.1
"""


def test_calibration_gives_intervals_that_hold_the_truth_and_names_an_undetermined_variable(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Spring force of k = 3.1e4 N/m, m = 2.6 kg at 1 m/s (scipy RK45, rtol 1e-10, independent of the
    kernel) plus 1% Gaussian noise; a third variable, the yield force of a spring on a node at rest (it never
    carries force), cannot affect the channel. Before: its value came back at the middle of its bounds with
    no remark, no intervals, no output while it ran. After: k and m have 95% intervals that contain the
    truth and are narrow (under 2% of the value), the third is 'undetermined' in calibrated.yaml and in a
    warning, and a progress line is printed per batch of runs. The fit itself: k and m within 1%, rms error
    under 2% of the peak force v sqrt(k m), correlation above 0.999, a calibration plot (this test took in
    test_optimization.py's calibration of the same data, which ran the same fit without the idle variable).
    Its ~120 batches run on the generic kernel (bitwise the results of the others, docs/kernels.md): the
    automatic choice took the NumPy reference for 103 of them, ~1.2 s each with the elastoplastic spring."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "generic")
    k, m = 3.1e4, 2.6
    t, noisy = noisy_spring_force(k, m)
    import pandas as pd

    pd.DataFrame({"time": t, "value": noisy}).to_csv(tmp_path / "data.csv", index=False)
    (tmp_path / "model.yaml").write_text(LINEAR_IDLE)
    variables = {
        "springs.s.material.stiffness": [1.0e4, 5.0e4],
        "nodes.body.mass": [1.0, 4.0],
        "springs.never.material.yield_force": [20.0, 80.0],
    }
    study = {
        "name": "cal",
        "model": "model.yaml",
        "calibrate": {
            "data": "data.csv",
            "channel": {"quantity": "spring_force", "spring": "s"},
            "variables": variables,
        },
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["calibrate", str(tmp_path / "study.yaml"), "-o", str(out)]) == 0
    printed, err = capsys.readouterr()
    cal = yaml.safe_load((out / "calibrated.yaml").read_text())
    u = cal["uncertainty"]
    for path, truth in (("springs.s.material.stiffness", k), ("nodes.body.mass", m)):
        assert cal["variables"][path] == pytest.approx(truth, rel=0.01)
        low, high = u[path]["ci95"]
        assert low < truth < high and (high - low) / 2 < 0.02 * truth, (path, low, high)
        assert u[path]["status"] == "determined"
    idle = u["springs.never.material.yield_force"]
    assert idle["status"] == "undetermined" and idle["ci95"] is None and idle["value"] == pytest.approx(50.0)
    assert "warning: springs.never.material.yield_force is undetermined" in err
    assert "undetermined" in printed and err.count("  batch ") >= 3
    assert cal["rms_error"] < 0.02 * np.sqrt(k * m) and cal["correlation"] > 0.999
    assert (out / "calibration.png").stat().st_size > 10_000


def test_uncertainty_matches_the_closed_form_of_a_straight_line_fit() -> None:
    """Fitting y = a + b t by least squares: the classical standard errors (second implementation:
    numpy.polyfit's covariance, scaled by n - p) give the same interval; a third, zero column is undetermined
    and a duplicated column makes both of its variables poorly determined (correlation 1)."""
    from scipy import stats

    from crashstudy.analysis.calibration_report import uncertainty

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 30)
    y = 2.0 + 3.0 * t + rng.normal(0.0, 0.1, t.size)
    (b, a), cov = np.polyfit(t, y, 1, cov="unscaled")
    r = a + b * t - y
    jac = np.column_stack([np.ones_like(t), t, np.zeros_like(t)])
    rep = uncertainty(
        jac, r, ["a", "b", "z"], np.array([a, b, 0.5]), np.zeros(3), np.array([10.0, 10.0, 1.0])
    )
    half = stats.t.ppf(0.975, 28) * np.sqrt(np.diag(cov) * (r @ r) / 28)
    assert rep["a"]["ci95"] == pytest.approx([a - half[1], a + half[1]], rel=1e-9)
    assert rep["b"]["ci95"] == pytest.approx([b - half[0], b + half[0]], rel=1e-9)
    assert rep["z"]["status"] == "undetermined" and rep["a"]["status"] == "determined"
    dup = uncertainty(np.column_stack([t, t]), r, ["p", "q"], np.ones(2), np.zeros(2), np.full(2, 10.0))
    assert {v["status"] for v in dup.values()} == {"poorly determined"}


# ---- item 9: a zip group is one factor -----------------------------------------------------------------------------

SIX = [f"springs.rail{i}.material.stiffness" for i in range(6)]


def _six_zip() -> tuple[object, dict[str, str], list[str]]:
    """A summary over impact_velocity (3) x nodes.m.mass (4) x a zip group of six stiffnesses (3): 36 variants,
    metric = v * m * (first stiffness), and the attributes a results file would hold."""
    import itertools
    import json

    import pandas as pd

    axes = ["impact_velocity", "nodes.m.mass", *SIX]
    rows = []
    for i, (v, m, z) in enumerate(
        itertools.product([10.0, 12.0, 14.0], [1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0])
    ):
        rows.append(
            {
                "variant": i,
                "impact_velocity": v,
                "nodes.m.mass": m,
                **{p: z * (k + 1) for k, p in enumerate(SIX)},
                "status": "ok",
                "peak_force.rail0": v * m * z,
            }
        )
    zipped = {p: [1.0 * (k + 1), 2.0 * (k + 1), 3.0 * (k + 1)] for k, p in enumerate(SIX)}
    attrs = {
        "study_yaml": yaml.safe_dump({"name": "z", "model": "m.yaml", "zip": [zipped]}),
        "crashstudy_axes": json.dumps(axes),
        "units": "SI",
    }
    return pd.DataFrame(rows), attrs, axes


def test_heat_map_footnote_names_the_zip_group_once_and_fits_the_image(tmp_path: Path) -> None:
    """Before: 'each cell: max over' all six paths, cut off at the right edge of the image."""
    from crashstudy.analysis.factors import factors
    from crashstudy.analysis.plot_matrix import plot_matrix

    df, attrs, axes = _six_zip()
    fig = plot_matrix(
        df, "peak_force.rail0", "impact_velocity", "nodes.m.mass", axes=axes, factors=factors(attrs, axes)
    )
    fig.savefig(tmp_path / "heat.png")
    note = next(t for t in fig.texts if "each cell" in t.get_text())
    text = note.get_text()
    assert "zip: springs.rail0.material.stiffness" in text and "(6 paths)" in text and SIX[3] not in text
    assert note.get_window_extent(fig.canvas.get_renderer()).x1 <= fig.bbox.width  # type: ignore[attr-defined]
    cells = fig.axes[0].images[0].get_array()
    assert float(cells.max()) == pytest.approx(14.0 * 4.0 * 3.0)  # max over the zip factor's three values
    fig = plot_matrix(
        df, "peak_force.rail0", SIX[2], "impact_velocity", axes=axes, factors=factors(attrs, axes)
    )
    moved = " ".join(t.get_text().replace("\n", " ") for t in fig.texts)
    assert f"{SIX[2]} moves with" in moved and "each cell: max over nodes.m.mass" in moved
    with pytest.raises(Exception, match="move together"):
        plot_matrix(df, "peak_force.rail0", SIX[0], SIX[1], axes=axes, factors=factors(attrs, axes))


def test_legend_names_the_zip_group_once_and_labels_hold_one_value_per_factor() -> None:
    """Before: 'lines differing only in' the six paths that cannot differ; labels of eight numbers."""
    import xarray as xr
    from matplotlib.figure import Figure

    from crashstudy.analysis.plot_style import Variants

    df, attrs, axes = _six_zip()
    ds = xr.Dataset(
        {a: ("variant", df[a].to_numpy(), {"units": "N/m" if "rail" in a else "m/s"}) for a in axes},
        coords={"variant": df["variant"].to_numpy()},
        attrs=attrs,
    )
    look = Variants(ds, np.arange(36), axes)
    fig = Figure()
    look.decorate(fig, [fig.subplots()])
    title = fig._crashstudy_legends[0].get_title().get_text().replace("\n", " ")  # type: ignore[attr-defined]
    assert (
        "differing only in zip: springs.rail0.material.stiffness, springs.rail1.material.stiffness, ... (6 paths)"
        in title
    )
    assert SIX[4] not in title
    few = Variants(ds, np.arange(3), axes)
    assert few.labels == ["10, 1, 1", "10, 1, 2", "10, 1, 3"]


def test_sensitivity_has_one_row_per_factor_and_compare_one_parameter_per_factor() -> None:
    """Before: six identical correlation rows, one per zipped path, and a 330-character parameter column."""
    from crashstudy.analysis.compare import Comparison
    from crashstudy.analysis.factors import factors
    from crashstudy.analysis.sensitivity import indices

    df, attrs, axes = _six_zip()
    t = indices(df, attrs, "peak_force.rail0", "correlation")
    assert sorted(set(t["axis"])) == sorted(
        [
            "impact_velocity",
            "nodes.m.mass",
            "zip: springs.rail0.material.stiffness, springs.rail1.material.stiffness, ... (6 paths)",
        ]
    )
    assert len(t) == 3 * 2
    from scipy import stats

    rho = t.set_index(["axis", "index"])["value"]
    zip_name = next(a for a in t["axis"] if a.startswith("zip:"))
    assert rho[(zip_name, "spearman")] == pytest.approx(
        stats.spearmanr(df[SIX[5]], df["peak_force.rail0"])[0], abs=1e-12
    )
    cmp = Comparison.__new__(Comparison)
    cmp.axes, cmp.factors = axes, factors(attrs, axes)
    text = cmp._params(df.iloc[5])
    assert text == "impact_velocity=10 nodes.m.mass=2 springs.rail0.material.stiffness=3 (+5 zipped)"


# ---- item 10: the pulse is signed along the direction of travel ---------------------------------------------------


def test_pulse_plot_draws_the_signed_deceleration_along_the_travel(tied: Path) -> None:
    """The body travels in -x; its acceleration is the spring forces over its mass, a_x = -(F_pad + F_ep) / m
    (second implementation: the spring_force history), so the deceleration along the travel is
    -a . (-x) = a_x. Before: the resultant |a| (never negative), so the pull-back after 70 ms looked like more
    deceleration. After: the raw line is -(F_pad + F_ep) / (m g) to 1e-9, negative once the springs stretch,
    and the filtered line has the magnitude of the filtered_acceleration history and that sign."""
    from crashstudy.analysis.plot_pulse import plot_pulse

    res = open_results(tied)
    try:
        ds = res.dataset
        fig = plot_pulse(ds)
        f = ds["spring_force"].values  # (variant, time, spring)
        mass = ds["nodes.body.mass"].values
        stored = ds["filtered_acceleration"].sel(node="body").values
        t_ms = ds["time"].values * 1e3
    finally:
        res.close()
    lines = fig.axes[0].lines
    for j in range(4):
        raw, filt = lines[2 * j].get_ydata(), lines[2 * j + 1].get_ydata()
        truth = -(f[j, :, 0] + f[j, :, 1]) / mass[j] / 9.80665
        assert np.allclose(raw, truth, rtol=1e-9, atol=1e-9 * np.abs(truth).max())
        late = t_ms > 100.0
        assert np.all(raw[late] < -3.0) and np.all(filt[late] < -3.0)  # pulled back along the travel
        assert np.allclose(np.abs(filt), stored[j], rtol=1e-12, equal_nan=True)
        assert filt[np.argmin(np.abs(t_ms - 30.0))] > 5.0  # decelerating while the springs compress


def test_sensitivity_over_time_has_one_curve_per_factor(tied: Path) -> None:
    """--history: the zip group of three paths is one curve (before: three identical ones)."""
    from crashstudy.analysis.sensitivity import over_time

    res = open_results(tied)
    try:
        da = over_time(res.dataset, "spring_force", "pad")
    finally:
        res.close()
    assert list(da["axis_path"].values) == [
        "impact_velocity",
        "zip: springs.ep.material.yield_force, springs.ep.material.tangent_stiffness, ... (3 paths)",
    ]
