"""A fixed ``time_step.dt`` above the history interval: the step is lowered to the interval (it divides the
interval exactly, docs/format.md), so a run takes dt / interval times the steps asked for. ``validate`` and
``run`` say so, with the file and line of the dt and what to change; a dt that fits is not mentioned.
The truth for the step actually run: interval / ceil(interval / dt) (the rule of arrays/timestep.py)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from helpers import model_batch, run_cli

MODEL = """name: fixed-step
nodes:
  a: {{position: [0.0], fixed: true}}
  b: {{position: [1.0], mass: 1.0}}
springs:
  s: {{nodes: [a, b], material: {{type: linear_elastic, stiffness: 1.0e4}}}}
end_time: 0.01
time_step: {{dt: {dt}}}
{output}initial_velocity: {{b: [-1.0]}}
"""


@pytest.mark.parametrize(
    ("dt", "output", "ratio"),
    [
        (9e-4, "", 90.0),  # the default interval end_time / 1000 = 1e-5
        (9e-4, "output: {interval: 3.0e-4}\n", 3.0),
        (9e-4, "output: {interval: 1.8e-3}\n", None),  # a multiple of dt: the step is kept
        (5e-6, "", None),  # below the interval: lowered a little at most, nothing to say
    ],
)
def test_a_fixed_step_above_the_history_interval_is_reported_with_its_line(
    tmp_path: Path, dt: float, output: str, ratio: float | None
) -> None:
    text = MODEL.format(dt=dt, output=output)
    model = tmp_path / "m.yaml"
    model.write_text(text)
    res = run_cli("validate", model)
    assert res.returncode == 0, res.stderr
    interval = 3.0e-4 if "3.0e-4" in output else 1.8e-3 if "1.8e-3" in output else 0.01 / 1000
    batch, _ = model_batch(text)
    assert math.isclose(float(batch.dt[0]), interval / math.ceil(interval / dt - 1e-9), rel_tol=1e-12)
    said = [ln for ln in (res.stdout + res.stderr).splitlines() if "is above output.interval" in ln]
    if ratio is None:
        assert not said
        return
    line = 1 + text.splitlines().index(f"time_step: {{dt: {dt}}}")
    assert len(said) == 1 and f"m.yaml:{line}: time_step.dt: dt={dt:g}" in said[0], said
    assert f"lowered to {interval:g} ({ratio:g} x the steps asked for)" in said[0], said
    assert float(batch.dt[0]) == pytest.approx(dt / ratio, rel=1e-12)


def test_a_fixed_step_refused_for_every_variant_is_the_one_error_on_it(tmp_path: Path) -> None:
    """dt above the critical step of every variant: exit 2 with the dt_crit problem, and no warning on the
    same dt about the interval (the step must change anyway)."""
    model = tmp_path / "m.yaml"
    model.write_text(MODEL.format(dt=3e-2, output=""))
    res = run_cli("validate", model)
    assert res.returncode == 2
    dt_crit = 0.99 * 2.0 / math.sqrt(2.0 * 1.0e4 / 1.0)  # the nodal bound 2 K_n / m_n, 1 % margin (solver.md)
    assert f"time_step.dt: dt=0.03 is above the critical step dt_crit={dt_crit:.6g}" in res.stderr, res.stderr
    assert "warning" not in res.stdout + res.stderr


def test_a_fixed_step_axis_is_reported_at_its_largest_value_and_its_line(tmp_path: Path) -> None:
    """dt as a study axis: the largest value is the one lowered most, and the axis line is where to change it."""
    (tmp_path / "m.yaml").write_text(MODEL.format(dt=5e-6, output=""))
    study = tmp_path / "s.yaml"
    study.write_text(
        "name: steps\nmodel: m.yaml\nmatrix:\n  nodes.b.mass: [1.0, 2.0]\n  time_step.dt: [5.0e-6, 9.0e-4]\n"
    )
    res = run_cli("validate", study)
    assert res.returncode == 0, res.stderr
    said = [ln for ln in (res.stdout + res.stderr).splitlines() if "is above output.interval" in ln]
    assert len(said) == 1 and "s.yaml:5: time_step.dt: dt=0.0009" in said[0], said
    assert "lowered to 1e-05 (90 x the steps asked for)" in said[0], said
