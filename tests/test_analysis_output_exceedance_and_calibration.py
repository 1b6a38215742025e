"""Issue 23 items 7-8: what the analysis commands show: an exceedance fraction of a matrix is no
probability (a warning; the sample caveat only for a plain sampled design), and what a calibration does not
determine (intervals that hold the truth, an undetermined variable named, the closed form of a straight
line fit).

The study of most tests is described in analysis_study.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.cli.main import main
from helpers import noisy_spring_force

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
