"""Sampled designs (the ``design:`` block, docs/design.md): reproducible rows, the strata of a Latin
hypercube, the moments of each distribution, variant numbering after matrix and zip, clear errors,
and reuse of unchanged variants as for a matrix."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from crashstudy.cli.main import main
from crashstudy.results.store import open_results
from crashstudy.study.design import n_rows, rows
from crashstudy.study.plan import load_study
from helpers import on_shared_pool
from models import DROP as MODEL


def _study(tmp: Path, design: dict[str, Any], matrix: dict[str, list[float]] | None = None) -> Path:
    (tmp / "model.yaml").write_text(MODEL)
    data: dict[str, Any] = {"name": "design-test", "model": "model.yaml", "design": design}
    if matrix:
        data["matrix"] = matrix
    path = tmp / "study.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.parametrize("method", ["lhs", "sobol", "halton", "random", "saltelli", "morris"])
def test_the_same_seed_gives_the_same_rows_and_another_seed_other_rows(method: str) -> None:
    dists = {"a": ("uniform", [0.0, 1.0]), "b": ("normal", [10.0, 2.0])}
    one, two, other = rows(method, 16, 7, dists), rows(method, 16, 7, dists), rows(method, 16, 8, dists)
    assert len(one["a"]) == n_rows(method, 16, 2)  # saltelli 16 (2d+2) = 96, morris 16 (d+1) = 48
    for k in dists:
        np.testing.assert_array_equal(one[k], two[k])
    assert not np.array_equal(one["a"], other["a"])


def test_latin_hypercube_puts_one_row_in_each_stratum_of_every_axis() -> None:
    """n = 50 rows over uniform [2, 7] and [-1, 1]: floor of the scaled value is a permutation of 0..49."""
    r = rows("lhs", 50, 1, {"a": ("uniform", [2.0, 7.0]), "b": ("uniform", [-1.0, 1.0])})
    for k, (lo, hi) in (("a", (2.0, 7.0)), ("b", (-1.0, 1.0))):
        strata = np.floor((r[k] - lo) / (hi - lo) * 50).astype(int)
        assert sorted(strata.tolist()) == list(range(50))


def test_each_distribution_has_its_stated_moments_and_bounds() -> None:
    """4096 scrambled Sobol' rows: sample mean and sd of a normal within 3 standard errors of the spec;
    the log of a lognormal likewise; a truncated normal stays inside its bounds and its mean is the
    closed form mu + sigma (phi(a) - phi(b)) / (Phi(b) - Phi(a)) (scipy.stats.truncnorm.mean, 3 s.e.)."""
    from scipy import stats

    n = 4096
    r = rows(
        "sobol",
        n,
        2,
        {
            "n": ("normal", [10.0, 2.0]),
            "ln": ("lognormal", [0.5, 0.25]),
            "t": ("truncnormal", [1.0, 1.0, 0.5, 3.0]),
            "u": ("uniform", [-3.0, 5.0]),
        },
    )
    se = 3.0 / np.sqrt(n)
    assert abs(r["n"].mean() - 10.0) < 2.0 * se and abs(r["n"].std() - 2.0) < 2.0 * se
    assert abs(np.log(r["ln"]).mean() - 0.5) < 0.25 * se and abs(np.log(r["ln"]).std() - 0.25) < 0.25 * se
    assert r["t"].min() >= 0.5 and r["t"].max() <= 3.0
    mean_t = stats.truncnorm.mean(-0.5, 2.0, loc=1.0, scale=1.0)
    assert abs(r["t"].mean() - mean_t) < se
    assert r["u"].min() >= -3.0 and r["u"].max() <= 5.0 and abs(r["u"].mean() - 1.0) < 8.0 * se


def test_design_rows_are_numbered_after_the_matrix_and_are_the_axis_coordinates(tmp_path: Path) -> None:
    """matrix impact_velocity [3, 5] x 8 design rows: variant = 8 * matrix index + row; the coordinates
    are the rows of :func:`rows` with the file's seed."""
    study = _study(
        tmp_path,
        {"method": "lhs", "n": 8, "seed": 4, "axes": {"nodes.body.mass": {"uniform": [80.0, 120.0]}}},
        {"impact_velocity": [3.0, 5.0]},
    )
    plan = load_study(study)
    assert plan.shape == (2, 8) and plan.n_variants == 16
    vals = plan.axis_values(0, 16)
    expected = rows("lhs", 8, 4, {"m": ("uniform", [80.0, 120.0])})["m"]
    np.testing.assert_array_equal(vals["nodes.body.mass"], np.tile(expected, 2))
    np.testing.assert_array_equal(vals["impact_velocity"], np.repeat([3.0, 5.0], 8))


def test_a_design_study_runs_each_row_as_the_model_alone_and_a_rerun_reuses_every_variant(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Peak force of each variant = v sqrt(k m) (undamped linear spring, closed form, 1e-3 relative at
    safety factor 0.9 ... measured 2e-4); the same study again computes nothing."""
    study = _study(
        tmp_path,
        {
            "method": "halton",
            "n": 12,
            "seed": 0,
            "axes": {
                "nodes.body.mass": {"uniform": [50.0, 150.0]},
                "impact_velocity": {"truncnormal": [5.0, 1.0, 3.0, 7.0]},
            },
        },
    )
    out = tmp_path / "out"
    assert main(["run", str(study), "-o", str(out), "--progress", "off"]) == 0
    s = open_results(out).summary
    closed = s["impact_velocity"] * np.sqrt(1.0e6 * s["nodes.body.mass"])
    np.testing.assert_allclose(s["peak_force.pad"], closed, rtol=1e-3)
    capsys.readouterr()
    assert main(["run", str(study), "-o", str(out), "--progress", "off"]) == 0
    assert "0 variants computed" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("design", "expected"),
    [
        ({"n": 8, "axes": {"nodes.body.mass": {"uniform": [120.0, 80.0]}}}, "needs low < high"),
        ({"n": 8, "axes": {"nodes.body.mass": {"normal": [100.0, -1.0]}}}, "standard deviation"),
        (
            {"n": 8, "axes": {"nodes.body.mass": {"uniform": [80.0, 120.0], "normal": [1.0, 1.0]}}},
            "exactly one",
        ),
        (
            {"n": 8, "method": "grid", "axes": {"nodes.body.mass": {"uniform": [80.0, 120.0]}}},
            "design.method",
        ),
        ({"n": 8, "axes": {"nodes.body.mas": {"uniform": [80.0, 120.0]}}}, "unknown axis 'nodes.body.mas'"),
        ({"n": 8, "axes": {"nodes.body.mass": {"normal": [10.0, 50.0]}}}, "makes the model invalid"),
    ],
)
def test_a_bad_design_is_exit_2_naming_its_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], design: dict[str, Any], expected: str
) -> None:
    study = _study(tmp_path, design)
    capsys.readouterr()
    assert main(["validate", str(study)]) == 2
    err = capsys.readouterr().err
    assert expected in err and f"{study}:" in err and "Traceback" not in err, err


def test_latin_hypercube_strata_are_equal_in_probability_for_other_distributions() -> None:
    """40 rows of a normal and a truncated normal: the CDF of each value (scipy.stats, the same
    distribution) falls one per stratum [k/40, (k+1)/40)."""
    from scipy import stats

    r = rows("lhs", 40, 9, {"n": ("normal", [3.0, 0.5]), "t": ("truncnormal", [300.0, 25.0, 250.0, 350.0])})
    cdf_n = stats.norm.cdf(r["n"], 3.0, 0.5)
    cdf_t = stats.truncnorm.cdf(r["t"], -2.0, 2.0, loc=300.0, scale=25.0)
    for p in (cdf_n, cdf_t):
        assert sorted(np.floor(p * 40 + 1e-9).astype(int).tolist()) == list(range(40))


def _product_indices(moments: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Exact first-order and total Sobol' indices of Y = prod X_i, X_i independent with (E X_i, E X_i^2):
    V_i = Var(X_i) prod_{j!=i} (E X_j)^2;  ST_i = 1 - (E X_i)^2 Var(prod_{j!=i} X_j) / Var(Y)."""
    m1 = np.array([m for m, _ in moments])
    m2 = np.array([q for _, q in moments])
    var_y = np.prod(m2) - np.prod(m1) ** 2
    s1 = np.array([(m2[i] - m1[i] ** 2) * np.prod(np.delete(m1, i)) ** 2 for i in range(len(m1))]) / var_y
    rest = np.array([np.prod(np.delete(m2, i)) - np.prod(np.delete(m1, i)) ** 2 for i in range(len(m1))])
    return s1, 1.0 - m1**2 * rest / var_y


def test_sobol_indices_of_a_crash_run_match_the_closed_form_of_its_peak_force(tmp_path: Path) -> None:
    """Peak force of a mass on a linear spring = v sqrt(k m) (closed form), a product of independent
    factors v, sqrt(k), sqrt(m) with v, k, m uniform: its Sobol' indices are exact (moments of a uniform:
    E sqrt(x) = 2/3 (b^1.5 - a^1.5) / (b - a), E x = (a + b) / 2). The crash study (saltelli design, 128
    base points = 1024 variants) gives indices within max(3 confidence half-widths, 0.03) of them."""
    from crashstudy.analysis.sensitivity import indices

    bounds = {
        "impact_velocity": [3.0, 7.0],
        "springs.pad.material.stiffness": [5.0e5, 2.0e6],
        "nodes.body.mass": [50.0, 150.0],
    }
    (va, vb), (ka, kb), (ma, mb) = bounds.values()
    sq = lambda a, b: (2.0 / 3.0 * (b**1.5 - a**1.5) / (b - a), (a + b) / 2.0)  # noqa: E731 - E sqrt(x), E x
    s1, st = _product_indices(
        [((va + vb) / 2.0, (va * va + va * vb + vb * vb) / 3.0), sq(ka, kb), sq(ma, mb)]
    )
    study = _study(
        tmp_path,
        {"method": "saltelli", "n": 128, "seed": 3, "axes": {p: {"uniform": b} for p, b in bounds.items()}},
    )
    out = tmp_path / "out"
    assert main(["run", str(study), "-o", str(out), "--progress", "off"]) == 0
    res = open_results(out)
    t = indices(res.summary, dict(res.dataset.attrs), "peak_force.pad", "sobol").set_index(["axis", "index"])
    res.close()
    for k, path in enumerate(bounds):
        for i, exact in (("S1", s1[k]), ("ST", st[k])):
            got = t.loc[(path, i)]
            assert abs(got["value"] - exact) <= max(3.0 * got["confidence"], 0.03), (
                path,
                i,
                got["value"],
                exact,
            )


def test_a_design_study_on_two_worker_processes_gives_the_in_process_numbers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The design's rows are a dimension like a zip group, so the backends need nothing new: --jobs 2
    (process pool) writes the same summary, bit for bit, as one process. The pool is the test process's
    shared one (helpers.shared_process_pool, also test_backends.TestProcessPool's): 2 spawned workers that
    unpickle the design's plan, started once."""
    on_shared_pool(monkeypatch)
    study = _study(
        tmp_path,
        {"method": "sobol", "n": 32, "seed": 6, "axes": {"nodes.body.mass": {"lognormal": [4.6, 0.2]}}},
        {"impact_velocity": [3.0, 5.0]},
    )
    one, two = tmp_path / "one", tmp_path / "two"
    assert main(["run", str(study), "-o", str(one), "--progress", "off"]) == 0
    assert main(["run", str(study), "-o", str(two), "--jobs", "2", "--progress", "off"]) == 0
    a, b = open_results(one).summary, open_results(two).summary
    assert len(a) == 64
    pd.testing.assert_frame_equal(a, b, check_exact=True)


@pytest.mark.parametrize(("n", "d", "seed"), [(1, 1, 0), (16, 2, 3), (37, 3, 11), (64, 5, 0)])
def test_saltelli_rows_are_salibs_own(n: int, d: int, seed: int) -> None:
    """The vectorised Saltelli arrangement (issue 24 item 9: SALib's Python loop took 34 s at n = 10^6)
    gives exactly SALib's rows, in its order (the second implementation is SALib itself)."""
    import warnings

    from SALib.sample import sobol

    from crashstudy.study.design import salib_problem, saltelli_rows

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        expected = np.asarray(sobol.sample(salib_problem(d), n, calc_second_order=True, seed=seed))
    assert np.array_equal(saltelli_rows(n, seed, d), expected)


@pytest.mark.parametrize(("n", "d", "seed"), [(1, 1, 0), (16, 2, 3), (37, 3, 11), (64, 6, 0)])
def test_morris_rows_are_salibs_own(n: int, d: int, seed: int) -> None:
    """The array-built Morris trajectories (issue 24 item 9: SALib's per-trajectory matrix products took
    20 s at n = 10^5) are exactly SALib's rows, in its order (the second implementation is SALib itself)."""
    from SALib.sample import morris

    from crashstudy.study.design import morris_rows, salib_problem

    expected = np.asarray(morris.sample(salib_problem(d), n, num_levels=4, seed=seed))
    assert np.array_equal(morris_rows(n, seed, d), expected)
