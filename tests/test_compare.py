"""Tests of ``crashstudy compare``: variants matched by parameters, tolerances, JUnit XML, exit codes.

Every result here is a real run of a tiny study: a 1-D mass hitting a ``crush`` spring whose loading
curve ``c1`` rises to a flat plateau of 50 kN. The peak force of a crush past the kink is the plateau
force exactly, so scaling the curve's forces by 1 % moves ``peak_force`` and ``peak_deceleration`` by
1 % (an analytic expectation), whatever the mass and the impact speed.
"""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.analysis.compare import compare
from crashstudy.errors import InputError
from crashstudy.results.store import FINAL, PARTIAL, open_results
from crashstudy.run.runner import run_study

PLATEAU = 50_000.0  # N
MASSES = [800.0, 1000.0]  # kg
SPEEDS = [3.0, 5.0, 7.0]  # m/s; crush = m v^2 / (2 F) = 0.07 .. 0.49 m, all past the kink at 0.01 m


def model(scale: float = 1.0) -> dict:
    f = PLATEAU * scale
    return {
        "name": "crush-block",
        "units": "SI",
        "curves": {"c1": {"x": [-10.0, -0.01, 0.0], "y": [-f, -f, 0.0]}},
        "nodes": {"ground": {"position": [0.0], "fixed": True}, "body": {"position": [1.0], "mass": 1000.0}},
        "springs": {
            "s1": {
                "nodes": ["ground", "body"],
                "material": {"type": "crush", "loading": "c1", "unloading_stiffness": 1.0e6},
            }
        },
        "initial_velocity": {"body": [-5.0]},
        "end_time": 0.2,  # s; the body stops after at most 0.14 s and springs back
        "output": {"histories": "none"},
    }


def run(
    folder: Path,
    scale: float = 1.0,
    matrix: dict | None = None,
    regression: dict | None = None,
    set_: dict | None = None,
) -> Path:
    """Write model + study into ``folder`` and run it into ``folder/out``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.yaml").write_text(yaml.safe_dump(model(scale), sort_keys=False))
    study: dict = {
        "name": "crush-matrix",
        "model": "model.yaml",
        "matrix": matrix or {"nodes.body.mass": MASSES, "impact_velocity": SPEEDS},
    }
    if set_:
        study["set"] = set_
    if regression:
        study["regression"] = regression
    (folder / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    run_study(folder / "study.yaml", folder / "out", force=True)
    return folder / "out"


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("compare")
    return {
        "baseline": run(root / "baseline"),
        "same": run(root / "same"),
        "scaled": run(root / "scaled", scale=1.01),
        "reordered": run(
            root / "reordered", matrix={"impact_velocity": SPEEDS[::-1], "nodes.body.mass": MASSES[::-1]}
        ),
        "scaled_loose": run(root / "scaled_loose", scale=1.01, regression={"peak_force": {"rtol": 0.05}}),
    }


# --- matching and tolerances -----------------------------------------------------------------


def test_identical_rerun_has_no_failure_and_no_change_at_all(runs: dict[str, Path]) -> None:
    cmp = compare(open_results(runs["same"]), open_results(runs["baseline"]))
    assert cmp.failed == 0
    assert len(cmp.matched) == 6 and cmp.missing.empty and cmp.extra.empty and cmp.status.empty
    assert float(cmp.frame["abs_diff"].max()) == 0.0  # the kernel is deterministic: bit-identical
    assert cmp.table() == "no metric value changed"
    assert cmp.verdict().startswith("OK: 6 variants")


def test_bookkeeping_columns_are_not_compared_and_t_end_is(runs: dict[str, Path]) -> None:
    cmp = compare(runs["same"], runs["baseline"])
    metrics = set(cmp.frame["metric"])
    assert {"peak_force.s1", "max_crush.s1", "energy_error", "t_end"} <= metrics
    assert not metrics & {"variant", "dt", "dt_crit", "nodes.body.mass", "impact_velocity", "status"}


def test_curve_scaled_by_one_percent_moves_peak_force_by_one_percent(runs: dict[str, Path]) -> None:
    cmp = compare(runs["scaled"], runs["baseline"])
    assert cmp.failed > 0
    for metric in ("peak_force.s1", "peak_deceleration.body", "peak_deceleration_g.body"):
        rows = cmp.frame[cmp.frame["metric"] == metric]
        assert len(rows) == 6 and not rows["passed"].any()
        np.testing.assert_allclose(rows["rel_diff"], 0.01, atol=1e-3)
    fails = cmp.failing_columns()
    assert fails["peak_force.s1"] == 6
    per_metric = cmp.by_metric().set_index("metric")
    assert per_metric.loc["peak_force.s1", "failed"] == 6
    assert per_metric.loc["peak_force.s1", "max_rel_diff"] == pytest.approx(0.01, abs=1e-3)
    # energy: the same kinetic energy is absorbed over a 1/1.01 shorter crush
    crush = cmp.frame[cmp.frame["metric"] == "max_crush.s1"]
    np.testing.assert_allclose(crush["rel_diff"], 1 / 1.01 - 1, atol=2e-3)
    # a fixed node does not move either way, and the table leads with what moved most
    assert "peak_deceleration.ground" not in fails
    table = cmp.table(n=5)
    assert "FAIL" in table and len(table.splitlines()) == 2 + 5
    top = cmp.top(3)
    assert list(top["score"]) == sorted(top["score"], reverse=True)


def test_variants_listed_in_another_order_match_by_parameters(runs: dict[str, Path]) -> None:
    base = open_results(runs["baseline"]).summary
    reordered = open_results(runs["reordered"]).summary
    assert list(reordered["impact_velocity"])[:2] == [7.0, 7.0]  # really in another order
    cmp = compare(runs["reordered"], runs["baseline"])
    assert cmp.failed == 0 and len(cmp.matched) == 6
    # and the pairs are right: each matched pair has the same parameters on both sides
    for _, r in cmp.matched.iterrows():
        b = base[base["variant"] == r["baseline_variant"]].iloc[0]
        n = reordered[reordered["variant"] == r["variant"]].iloc[0]
        assert (b["nodes.body.mass"], b["impact_velocity"]) == (n["nodes.body.mass"], n["impact_velocity"])
    assert (cmp.matched["variant"] != cmp.matched["baseline_variant"]).any()


def test_regression_block_loosens_only_the_metric_it_names(runs: dict[str, Path]) -> None:
    cmp = compare(runs["scaled_loose"], runs["baseline"])
    pf = cmp.frame[cmp.frame["metric"] == "peak_force.s1"]
    assert pf["passed"].all() and (pf["rtol"] == 0.05).all() and (pf["atol"] == 0.0).all()
    fails = cmp.failing_columns()
    assert "peak_force.s1" not in fails
    assert fails["peak_deceleration.body"] == 6  # not named: default rtol 1e-6
    assert cmp.failed > 0


def test_full_column_key_wins_over_the_metric_name(runs: dict[str, Path]) -> None:
    tol = {"peak_force": {"rtol": 0.05}, "peak_force.s1": {"rtol": 1e-3}}
    cmp = compare(runs["scaled"], runs["baseline"], tolerances=tol)
    assert cmp.failing_columns()["peak_force.s1"] == 6
    cmp = compare(runs["scaled"], runs["baseline"], tolerances={"peak_force.s1": {"atol": 600.0}})
    assert "peak_force.s1" not in cmp.failing_columns()  # |50500 - 50000| = 500 N <= 600 N


def test_default_rtol_from_the_caller_applies_to_unnamed_metrics(runs: dict[str, Path]) -> None:
    cmp = compare(runs["scaled"], runs["baseline"], rtol=0.02)
    # every metric moved by about 1 % except the final energies (2 %), the crush near the kink and the
    # small stretch of the rebound (max_elongation)
    assert set(cmp.failing_columns()) <= {
        "final_kinetic_energy",
        "final_internal_energy",
        "absorbed_energy.s1",
        "max_elongation.s1",
    }
    assert "peak_force.s1" not in cmp.failing_columns()


def test_unknown_regression_key_is_invalid_input_with_its_line(tmp_path: Path, runs: dict[str, Path]) -> None:
    new = run(tmp_path / "typo", regression={"peak_forces": {"rtol": 0.05}})
    with pytest.raises(InputError) as info:
        compare(new, runs["baseline"])
    (p,) = info.value.problems
    line = 1 + (new.parent / "study.yaml").read_text().splitlines().index("  peak_forces:")
    assert p.field == "regression.peak_forces" and p.line == line
    assert p.file.endswith("study.yaml") and "did you mean peak_force" in p.message


def test_variant_missing_from_new_fails_and_extra_variant_is_only_noted(
    tmp_path: Path, runs: dict[str, Path]
) -> None:
    fewer = run(tmp_path / "fewer", matrix={"nodes.body.mass": MASSES, "impact_velocity": [3.0, 5.0]})
    cmp = compare(fewer, runs["baseline"])
    assert len(cmp.missing) == 2 and set(cmp.missing["impact_velocity"]) == {7.0}
    assert cmp.failed == 2 and cmp.failed_values == 0
    # the other way round: the new run has two more variants than its baseline
    cmp = compare(runs["baseline"], fewer)
    assert len(cmp.extra) == 2 and cmp.failed == 0 and "2 new variants" in cmp.verdict()


def test_ok_to_failed_status_change_is_a_failure(tmp_path: Path, runs: dict[str, Path]) -> None:
    # a fixed step between the critical steps of the two masses: 2 / sqrt(2 k / m) with k = 5e6 N/m
    # is 0.0179 s at 800 kg and 0.0200 s at 1000 kg, so the 800 kg variants are refused
    new = run(tmp_path / "coarse", set_={"time_step": {"dt": 0.019}})
    cmp = compare(new, runs["baseline"])
    assert cmp.status_failures == 3
    assert set(cmp.status["nodes.body.mass"]) == {800.0}
    assert (cmp.status["old"] == "ok").all() and (cmp.status["new"] == "failed").all()
    assert cmp.status["failure_reason"].str.contains("dt_crit").all()
    # their metrics are NaN now: NaN against a number fails, with an infinite score
    pf = cmp.frame[(cmp.frame["metric"] == "peak_force.s1") & (cmp.frame["nodes.body.mass"] == 800.0)]
    assert not pf["passed"].any() and np.isinf(pf["score"]).all()
    # and a result compared with itself, failed variants included, is equal (NaN == NaN)
    assert compare(new, new).failed == 0


# --- JUnit XML and the command line ----------------------------------------------------------


def junit_cases(path: Path) -> tuple[ET.Element, dict[str, ET.Element]]:
    root = ET.parse(path).getroot()
    suites = root.findall("testsuite") if root.tag == "testsuites" else [root]
    assert len(suites) == 1 and suites[0].get("name") == "crashstudy compare"
    return suites[0], {tc.get("name", ""): tc for tc in suites[0].findall("testcase")}


def test_junit_report_has_one_testcase_per_metric_and_failures_listing_variants(
    tmp_path: Path, runs: dict[str, Path]
) -> None:
    cmp = compare(runs["scaled"], runs["baseline"])
    report = tmp_path / "reports" / "compare.xml"
    cmp.to_junit(report)
    suite, cases = junit_cases(report)
    n_metrics = len(cmp.columns)
    assert len(cases) == n_metrics + 3  # + status, missing variants, variants only in new
    assert int(suite.get("tests", -1)) == len(cases)
    failed = {name for name, tc in cases.items() if tc.find("failure") is not None}
    assert failed == set(cmp.failing_columns())
    assert int(suite.get("failures", -1)) == len(failed)
    f = cases["peak_force.s1"].find("failure")
    assert f is not None and f.get("message", "").startswith("6 of 6 variants moved past tolerance")
    assert len((f.text or "").splitlines()) == 6
    assert "old 50000 new 50500" in (f.text or "")
    assert cases["peak_deceleration.ground"].find("failure") is None


def test_junit_report_of_a_missing_variant_group(tmp_path: Path, runs: dict[str, Path]) -> None:
    fewer = run(tmp_path / "fewer", matrix={"nodes.body.mass": MASSES, "impact_velocity": [3.0, 5.0]})
    compare(fewer, runs["baseline"]).to_junit(tmp_path / "r.xml")
    suite, cases = junit_cases(tmp_path / "r.xml")
    assert int(suite.get("failures", -1)) == 1
    f = cases["variants missing from the new result"].find("failure")
    assert f is not None and len((f.text or "").splitlines()) == 2 and "impact_velocity=7" in (f.text or "")


def test_cli_exit_codes_and_junit_file(tmp_path: Path, runs: dict[str, Path], cli) -> None:
    ok = cli("compare", str(runs["same"]), str(runs["baseline"]), "--junit", str(tmp_path / "ok.xml"))
    assert ok.returncode == 0, ok.stderr
    assert "OK: 6 variants" in ok.stdout
    suite, _ = junit_cases(tmp_path / "ok.xml")
    assert suite.get("failures") == "0"

    bad = cli("compare", str(runs["scaled"]), str(runs["baseline"]), "--junit", str(tmp_path / "bad.xml"))
    assert bad.returncode == 1, bad.stderr
    lines = bad.stdout.splitlines()
    assert lines[-2].startswith("FAILED:") and "what moved most" in bad.stdout
    suite, cases = junit_cases(tmp_path / "bad.xml")
    assert cases["peak_force.s1"].find("failure") is not None

    loose = cli("compare", str(runs["scaled"]), str(runs["baseline"]), "--rtol", "0.05")
    assert loose.returncode == 0, loose.stdout


def test_cli_refuses_folders_without_results(tmp_path: Path, runs: dict[str, Path], cli) -> None:
    gone = cli("compare", str(tmp_path / "nowhere"), str(runs["baseline"]))
    assert (
        gone.returncode == 2 and "result folder not found" in gone.stderr and "Traceback" not in gone.stderr
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    res = cli("compare", str(runs["baseline"]), str(empty))
    assert res.returncode == 2 and f"no {FINAL} here" in res.stderr and "baseline" in res.stderr
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    shutil.copy(runs["baseline"] / FINAL, unfinished / PARTIAL)
    res = cli("compare", str(unfinished), str(runs["baseline"]))
    assert res.returncode == 2 and "--resume" in res.stderr
