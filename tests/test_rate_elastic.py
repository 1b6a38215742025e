"""``rate_elastic`` (docs/format.md): F = C(e, |de/dt|), linear in the rate between the curves that
bracket it, the first curve below the first rate, the last above the last.

Closed form: two linear curves k1 at rate r1 and k2 at r2 make F = k(r) e with k(r) = k1 below r1,
k1 + (r - r1) / (r2 - r1) (k2 - k1) between, k2 above. A spring stretched (or crushed) at a constant
prescribed rate follows it to round-off; a mass on it follows a converged ``solve_ivp`` solution of
m x'' = -k(|x'|) x. The fast kernels' bitwise agreement is in tests/test_kernel_twins.py (cases
``rate-elastic-*``), the law against its NumPy twin in tests/test_laws.py.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from conftest import run_model
from crashstudy.cli.main import main
from lanes import run_lanes

K1, R1, K2, R2 = 1.0e4, 1.0, 3.0e4, 3.0  # [N/m] at [m/s]


def k_of(r: float) -> float:
    """The closed form's stiffness at rate magnitude r."""
    return K1 if r <= R1 else K2 if r >= R2 else K1 + (r - R1) / (R2 - R1) * (K2 - K1)


def _driven(speed: float, end_time: float = 0.05) -> dict[str, Any]:
    """A rate_elastic spring between a fixed anchor and a node driven at ``speed`` [m/s] (< 0: crushed),
    for ``end_time`` [s] (the tests of F = k(|v|) e run 0.01 s, 625 reference steps and 10 samples: the
    rate is constant, so every sample checks the same law; 0.05 s before)."""
    return {
        "name": "rate-elastic-driven",
        "curves": {
            "soft": {"x": [-1.0, 0.0, 1.0], "y": [-K1, 0.0, K1]},
            "stiff": {"x": [-1.0, 0.0, 1.0], "y": [-K2, 0.0, K2]},
            "const": {"x": [0.0, 1.0], "y": [1.0, 1.0]},
        },
        "nodes": {"anchor": {"position": [0.0], "fixed": True}, "end": {"position": [1.0], "mass": 1.0}},
        "springs": {
            "s": {
                "nodes": ["anchor", "end"],
                "material": {
                    "type": "rate_elastic",
                    "curves": [{"rate": R1, "curve": "soft"}, {"rate": R2, "curve": "stiff"}],
                },
            }
        },
        "initial_velocity": {"end": [speed]},
        "prescribed_motion": [
            {"node": "end", "quantity": "velocity", "direction": "x", "curve": "const", "scale": speed}
        ],
        "end_time": end_time,
        "time_step": {"dt": 1.6e-5},  # below the rate terms' damper limit (2e-5 at scale 2)
        "output": {"interval": 1.0e-3, "histories": ["spring_force", "spring_elongation"]},
    }


SPEEDS = [0.4, -0.4, 1.5, -2.2, 2.9, 5.0, -8.0]  # m/s: below, between and above the two rates, both ways
DRIVEN_END = 0.01  # [s] end time of the driven spring where only the law F = k(|v|) e is checked


@pytest.fixture(scope="module")
def driven_runs() -> dict[float, Any]:
    """speed -> the reference's output of :func:`_driven` at that speed: the seven are lanes of one kernel
    call (tests/lanes.py; the reference's cost is per step, hardly per lane)."""
    outs, _, _ = run_lanes([_driven(v, DRIVEN_END) for v in SPEEDS])
    return dict(zip(SPEEDS, outs, strict=True))


@pytest.mark.parametrize("speed", SPEEDS)
def test_spring_driven_at_a_constant_rate_follows_the_interpolated_stiffness(
    speed: float, driven_runs: dict[float, Any]
) -> None:
    """F = k(|v|) e at every sample: below, between and above the two rates, stretched and crushed
    (relative 1e-12: the kernels evaluate the same two curves and one interpolation)."""
    out = driven_runs[speed]
    force = out.histories["spring_force"][1:, 0, 0]
    elong = out.histories["spring_elongation"][1:, 0, 0]
    assert np.all(np.abs(elong) > 0)
    np.testing.assert_allclose(force, k_of(abs(speed)) * elong, rtol=1e-12)
    np.testing.assert_allclose(elong[-1], speed * DRIVEN_END, rtol=1e-9)


def test_one_curve_is_rate_independent() -> None:
    model = _driven(2.0, DRIVEN_END)
    model["springs"]["s"]["material"]["curves"] = [{"rate": 1.0, "curve": "stiff"}]
    out, _, _ = run_model(model, kernel="reference")
    np.testing.assert_allclose(
        out.histories["spring_force"][1:, 0, 0], K2 * out.histories["spring_elongation"][1:, 0, 0], rtol=1e-12
    )


def _mass(v0: float, dt: float) -> dict[str, Any]:
    model = _driven(v0)
    del model["prescribed_motion"]
    model["nodes"]["end"]["mass"] = 2.0
    model["end_time"] = 0.06
    model["time_step"] = {"dt": dt}
    model["output"] = {"interval": 1.0e-3, "histories": ["displacement"]}
    return model


def _solve_ivp(v0: float, t: np.ndarray) -> np.ndarray:
    from scipy.integrate import solve_ivp

    sol = solve_ivp(
        lambda _t, y: [y[1], -k_of(abs(y[1])) * y[0] / 2.0],
        (0.0, float(t[-1])),
        [0.0, v0],
        rtol=1e-11,
        atol=1e-13,
        dense_output=True,
        max_step=1e-5,
    )
    return sol.sol(t)[0]


@pytest.mark.parametrize("v0", [4.0])
def test_mass_on_a_rate_elastic_spring_converges_to_the_ode_solution(v0: float) -> None:
    """A 2 kg mass leaving at 4 m/s: the spring stiffens with the speed (k(|x'|) from 3e4 down to 1e4 N/m
    as it slows). Against solve_ivp (rtol 1e-11): the displacement error below 1e-5 of the amplitude at
    dt = 2e-5 s, and it falls at least 3x when dt halves (the central difference's second order, the
    rate estimate near the kinks at r1 and r2; measured 1.9e-6 and 3.9e-7)."""
    outs, _, plan = run_lanes([_mass(v0, dt) for dt in (2.0e-5, 1.0e-5)])  # one reference call, two lanes
    ref = _solve_ivp(v0, np.arange(plan.n_out) * 1.0e-3)  # the same samples for both steps
    errs = []
    for out in outs:
        x = out.histories["displacement"][:, 1, 0, 0]
        errs.append(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))
    assert errs[0] < 1e-5, errs
    assert errs[1] < errs[0] / 3.0, errs


def test_curve_scale_axis_scales_the_force() -> None:
    """A study axis ``curves.<id>.scale`` on the stiff curve scales k2 (the rate of 4 m/s is above r2)."""
    out, _, _ = run_model(
        _driven(4.0, DRIVEN_END), kernel="reference", variants={"curves.stiff.scale": [1.0, 0.5, 2.0]}
    )
    ratio = out.histories["spring_force"][1:, 0, :] / out.histories["spring_elongation"][1:, 0, :]
    np.testing.assert_allclose(ratio, np.broadcast_to([K2, 0.5 * K2, 2.0 * K2], ratio.shape), rtol=1e-12)


def test_critical_step_uses_the_steepest_curve() -> None:
    """dt_crit of a free mass on the spring is that of the stiffest curve: a fixed dt between the two
    curves' limits is refused."""
    from conftest import model_batch

    batch, _ = model_batch(_mass(1.0, 1.0e-5))
    limit_k2 = float(2.0 / np.sqrt(K2 / 2.0))
    assert batch.invalid[0] == 0
    batch, _ = model_batch(_mass(1.0, 0.995 * limit_k2))  # below k1's limit, above k2's (with its 1 % margin)
    assert batch.invalid[0] == 1


def _invalid(tmp_path: Path, capsys: pytest.CaptureFixture[str], edit: Any) -> str:
    model = _driven(1.0)
    edit(model)
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(model, sort_keys=False))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(path) in err
    return err


def test_rates_must_increase(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def edit(m: dict[str, Any]) -> None:
        m["springs"]["s"]["material"]["curves"][1]["rate"] = 0.5

    err = _invalid(tmp_path, capsys, edit)
    assert "springs.s.material.curves" in err and "strictly increasing" in err


def test_negative_rate_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def edit(m: dict[str, Any]) -> None:
        m["springs"]["s"]["material"]["curves"][0]["rate"] = -1.0

    err = _invalid(tmp_path, capsys, edit)
    assert "springs.s.material.curves.0.rate" in err


def test_each_curve_must_pass_the_origin_and_have_the_sign_of_e(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def shifted(m: dict[str, Any]) -> None:
        m["curves"]["stiff"]["y"] = [-K2 + 5.0, 5.0, K2 + 5.0]

    err = _invalid(tmp_path, capsys, shifted)
    assert "springs.s.material.curves.1.curve" in err and "origin" in err

    def flipped(m: dict[str, Any]) -> None:
        m["curves"]["soft"]["y"] = [K1, 0.0, -K1]

    err = _invalid(tmp_path, capsys, flipped)
    assert "springs.s.material.curves.0.curve" in err


def test_unknown_curve_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def edit(m: dict[str, Any]) -> None:
        m["springs"]["s"]["material"]["curves"][1]["curve"] = "nope"

    err = _invalid(tmp_path, capsys, edit)
    assert "springs.s.material.curves.1.curve" in err and "nope" in err


def test_stretching_past_the_shortest_curve_end_is_reported() -> None:
    """past_curve_end: the soft curve ends at 1 m, the stiff one (here cut to 0.04 m) earlier; a spring
    stretched to 0.05 m has passed the stiff curve's last point (code 2), one crushed to -0.05 m its
    first point (code 1), one stretched to 0.03 m neither (0)."""
    from crashstudy.results.curve_ends import past_curve_ends

    cases = ((1.0, 2.0), (-1.0, 1.0), (0.6, 0.0))
    models = [_driven(speed) for speed, _ in cases]
    for model in models:
        model["curves"]["stiff"] = {"x": [-0.04, 0.0, 0.04], "y": [-0.04 * K2, 0.0, 0.04 * K2]}
    outs, batch, _ = run_lanes(models)  # one reference call, a lane per speed
    for k, ((speed, code), out) in enumerate(zip(cases, outs, strict=True)):
        got = past_curve_ends(batch, out.max_crush, out.max_elongation, np.array([k]))
        assert got[0, 0] == code, (speed, got)
