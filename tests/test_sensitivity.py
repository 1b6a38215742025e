"""Sensitivity and exceedance (crashstudy.analysis.sensitivity, ``crashstudy sensitivity``, ``summary --exceed``):
indices against closed forms, the failed-variant policy, and the command line end to end."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import xarray as xr
import yaml
from scipy import stats

from crashstudy.analysis.sensitivity import exceedance, indices, over_time
from crashstudy.cli.main import main
from crashstudy.study.design import unit_rows
from models import DROP


def _frame(method: str, n: int, y_of: Any, d: int = 3) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A summary of a design over d uniform [0, 1] axes whose metric is ``y_of(unit rows)``."""
    u = unit_rows(method, n, 5, d)
    axes = [f"a{k}" for k in range(d)]
    df = pd.DataFrame(
        {
            "variant": np.arange(len(u)),
            **{a: u[:, k] for k, a in enumerate(axes)},
            "status": "ok",
            "y": y_of(u),
        }
    )
    design = {"method": method, "n": n, "seed": 5, "axes": {a: {"uniform": [0.0, 1.0]} for a in axes}}
    attrs = {"crashstudy_axes": json.dumps(axes), "study_yaml": yaml.safe_dump({"design": design})}
    return df, attrs


def test_sobol_indices_of_an_additive_function_match_the_closed_form() -> None:
    """y = 2 x0 + x1^2, x ~ U(0, 1): Var = 4/12 + 4/45, so S1 = ST = (0.7895, 0.2105, 0) (closed form);
    Saltelli n = 1024 (8192 rows): each estimate within 3 of its own 95% half-widths (at least 0.02)."""
    df, attrs = _frame("saltelli", 1024, lambda u: 2.0 * u[:, 0] + u[:, 1] ** 2)
    t = indices(df, attrs, "y", "sobol").set_index(["axis", "index"])
    var = 4.0 / 12.0 + 4.0 / 45.0
    exact = {"a0": (4.0 / 12.0) / var, "a1": (4.0 / 45.0) / var, "a2": 0.0}
    for a, s in exact.items():
        for i in ("S1", "ST"):
            row = t.loc[(a, i)]
            assert abs(row["value"] - s) <= max(3.0 * row["confidence"], 0.02), (a, i, row["value"], s)


def test_morris_mu_star_of_a_linear_input_is_its_slope() -> None:
    """y = 2 x0 + x1^2: every elementary effect of x0 is exactly 2 (mu_star 2, sigma 0); x2 does nothing."""
    df, attrs = _frame("morris", 30, lambda u: 2.0 * u[:, 0] + u[:, 1] ** 2)
    t = indices(df, attrs, "y", "morris").set_index(["axis", "index"])
    assert t.loc[("a0", "mu_star"), "value"] == pytest.approx(2.0, abs=1e-9)
    assert t.loc[("a0", "sigma"), "value"] == pytest.approx(0.0, abs=1e-9)
    assert t.loc[("a2", "mu_star"), "value"] == pytest.approx(0.0, abs=1e-12)
    assert 0.0 < t.loc[("a1", "mu_star"), "value"] < 2.0  # d(x^2)/dx over [0, 1]: between 0 and 2


def test_a_failed_variant_makes_the_sobol_indices_nan_with_the_reason_never_a_biased_number() -> None:
    df, attrs = _frame("saltelli", 64, lambda u: u[:, 0])
    df.loc[7, "status"], df.loc[7, "y"] = "failed", np.nan
    t = indices(df, attrs, "y", "sobol")
    assert t["value"].isna().all() and t["note"].str.contains("1 of 512 variants failed").all()


def test_correlation_and_its_fisher_interval() -> None:
    """y = x0 + 0.1 * noise over 400 random rows: Spearman and Pearson equal scipy's (second
    implementation); the interval is tanh(atanh(r) +- 1.96 / sqrt(n - 3)); a failed row is left out and
    counted."""
    rng = np.random.default_rng(0)
    df, attrs = _frame("random", 400, lambda u: u[:, 0] + 0.1 * rng.standard_normal(len(u)))
    df.loc[3, "status"] = "failed"
    t = indices(df, attrs, "y", "correlation").set_index(["axis", "index"])
    ok = df["status"] == "ok"
    r = stats.spearmanr(df.loc[ok, "a0"], df.loc[ok, "y"])[0]
    assert t.loc[("a0", "spearman"), "value"] == pytest.approx(r, rel=1e-12)
    half = 1.959963984540054 / np.sqrt(399 - 3)
    width = (np.tanh(np.arctanh(r) + half) - np.tanh(np.arctanh(r) - half)) / 2
    assert t.loc[("a0", "spearman"), "confidence"] == pytest.approx(width, rel=1e-9)
    assert t.loc[("a0", "pearson"), "value"] == pytest.approx(
        stats.pearsonr(df.loc[ok, "a0"], df.loc[ok, "y"])[0]
    )
    assert (t["note"] == "1 failed variant(s) left out").all()


def test_exceedance_is_the_binomial_fraction_with_its_exact_interval() -> None:
    y = np.r_[np.full(90, 1.0), np.full(10, 3.0), [np.nan, np.nan]]
    df = pd.DataFrame({"y": y, "status": ["ok"] * 100 + ["failed"] * 2})
    e = exceedance(df, "y", 2.0)
    ci = stats.binomtest(10, 100).proportion_ci(method="exact")
    assert (e.n, e.exceed, e.failed) == (100, 10, 2) and e.probability == 0.1
    assert (e.low, e.high) == pytest.approx((ci.low, ci.high), rel=1e-12)
    assert e.if_failed_exceed == pytest.approx(12 / 102)


MODEL = DROP.replace("end_time: 0.03", "end_time: 0.02").replace(
    "output: {histories: none}", "output: {interval: 1.0e-3, histories: [spring_force]}"
)  # the drop of test_design, sampled


def test_command_line_writes_sensitivity_csv_and_the_history_over_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 64-row LHS over mass and speed of a linear drop: peak force = v sqrt(k m), so its Spearman
    correlation with speed and with mass are both positive; the history correlation at every sample
    equals scipy.stats.spearmanr across variants (second implementation, 1e-12); exit 2 for sobol on a
    study without a saltelli design, and for a non-number limit of --exceed."""
    (tmp_path / "model.yaml").write_text(MODEL)
    study = {
        "name": "drop-design",
        "model": "model.yaml",
        "design": {
            "method": "lhs",
            "n": 64,
            "seed": 2,
            "axes": {
                "nodes.body.mass": {"uniform": [50.0, 150.0]},
                "impact_velocity": {"uniform": [3.0, 7.0]},
            },
        },
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "study.yaml"), "-o", str(out), "--progress", "off"]) == 0
    assert main(["sensitivity", str(out), "--metric", "peak_force.pad", "--history", "spring_force"]) == 0
    t = pd.read_csv(out / "sensitivity.csv").set_index(["axis", "index"])
    assert (
        t.loc[("impact_velocity", "spearman"), "value"] > 0.5
        and t.loc[("nodes.body.mass", "spearman"), "value"] > 0.3
    )
    with xr.open_dataset(out / "results.nc") as ds:
        force, v = ds["spring_force"].values[:, :, 0], ds["impact_velocity"].values
    with xr.open_dataarray(out / "sensitivity_spring_force.nc") as da:
        got = da.sel(axis_path="impact_velocity").values
    for k in (3, 8, 15):
        assert got[k] == pytest.approx(stats.spearmanr(v, force[:, k])[0], abs=1e-12)
    assert (out / "sensitivity_spring_force.png").stat().st_size > 10_000
    capsys.readouterr()
    assert main(["sensitivity", str(out), "--metric", "peak_force.pad", "--method", "sobol"]) == 2
    assert "needs a study with design: {method: saltelli}" in capsys.readouterr().err
    assert main(["summary", str(out), "--exceed", "peak_force.pad", "lots"]) == 2
    assert main(["summary", str(out), "--exceed", "peak_force", "2.0e4"]) == 0
    assert "P(peak_force.pad > 20000)" in capsys.readouterr().out


def test_over_time_refuses_an_unknown_item() -> None:
    ds = xr.Dataset(
        {
            "spring_force": (("variant", "time", "spring"), np.zeros((3, 2, 1))),
            "status": ("variant", np.array(["ok"] * 3)),
            "a": ("variant", [1.0, 2.0, 3.0]),
        },
        coords={"spring": ["s"], "time": [0.0, 1.0]},
        attrs={"crashstudy_axes": '["a"]'},
    )
    with pytest.raises(ValueError, match="no spring 'x'"):
        over_time(ds, "spring_force", "x")


@pytest.mark.parametrize("distinct_max", [1 << 20, 50])  # 50: the sampled axis is ranked whole (SciPy)
def test_streamed_correlation_equals_scipy_on_the_whole_columns_with_ties(
    monkeypatch: pytest.MonkeyPatch, distinct_max: int
) -> None:
    """correlation_table over blocks of 997 rows, the metric ranked in buckets of ~300 rows (~20 bucket files):
    Spearman and Pearson equal scipy.stats.spearmanr / pearsonr on the whole columns of the rows that ran
    (second implementation, 1e-12). Two matrix axes (6 and 40 values) and a sampled one (6000 values); the
    metric rounded so that it has many ties (and ties across bucket cut points); failed rows and NaN left out."""
    from crashstudy.analysis import correlation

    monkeypatch.setattr(correlation, "BUCKET_ROWS", 300)
    monkeypatch.setattr(correlation, "SAMPLE", 256)
    monkeypatch.setattr(correlation, "DISTINCT_MAX", distinct_max)
    rng = np.random.default_rng(3)
    n = 6000
    a = np.tile(np.linspace(1.0, 2.0, 6), n // 6)
    b = np.repeat(np.linspace(-3.0, 5.0, 40), n // 40)
    c = rng.uniform(0.0, 1.0, n)
    y = np.round(2.0 * a - 0.3 * b + 0.5 * c + rng.standard_normal(n), 1)  # ~100 distinct values: ties
    status = np.where(rng.uniform(size=n) < 0.03, "failed", "ok")
    y[rng.integers(0, n, 20)] = np.nan
    df = pd.DataFrame({"variant": np.arange(n), "a": a, "b": b, "c": c, "status": status, "y": y})
    blocks = lambda: (df.iloc[lo : lo + 997] for lo in range(0, n, 997))  # noqa: E731
    t = correlation.correlation_table(blocks, {"a": "a", "b": "b", "c": "c"}, "y").set_index(
        ["axis", "index"]
    )
    ok = (status == "ok") & np.isfinite(y)
    assert len(np.unique(y[ok])) < 200
    for ax in ("a", "b", "c"):
        assert t.loc[(ax, "spearman"), "value"] == pytest.approx(
            stats.spearmanr(df[ax][ok], y[ok])[0], abs=1e-12
        )
        assert t.loc[(ax, "pearson"), "value"] == pytest.approx(
            stats.pearsonr(df[ax][ok], y[ok])[0], abs=1e-12
        )
    assert (t["note"] == f"{int((~ok).sum())} failed variant(s) left out").all()
    const = df.assign(y=1.0)  # a metric that does not vary: no correlation (NaN), as SciPy would warn
    t = correlation.correlation_table(lambda: iter([const]), {"a": "a"}, "y")
    assert t["value"].isna().all()
