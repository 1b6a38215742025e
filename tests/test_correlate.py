"""``crashstudy correlate`` end to end, ``calibrate: {objective: iso18571}``, and their bad input (exit 2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from conftest import LINEAR_SPRING, noisy_spring_force
from crashstudy.analysis.iso18571 import A0, B0, EPS_P
from crashstudy.cli.main import main

STIFFNESS = [1.5e4, 2.0e4, 2.5e4, 3.0e4]


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four stiffnesses of the linear spring model, histories kept (every 0.1 ms)."""
    tmp = tmp_path_factory.mktemp("correlate")
    (tmp / "model.yaml").write_text(LINEAR_SPRING)
    (tmp / "study.yaml").write_text(
        yaml.safe_dump(
            {"name": "corr", "model": "model.yaml", "matrix": {"springs.s.material.stiffness": STIFFNESS}}
        )
    )
    assert main(["run", str(tmp / "study.yaml"), "-o", str(tmp / "out")]) == 0
    return tmp


def _history(folder: Path, variant: int) -> tuple[np.ndarray, np.ndarray]:
    from crashstudy import open_results

    res = open_results(folder)
    try:
        ds = res.dataset
        return np.asarray(ds["time"].values), np.asarray(ds["spring_force"].sel(spring="s").values[variant])
    finally:
        res.close()


def test_a_test_curve_made_from_one_variant_rates_it_1(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    t, f = _history(study / "out", 1)
    pd.DataFrame({"time": t, "force": f}).to_csv(study / "test.csv", index=False)
    assert (
        main(
            [
                "correlate",
                str(study / "out"),
                "--test",
                str(study / "test.csv"),
                "--channel",
                "force",
                "--item",
                "s",
                "--quantity",
                "force",
            ]
        )
        == 0
    )
    table = pd.read_csv(study / "out" / "correlation.csv")
    assert list(table.columns) == [
        "variant",
        "springs.s.material.stiffness",
        "R",
        "Z",
        "EP",
        "EM",
        "ES",
        "grade",
    ]
    row = table.set_index("variant").loc[1]
    for score in ("R", "Z", "EP", "EM", "ES"):
        assert row[score] == pytest.approx(1.0, abs=1e-12)
    assert row["grade"] == "excellent"
    assert (table.drop(index=1)["R"] < 0.8).all()  # 25 % stiffer or softer: another frequency
    out = capsys.readouterr().out
    assert out.splitlines()[1].split()[0] == "variant" and out.splitlines()[2].split()[0] == "1"  # best first


def test_a_shifted_test_curve_scores_its_phase_by_the_closed_form(study: Path) -> None:
    """The variant-1 curve 3 ms later: common interval 3 .. 100 ms (971 samples at 10 kHz), the best
    shift is 30 samples, EP = (0.2 N - 30) / (0.2 N); the overlapping parts are equal (EM = ES = 1), and Z
    is the corridor score of the unshifted difference, computed here directly."""
    t, f = _history(study / "out", 1)
    pd.DataFrame({"time": t + 0.003, "value": f}).to_csv(study / "late.csv", index=False)
    assert (
        main(
            [
                "correlate",
                str(study / "out"),
                "--test",
                str(study / "late.csv"),
                "--item",
                "s",
                "--quantity",
                "force",
                "--window",
                "0.0",
                "0.1",
            ]
        )
        == 0
    )
    row = pd.read_csv(study / "out" / "correlation.csv").set_index("variant").loc[1]
    n = 971
    assert row["EP"] == pytest.approx((EPS_P * n - 30) / (EPS_P * n), abs=1e-9)
    assert row["EM"] == pytest.approx(1.0, abs=1e-6) and row["ES"] == pytest.approx(1.0, abs=1e-6)
    grid = 0.003 + 1e-4 * np.arange(n)
    test, model = np.interp(grid, t + 0.003, f), np.interp(grid, t, f)
    peak = np.abs(test).max()
    d = np.abs(model - test)
    z = np.where(
        d < A0 * peak, 1.0, np.where(d > B0 * peak, 0.0, ((B0 * peak - d) / ((B0 - A0) * peak)) ** 2)
    ).mean()
    assert row["Z"] == pytest.approx(z, abs=1e-9)
    assert row["R"] == pytest.approx(0.4 * z + 0.2 * row["EP"] + 0.2 + 0.2, abs=1e-6)


def test_cfc_filters_both_curves_before_rating(study: Path) -> None:
    """Variant 1's curve plus a 2 kHz ripple of 10 % of its peak: the slope score suffers unfiltered;
    CFC 60 (-3 dB at 100 Hz, < -60 dB at 2 kHz) removes the ripple, and the same filter on both curves
    leaves variant 1 at R > 0.999."""
    t, f = _history(study / "out", 1)
    rippled = f + 0.1 * np.abs(f).max() * np.sin(2 * np.pi * 2000.0 * t)
    pd.DataFrame({"time": t, "value": rippled}).to_csv(study / "ripple.csv", index=False)
    rows = {}
    for cfc in ([], ["--cfc", "60"]):
        assert (
            main(
                [
                    "correlate",
                    str(study / "out"),
                    "--test",
                    str(study / "ripple.csv"),
                    "--item",
                    "s",
                    "--quantity",
                    "force",
                    *cfc,
                ]
            )
            == 0
        )
        rows[bool(cfc)] = pd.read_csv(study / "out" / "correlation.csv").set_index("variant").loc[1]
    assert rows[False]["ES"] < 0.7 and rows[False]["R"] < 0.9  # measured 0.59, 0.86
    assert rows[True]["R"] > 0.999


@pytest.mark.parametrize(
    "extra, field, words",
    [
        (["--test", "missing.csv", "--item", "s", "--quantity", "force"], "--test", "no such file"),
        (
            ["--test", "test.csv", "--item", "s", "--quantity", "force"],
            "--test",
            "line 1: expected the header 'time,value'",
        ),
        (
            ["--test", "test.csv", "--channel", "force", "--item", "nope", "--quantity", "force"],
            "--item",
            "'nope' is none of s",
        ),
        (
            [
                "--test",
                "test.csv",
                "--channel",
                "force",
                "--item",
                "body",
                "--quantity",
                "velocity",
                "--direction",
                "y",
            ],
            "--direction",
            "moves along x only",
        ),
        (
            [
                "--test",
                "test.csv",
                "--channel",
                "force",
                "--item",
                "s",
                "--quantity",
                "force",
                "--window",
                "0.2",
                "0.3",
            ],
            "--window",
            "at least 20 are needed",
        ),
        (
            [
                "--test",
                "test.csv",
                "--channel",
                "force",
                "--item",
                "s",
                "--quantity",
                "force",
                "--window",
                "0.05",
                "0.01",
            ],
            "--window",
            "expected T0 < T1",
        ),
        (
            ["--test", "uneven.csv", "--item", "s", "--quantity", "force", "--cfc", "60"],
            "--cfc",
            "constant step",
        ),
        (
            ["--test", "flat.csv", "--item", "s", "--quantity", "force"],
            "--test",
            "the test curve is constant",
        ),
    ],
)
def test_bad_input_is_exit_2_naming_file_and_field(
    study: Path,
    capsys: pytest.CaptureFixture[str],
    extra: list[str],
    field: str,
    words: str,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if not (study / "test.csv").exists():
        t, f = _history(study / "out", 1)
        pd.DataFrame({"time": t, "force": f}).to_csv(study / "test.csv", index=False)
    pd.DataFrame({"time": [0.0, 0.001, 0.003, 0.004], "value": [0.0, 1.0, 2.0, 3.0]}).to_csv(
        study / "uneven.csv", index=False
    )
    pd.DataFrame({"time": [0.0, 0.05, 0.1], "value": [2.0, 2.0, 2.0]}).to_csv(study / "flat.csv", index=False)
    monkeypatch.chdir(study)
    assert main(["correlate", "out", *extra]) == 2
    err = capsys.readouterr().err
    assert f": {field}: " in err and words in err and "Traceback" not in err


def test_a_study_without_histories_is_exit_2_saying_how_to_keep_them(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (study / "bare.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "bare",
                "model": "model.yaml",
                "set": {"output": {"histories": "none"}},
                "matrix": {"springs.s.material.stiffness": STIFFNESS[:2]},
            }
        )
    )
    assert main(["run", str(study / "bare.yaml"), "-o", str(study / "bare")]) == 0
    capsys.readouterr()
    t, f = _history(study / "out", 1)
    pd.DataFrame({"time": t, "value": f}).to_csv(study / "v.csv", index=False)
    assert (
        main(
            [
                "correlate",
                str(study / "bare"),
                "--test",
                str(study / "v.csv"),
                "--item",
                "s",
                "--quantity",
                "force",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert str(study / "bare") in err and "no spring_force histories" in err and "histories: all" in err


def test_calibrate_by_iso18571_recovers_the_stiffness_of_an_independent_solution(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Spring force of k = 3.1e4 N/m on the 2 kg body at 1 m/s from scipy's RK45 (no noise): maximising R
    over k in [1e4, 5e4] gives k back within 0.5 % and R > 0.99 (excellent); calibrated.yaml reports R
    and its sub-scores. The runs take the generic kernel (bitwise the reference: test_kernel_twins); the
    automatic choice put each of the ~20 small batches on the NumPy reference (1.7 s in all)."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "generic")
    k = 3.1e4
    t, force = noisy_spring_force(k, 2.0, noise=0.0)
    pd.DataFrame({"time": t, "value": force}).to_csv(tmp_path / "data.csv", index=False)
    (tmp_path / "model.yaml").write_text(LINEAR_SPRING)
    (tmp_path / "cal.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "cal",
                "model": "model.yaml",
                "calibrate": {
                    "data": "data.csv",
                    "channel": {"quantity": "spring_force", "spring": "s"},
                    "variables": {"springs.s.material.stiffness": [1.0e4, 5.0e4]},
                    "objective": "iso18571",
                    "budget": 300,
                },
            }
        )
    )
    assert main(["calibrate", str(tmp_path / "cal.yaml"), "-o", str(tmp_path / "out")]) == 0
    cal = yaml.safe_load((tmp_path / "out" / "calibrated.yaml").read_text())
    assert cal["variables"]["springs.s.material.stiffness"] == pytest.approx(k, rel=0.005)
    assert (
        cal["objective"] == "iso18571"
        and cal["iso18571"]["R"] > 0.99
        and cal["iso18571"]["grade"] == "excellent"
    )
    assert set(cal["iso18571"]) >= {"R", "Z", "EP", "EM", "ES"}


def test_validate_checks_the_objective(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "model.yaml").write_text(LINEAR_SPRING)
    (tmp_path / "cal.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "cal",
                "model": "model.yaml",
                "calibrate": {
                    "data": "data.csv",
                    "channel": {"quantity": "spring_force", "spring": "s"},
                    "variables": {"springs.s.material.stiffness": [1.0e4, 5.0e4]},
                    "objective": "r2",
                },
            },
            sort_keys=False,
        )
    )
    assert main(["validate", str(tmp_path / "cal.yaml")]) == 2
    err = capsys.readouterr().err
    assert "calibrate.objective" in err and "'rms' or 'iso18571'" in err


def test_new_results_remove_an_old_correlation(tmp_path: Path) -> None:
    from crashstudy.results.outdir import remove_derived

    (tmp_path / "correlation.csv").write_text("variant,R\n0,1.0\n")
    (tmp_path / "notes.csv").write_text("mine\n")
    assert remove_derived(tmp_path) == [tmp_path / "correlation.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.csv"]


def test_an_isomme_test_of_one_variant_rates_it_1(study: Path) -> None:
    """Variant 2 exported as an ISO-MME test (SI, force in N) and read back as the test curve by its channel
    code: the same curve to the 12 digits written, so every score is 1 within 1e-9; a code that matches
    no channel is exit 2 naming --test."""
    assert main(["export", str(study / "out"), "--isomme", str(study / "iso"), "--variants", "2"]) == 0
    assert (
        main(
            [
                "correlate",
                str(study / "out"),
                "--test",
                str(study / "iso" / "corr-2"),
                "--channel",
                "????????????FO0?",
                "--item",
                "s",
                "--quantity",
                "force",
            ]
        )
        == 0
    )
    row = pd.read_csv(study / "out" / "correlation.csv").set_index("variant").loc[2]
    for score in ("R", "Z", "EP", "EM", "ES"):
        assert row[score] == pytest.approx(1.0, abs=1e-9)
    assert (
        main(
            [
                "correlate",
                str(study / "out"),
                "--test",
                str(study / "iso" / "corr-2"),
                "--channel",
                "????????????XX??",
                "--item",
                "s",
                "--quantity",
                "force",
            ]
        )
        == 2
    )
