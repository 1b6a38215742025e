"""The ``metrics:`` block through the whole pipeline (model file -> per-step record -> criteria ->
results) against closed forms: the criteria of a half-sine pulse in 1-D and 2-D (the default direction),
and in the summary, a study sweep, ``compare``, ``summary --sort`` and the plots.

The truth, a half-sine pulse imposed exactly with prescribed acceleration whose criteria have closed forms,
is described in half_sine_sled.py."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from crashstudy.cli.main import main
from crashstudy.results.store import open_results
from half_sine_sled import A_G, T_PULSE, G, pulse_model

X_STAR = 1.0528  # root of tan x = 5 x / 3 (checked below)


def hic_closed_form(a_g: float, T: float, window: float) -> tuple[float, float, float]:
    """HIC, t1, t2 [s] of the half-sine ``a_g sin(pi t / T)`` [g] with windows up to ``window`` [s]."""
    x = min(X_STAR, math.pi * window / (2 * T))
    L = 2 * T * x / math.pi
    hic = L**-1.5 * (2 * a_g * T / math.pi) ** 2.5 * math.sin(x) ** 2.5
    return hic, T / 2 - L / 2, T / 2 + L / 2


def test_closed_form_root_is_right() -> None:
    assert math.tan(X_STAR) == pytest.approx(5 * X_STAR / 3, rel=1e-3)


@pytest.mark.parametrize("units", ["SI", "mm-ms-kg-kN"])
def test_half_sine_pulse_gives_closed_form_hic_peak_g_and_delta_v(
    units: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "pulse.yaml"
    model.write_text(pulse_model(units))
    assert main(["simulate", str(model), "-o", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    ds = open_results(tmp_path / "out").dataset.sel(variant=0, node="sled")
    t_unit = 1e-3 if units == "mm-ms-kg-kN" else 1.0  # model time unit in s (mm/ms = m/s)
    assert float(ds["peak_g"]) == pytest.approx(A_G, rel=1e-3)
    assert float(ds["delta_v"]) == pytest.approx(2 * A_G * G * T_PULSE / math.pi, rel=1e-3)
    for name, window in (("hic15", 0.015), ("hic36", 0.036)):
        hic, t1, t2 = hic_closed_form(A_G, T_PULSE, window)
        assert float(ds[name]) == pytest.approx(hic, rel=5e-3), name
        # the optimum is flat in t1, t2: a few steps of 1e-5 s
        assert float(ds[f"{name}_t1"]) * t_unit == pytest.approx(t1, abs=5e-5)
        assert float(ds[f"{name}_t2"]) * t_unit == pytest.approx(t2, abs=5e-5)
        assert ds[name].attrs["standard"].startswith("FMVSS 208")
    assert ds["peak_g"].attrs["units"] == "g" and "J211" in ds["peak_g"].attrs["standard"]
    assert ds["delta_v"].attrs["units"] == ("mm/ms" if units == "mm-ms-kg-kN" else "m/s")
    assert ds["hic15_t1"].attrs["units"] == ("ms" if units == "mm-ms-kg-kN" else "s")


def test_summary_columns_are_the_criteria_of_the_asking_nodes_and_equal_the_dataset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    metrics = (
        "  - {node: sled, cfc: 1000, criteria: [peak_g, hic15]}\n"
        "  - {node: other, cfc: 60, criteria: [delta_v]}"
    )
    model = tmp_path / "pulse.yaml"
    model.write_text(pulse_model(metrics=metrics))
    assert main(["simulate", str(model), "-o", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    res = open_results(tmp_path / "out")
    df, ds = res.summary, res.dataset
    wanted = {"peak_g.sled", "hic15.sled", "hic15_t1.sled", "hic15_t2.sled", "delta_v.other"}
    crit_cols = {
        c
        for c in df.columns
        if c.split(".")[0]
        in ("peak_g", "hic15", "hic15_t1", "hic15_t2", "delta_v", "hic36", "olc", "dri", "clip3ms")
    }
    assert crit_cols == wanted
    for col in wanted:
        name, node = col.split(".")
        assert df[col].to_numpy() == pytest.approx(ds[name].sel(node=node).to_numpy(), rel=0, abs=0)
    # NaN where a node does not ask for a criterion
    assert np.isnan(ds["peak_g"].sel(node="other")).all() and np.isnan(ds["delta_v"].sel(node="sled")).all()
    # "other" moves freely at 10 m/s: no change of velocity
    assert float(ds["delta_v"].sel(node="other", variant=0)) == pytest.approx(0.0, abs=1e-12)
    assert (df["criteria_note"] == "").all()
    # the filtered pulse history (g) peaks at peak_g, sampled every 1/1000 of end_time (30 us)
    filt = ds["filtered_acceleration"].sel(node="sled", variant=0)
    assert filt.attrs["units"] == "g"
    assert float(filt.max()) == pytest.approx(float(ds["peak_g"].sel(node="sled", variant=0)), rel=1e-3)
    assert np.isnan(ds["filtered_acceleration"].sel(node="base")).all()
    csv = __import__("pandas").read_csv(tmp_path / "out" / "summary.csv")
    assert csv["hic15.sled"].to_numpy() == pytest.approx(df["hic15.sled"].to_numpy(), rel=1e-15)


SCALES = [0.6, 0.8, 1.0]  # axis curves.pulse.scale: the pulse amplitude as a fraction of A_G


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A study over the pulse amplitude, run twice: "baseline", and "bigger" with every pulse 1% larger
    and a regression: block that lets hic15 move 5% (hic36 and peak_g keep the default 1e-6)."""
    from crashstudy.run.runner import run_study

    root = tmp_path_factory.mktemp("sweeps")
    out = {}
    for name, factor, regression in (
        ("baseline", 1.0, ""),
        ("bigger", 1.01, "regression:\n  hic15: {rtol: 0.05}\n"),
    ):
        model = pulse_model(
            metrics="  - {node: sled, cfc: 1000, criteria: [peak_g, hic15, hic36]}", scale_a=factor
        )
        (root / f"{name}.yaml").write_text(model)
        values = ", ".join(f"{s:g}" for s in SCALES)
        (root / f"{name}-study.yaml").write_text(
            f"name: sweep\nmodel: {name}.yaml\nmatrix:\n  curves.pulse.scale: [{values}]\n{regression}"
        )
        run_study(root / f"{name}-study.yaml", root / name)
        out[name] = root / name
    return out


def test_study_sweep_criteria_follow_the_closed_form_over_the_axis(sweeps: dict[str, Path]) -> None:
    df = open_results(sweeps["baseline"]).summary
    for k, s in enumerate(SCALES):
        assert df["peak_g.sled"][k] == pytest.approx(s * A_G, rel=1e-3)
        assert df["hic15.sled"][k] == pytest.approx(hic_closed_form(s * A_G, T_PULSE, 0.015)[0], rel=5e-3)


def test_compare_flags_a_criterion_that_moved_and_the_regression_block_tolerates_it(
    sweeps: dict[str, Path],
) -> None:
    from crashstudy.analysis.compare import compare

    cmp = compare(sweeps["bigger"], sweeps["baseline"])
    failing = cmp.failing_columns()
    # HIC grows as the amplitude to the power 2.5: 1.01^2.5 = +2.52%, past the default 1e-6 ...
    assert failing.get("hic36.sled") == len(SCALES) and failing.get("peak_g.sled") == len(SCALES)
    # ... but within the study's regression: block for hic15 (rtol 5%)
    assert "hic15.sled" not in failing
    rows = cmp.frame
    moved = rows[rows["metric"] == "hic36.sled"]
    assert (moved["new"] / moved["old"] - 1).to_numpy() == pytest.approx(1.01**2.5 - 1, rel=2e-3)


def test_summary_sort_orders_by_a_criterion(
    sweeps: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert main(["summary", str(sweeps["baseline"]), "--sort", "hic15.sled", "--columns", "hic15.sled"]) == 0
    lines = [ln.split() for ln in capsys.readouterr().out.splitlines()[2:]]
    assert [int(ln[1]) for ln in lines] == [2, 1, 0]  # the largest pulse (variant 2) has the largest HIC
    # a criterion's name alone picks its one node's column (not hic15_t1.sled, hic15_t2.sled)
    assert (
        main(["summary", str(sweeps["baseline"]), "--sort", "hic15", "--ascending", "--columns", "hic15"])
        == 0
    )
    lines = [ln.split() for ln in capsys.readouterr().out.splitlines()[2:]]
    assert [int(ln[1]) for ln in lines] == [0, 1, 2]


def test_matrix_plot_draws_a_criterion_over_the_axis(sweeps: dict[str, Path], tmp_path: Path) -> None:
    from crashstudy.analysis.plot_matrix import plot_matrix

    assert (
        main(
            [
                "plot",
                str(sweeps["baseline"]),
                "--kind",
                "matrix",
                "--quantity",
                "hic15.sled",
                "-o",
                str(tmp_path),
            ]
        )
        == 0
    )
    assert (tmp_path / "matrix-hic15.sled.png").stat().st_size > 0
    fig = plot_matrix(open_results(sweeps["baseline"]).summary, "hic15.sled")
    y = fig.axes[0].lines[0].get_ydata()
    truth = [hic_closed_form(s * A_G, T_PULSE, 0.015)[0] for s in SCALES]
    assert np.asarray(y) == pytest.approx(truth, rel=5e-3)


def test_pulse_plot_shows_the_filtered_pulse_in_g_over_ms_beside_the_raw_channel(
    sweeps: dict[str, Path], tmp_path: Path
) -> None:
    from crashstudy.analysis.plot_pulse import plot_pulse

    assert main(["plot", str(sweeps["baseline"]), "--kind", "pulse", "-o", str(tmp_path)]) == 0
    assert (tmp_path / "pulse.png").stat().st_size > 0
    res = open_results(sweeps["baseline"])
    fig = plot_pulse(res.dataset)
    ax = fig.axes[0]
    assert (
        ax.get_xlabel() == "time [ms]" and ax.get_ylabel() == "deceleration along travel [g]"
    )  # signed (item 23.10)
    for j, s in enumerate(SCALES):
        raw, filt = ax.lines[2 * j], ax.lines[2 * j + 1]
        assert max(raw.get_xdata()) == pytest.approx(30.0)  # end_time 0.03 s in ms
        # sampled every 30 us: the raw channel's samples of the half-sine peak within (1 - cos(pi 15us/T))
        assert max(raw.get_ydata()) == pytest.approx(s * A_G, rel=2e-4)
        assert np.nanmax(filt.get_ydata()) == pytest.approx(res.summary["peak_g.sled"][j], rel=2e-4)


def test_2d_default_direction_is_the_initial_velocity_direction(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 2-D drop: the sled falls at 10 m/s (-y) and the half-sine decelerates it (+y acceleration).
    Against the direction of travel the deceleration is positive: ``delta_v = 2 A T / pi``; the default
    direction equals an explicit [0, -2] (normalised) and differs from +y (dri sees the pulse reversed)."""
    text = pulse_model(
        metrics=(
            "  - {node: sled, criteria: [delta_v, dri]}\n"
            "  - {node: other, direction: [0.0, -2.0], criteria: [delta_v, dri]}\n"
            "  - {node: third, direction: y, criteria: [dri]}"
        )
    )
    text = (
        text.replace("position: [0.0], fixed", "position: [0.0, 0.0], fixed")
        .replace("position: [1.0]", "position: [0.0, 1.0]")
        .replace("position: [2.0]", "position: [0.0, 2.0]")
        .replace("direction: x, curve: pulse", "direction: y, curve: pulse")
        .replace(
            "initial_velocity: {sled: [10.0], other: [10.0]}",
            "initial_velocity: {sled: [0.0, -10.0], other: [0.0, -10.0], third: [0.0, -10.0]}",
        )
    )
    text = text.replace("scale: -", "scale: ")  # +y acceleration
    # other and third follow the same pulse
    amp = f"{A_G * G:.12g}"
    text = text.replace(
        "prescribed_motion:\n",
        "prescribed_motion:\n"
        f"  - {{node: other, quantity: acceleration, direction: y, curve: pulse, scale: {amp}}}\n"
        f"  - {{node: third, quantity: acceleration, direction: y, curve: pulse, scale: {amp}}}\n",
    )
    text = text.replace(
        "  other: {position: [0.0, 2.0], mass: 1.0}",
        "  other: {position: [0.0, 2.0], mass: 1.0}\n  third: {position: [0.0, 3.0], mass: 1.0}",
    )
    model = tmp_path / "drop.yaml"
    model.write_text(text)
    assert main(["simulate", str(model), "-o", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    ds = open_results(tmp_path / "out").dataset.sel(variant=0)
    assert float(ds["delta_v"].sel(node="sled")) == pytest.approx(2 * A_G * G * T_PULSE / math.pi, rel=1e-3)
    assert float(ds["dri"].sel(node="sled")) == float(ds["dri"].sel(node="other")) > 1.0
    assert float(ds["dri"].sel(node="third")) < 0.5 * float(ds["dri"].sel(node="sled"))
