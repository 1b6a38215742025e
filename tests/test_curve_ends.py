"""past_curve_end: springs driven past the drawn ends of their material curves (where the force is
extrapolated), per variant and spring, in the summary and as a warning of `run` / `simulate`.
Truth: closed-form extremes of one mass on one spring (crush at constant force, linear oscillation)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.cli.main import main
from crashstudy.results.store import open_results

CURVES = {  # crush plateau of 1 kN drawn to 0.1 m; an elastic 100 N/m line drawn over +-0.1 m
    "plateau": {"x": [-0.1, -0.001, 0.0], "y": [-1000.0, -1000.0, 0.0]},
    "line": {"x": [-0.1, 0.0, 0.1], "y": [-10.0, 0.0, 10.0]},
    "unload": {"x": [-0.001, 0.0, 0.001], "y": [-2000.0, 0.0, 2000.0]},
}


def _model(material: dict, v0: float, end_time: float) -> dict:
    return {
        "name": "one",
        "curves": CURVES,
        "nodes": {"wall": {"position": [0.0], "fixed": True}, "m": {"position": [1.0], "mass": 1.0}},
        "springs": {
            "s": {"nodes": ["wall", "m"], "material": material},
            "link": {"nodes": ["wall", "m"], "material": {"type": "linear_elastic", "stiffness": 1e-6}},
        },
        "initial_velocity": {"m": [v0]},
        "end_time": end_time,
        "output": {"histories": "none"},
    }


def _run(tmp_path: Path, model: dict, speeds: list[float], capsys: pytest.CaptureFixture[str]) -> tuple:
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(model))
    (tmp_path / "s.yaml").write_text(
        yaml.safe_dump({"name": "ends", "model": "m.yaml", "matrix": {"impact_velocity": speeds}})
    )
    assert main(["run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out")]) == 0
    res = open_results(tmp_path / "out")
    return res.summary, res.dataset, capsys.readouterr().err


def test_a_crush_spring_crushed_past_its_curve_is_flagged_and_warned(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1 kg at v0 into a 1 kN plateau: crush m v0^2 / (2 F) = 0.032 m at 8 m/s (within the drawn 0.1 m),
    0.125 m at 15.81 m/s and 0.2 m at 20 m/s (past it: the plateau extrapolated); the tension end of
    a crush curve is never checked; the linear spring has no column."""
    crush = {"type": "crush", "loading": "plateau", "unloading_stiffness": 1e5}
    df, ds, err = _run(tmp_path, _model(crush, -8.0, 0.05), [8.0, 15.81, 20.0], capsys)
    for v, speed in enumerate((8.0, 15.81, 20.0)):  # the closed form, 1e-2 (the first 1 mm ramps up)
        assert df["max_crush.s"][v] == pytest.approx(speed**2 / 2000.0, rel=1e-2, abs=1e-3)
    assert list(df["past_curve_end.s"]) == [0.0, 1.0, 1.0]
    assert "past_curve_end.link" not in df.columns
    assert "spring s was compressed past its curve's first point in 2 of 3 variants" in err
    assert ds["past_curve_end"].attrs["springs"] == "s"


def test_an_elastic_curve_checks_both_ends(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """1 kg on a 100 N/m line (omega = 10 rad/s) hit at v0: amplitude v0 / omega, stretched and then
    compressed within a period (0.63 s < 0.7 s): 0.05 m stays within +-0.1 m (0), 0.15 m passes both
    ends (3); moving away at 1.5 m/s for 0.1 s stretches sin(1) 0.15 = 0.126 m only (2)."""
    line = {"type": "nonlinear_elastic", "curve": "line"}
    df, _, err = _run(tmp_path, _model(line, -0.5, 0.7), [0.5, 1.5], capsys)
    assert df["max_elongation.s"][1] == pytest.approx(0.15, rel=1e-3)
    assert list(df["past_curve_end.s"]) == [0.0, 3.0]
    assert (
        "compressed past its curve's first point in 1" in err and "stretched past its last point in 1" in err
    )
    (tmp_path / "away").mkdir()
    away, _, _ = _run(tmp_path / "away", _model(line, 1.5, 0.1), [1.5], capsys)
    assert away["max_elongation.s"][0] == pytest.approx(0.15 * math.sin(1.0), rel=1e-3)
    assert list(away["past_curve_end.s"]) == [2.0]


@pytest.mark.parametrize("compression_yield", [None, -5.0])
def test_a_general_nonlinear_stretch_is_checked_only_without_a_compression_yield(
    compression_yield: float | None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Moving away at 1.5 m/s for 0.1 s on the 100 N/m loading line: stretched sin(1) 0.15 = 0.126 m,
    past the curve's last point (0.1 m). Without a compression yield the force is read on the loading
    curve there: flagged (2). With one, a stretch is never checked (after a compression yield it would
    follow the moved unloading curve); the rule errs on the side of silence, so this stretch of a spring
    that never yielded is not flagged (0)."""
    material = {"type": "general_nonlinear", "loading": "line", "unloading": "unload"}
    if compression_yield is not None:
        material["compression_yield"] = compression_yield
    df, _, _ = _run(tmp_path, _model(material, 1.5, 0.1), [1.5], capsys)
    assert df["max_elongation.s"][0] == pytest.approx(0.15 * math.sin(1.0), rel=1e-3)
    assert list(df["past_curve_end.s"]) == [2.0 if compression_yield is None else 0.0]


def test_a_failed_variant_has_no_past_curve_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The 0.01 kg variant cannot use the fixed dt = 0.03 s (dt_crit = 2 sqrt(m / k) = 0.02 s) and fails:
    NaN, like every summary of a failed variant; the 1 kg one (dt_crit 0.2 s) runs (0)."""
    line = {"type": "nonlinear_elastic", "curve": "line"}
    model = dict(_model(line, -0.5, 0.7), time_step={"dt": 0.03})
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(model))
    (tmp_path / "s.yaml").write_text(
        yaml.safe_dump({"name": "ends", "model": "m.yaml", "matrix": {"nodes.m.mass": [1.0, 0.01]}})
    )
    assert main(["run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out")]) == 1
    df = open_results(tmp_path / "out").summary
    assert list(df["status"]) == ["ok", "failed"]
    assert df["past_curve_end.s"][0] == 0.0 and np.isnan(df["past_curve_end.s"][1])
