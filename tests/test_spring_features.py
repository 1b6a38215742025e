"""SPEC v2 spring features against closed forms: ``elastoplastic`` (LS-DYNA S03), ``nonlinear_damper``
(S05), the spring options ``initial_elongation`` (with IE0 in the energy balance) and ``failure``, and the
summaries ``max_elongation`` and ``failure_time``.

Every model is a single mass on one spring (1-D, and 2-D along a slanted axis where the feature has a 2-D
form), so the truth is a formula of mechanics, written here from docs/format.md, not from the kernels.
Most tests run the NumPy reference; tests/test_kernel_twins.py holds both fast kernels bitwise equal to it
on every feature.
"""

from __future__ import annotations

import contextlib
import functools
import io
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from crashstudy.arrays.compiler import apply_axis
from crashstudy.arrays.parameter_checks import check_parameters
from crashstudy.cli.main import main
from crashstudy.errors import InputError
from crashstudy.kernel import choice, generated
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import loads_yaml
from helpers import generated_part, model_plan, run_model
from lanes import run_lanes
from models import PULL, breaking_spring
from models import one_spring as _one_spring


def _along(out: Any, name: str, dim: int) -> np.ndarray:
    """History ``name`` of node ``b`` along the spring axis, variant 0."""
    axis = np.array([1.0] if dim == 1 else [0.6, 0.8])
    return out.histories[name][:, 1, :, 0] @ axis


def run_main(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(list(argv))
    return rc, out.getvalue(), err.getvalue()


# --------------------------------------------------------------------------------------------------
# elastoplastic
# --------------------------------------------------------------------------------------------------

K, KT, FY = 4.0e4, 1.0e4, 2.0e3  # N/m, N/m, N: elastic limit ey = FY / K = 0.05 m
MASS = 10.0


def _plastic_peak(v0: float) -> tuple[float, float]:
    """(e_max, F_max) of a mass MASS hitting the bilinear spring at v0: 1/2 m v0^2 = work to e_max."""
    ey = FY / K
    energy = 0.5 * MASS * v0**2 - 0.5 * FY * ey  # beyond the elastic limit
    d = (-FY + math.sqrt(FY**2 + 2.0 * KT * energy)) / KT  # FY d + KT d^2 / 2 = energy
    return ey + d, FY + KT * d


def _impact(v0: float, dim: int, tangent_stiffness: float = KT) -> dict[str, Any]:
    """MASS leaving (v0 > 0) or crushing (v0 < 0) the bilinear spring; every step sampled."""
    material = {
        "type": "elastoplastic",
        "stiffness": K,
        "tangent_stiffness": tangent_stiffness,
        "yield_force": FY,
    }
    return _one_spring(material, MASS, v0, dim, end_time=0.08, dt=5.0e-5, interval=5.0e-5)


@pytest.fixture(scope="module")
def elastoplastic_impacts() -> Callable[[int], list[Any]]:
    """dim -> the reference's outputs of (tension, compression at 5 m/s, and in 1-D the perfectly plastic
    spring KT = 0 at 5 m/s): one kernel call per dimension (tests/lanes.py), shared by the tests below."""

    @functools.cache
    def runs(dim: int) -> list[Any]:
        models = [_impact(5.0, dim), _impact(-5.0, dim)]
        if dim == 1:
            models.append(_impact(5.0, dim, tangent_stiffness=0.0))
        return run_lanes(models)[0]

    return runs


@pytest.mark.parametrize("dim", [1, 2])
def test_elastoplastic_impact_max_and_residual_elongation_and_elastic_rebound_match_closed_form(
    dim: int, elastoplastic_impacts: Callable[[int], list[Any]]
) -> None:
    """A 10 kg mass at 5 m/s stretches (or crushes) the bilinear spring past yield: the peak follows from
    the work, ``1/2 m v0^2 = FY^2 / 2K + FY d + KT d^2 / 2``; it unloads elastically (slope K) to the residual
    elongation ``e_max - F_max / K`` where the force is 0, passing it at the elastic rebound speed
    ``F_max / sqrt(K m)``. Tolerance 1e-3 relative (dt = 5e-5 s, omega dt ~ 3e-3; measured errors
    <= 3.8e-6, 1.4e-7 at dt = 1e-5; the force returns to 0 at t = 0.053 s of 0.08). Tension and
    compression are two lanes of one reference run."""
    v0 = 5.0
    e_max, f_max = _plastic_peak(v0)
    for direction, out in zip((1.0, -1.0), elastoplastic_impacts(dim)[:2], strict=True):
        assert out.status[0] == 0, direction
        peak = out.max_elongation[0, 0] if direction > 0 else out.max_crush[0, 0]
        assert peak == pytest.approx(e_max, rel=1e-3), direction
        assert out.peak_force[0, 0] == pytest.approx(f_max, rel=1e-3), direction
        e = out.histories["spring_elongation"][:, 0, 0]
        f = out.histories["spring_force"][:, 0, 0]
        v = _along(out, "velocity", dim)
        k = int(np.argmax(direction * e))
        z = k + int(np.argmax(direction * f[k:] <= 0.0))  # first sample at or past the force's return to 0
        w = f[z - 1] / (f[z - 1] - f[z])
        e_res = e[z - 1] + w * (e[z] - e[z - 1])
        v_res = v[z - 1] + w * (v[z] - v[z - 1])
        assert e_res == pytest.approx(direction * (e_max - f_max / K), rel=1e-3), direction
        assert v_res == pytest.approx(-direction * f_max / math.sqrt(K * MASS), rel=1e-3), direction
        assert out.energy_error[0] < 1e-3, direction


def test_elastoplastic_perfectly_plastic_spring_flows_at_the_yield_force(
    elastoplastic_impacts: Callable[[int], list[Any]],
) -> None:
    """KT = 0: the force never exceeds FY (to round-off) and the plastic flow takes the energy above the
    elastic limit: ``e_max = ey / 2 + m v0^2 / (2 FY)``."""
    v0 = 5.0
    out = elastoplastic_impacts(1)[2]
    assert out.peak_force[0, 0] == pytest.approx(FY, rel=1e-12)
    assert out.max_elongation[0, 0] == pytest.approx(0.5 * FY / K + MASS * v0**2 / (2 * FY), rel=1e-3)


def test_elastoplastic_reverse_yield_waits_for_the_grown_yield_force_then_hardens_at_kt() -> None:
    """Isotropic hardening under a prescribed elongation 0 -> 0.1 m -> -0.1 m (K 4e4, KT 1e4, FY 2e3):
    tension past ey = 0.05 on ``F = FY + KT (e - ey)`` to F1 = 2500 N; elastic unloading (slope K) down to
    the grown yield force -F1 (not -FY) at ``e_r = 0.1 - 2 F1 / K``; then ``F = -F1 + KT (e - e_r)``.
    Every sample to 1e-9 of F1."""
    e1, f1 = 0.1, FY + KT * (0.1 - FY / K)
    model = _one_spring(
        {
            "type": "elastoplastic",
            "stiffness": K,
            "tangent_stiffness": KT,
            "yield_force": FY,
            "_curves": {"path": {"x": [0.0, 1.0, 3.0], "y": [0.0, e1, -e1]}},
        },
        1.0,
        end_time=3.0,
        dt=5.0e-3,
        interval=5.0e-3,
    )
    model["prescribed_motion"] = [
        {"node": "b", "quantity": "displacement", "direction": "x", "curve": "path"}
    ]
    out, _, _ = run_model(model, kernel="reference")
    e = out.histories["spring_elongation"][:, 0, 0]
    f = out.histories["spring_force"][:, 0, 0]
    t = np.arange(len(e)) * 5.0e-3
    e_r = e1 - 2.0 * f1 / K
    truth = np.where(
        t <= 1.0 + 1e-9,
        np.where(e <= FY / K, K * e, FY + KT * (e - FY / K)),
        np.where(e >= e_r, f1 - K * (e1 - e), -f1 + KT * (e - e_r)),
    )
    assert np.max(np.abs(f - truth)) < 1e-9 * f1
    assert f.min() == pytest.approx(-f1 + KT * (-e1 - e_r), rel=1e-9)


# --------------------------------------------------------------------------------------------------
# nonlinear_damper
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dim", [1, 2])
def test_nonlinear_damper_decelerates_a_mass_like_the_closed_form(dim: int) -> None:
    """A blow-off damper: ``C(r) = F0 r / r1`` up to ``r1``, ``F0`` beyond. A 10 kg mass leaving at 5 m/s
    first decelerates at ``F0 / m`` (v = v0 - F0 t / m) down to r1 at ``t1 = m (v0 - r1) / F0``, then
    exponentially, ``v = r1 exp(-F0 (t - t1) / (m r1))``. Velocity to 2e-3 of v0 at every sample,
    peak deceleration ``F0 / m`` to 1e-3 (dt = 5e-4 s; measured velocity error 7.7e-7 of v0, 3.1e-8 at
    dt = 1e-4 s, the second order of central difference)."""
    m, v0, f0, r1 = 10.0, 5.0, 100.0, 1.0
    curve = {"x": [-10.0, -r1, 0.0, r1, 10.0], "y": [-f0, -f0, 0.0, f0, f0]}
    model = _one_spring(
        {"type": "nonlinear_damper", "curve": "blow-off", "_curves": {"blow-off": curve}},
        m,
        v0,
        dim,
        end_time=0.8,
        dt=5.0e-4,
        interval=1.0e-3,
    )
    out, _, plan = run_model(model, kernel="reference")
    assert out.status[0] == 0
    t = np.arange(plan.n_out) * 1.0e-3
    t1 = m * (v0 - r1) / f0
    truth = np.where(t <= t1, v0 - f0 * t / m, r1 * np.exp(-f0 * (t - t1) / (m * r1)))
    v = _along(out, "velocity", dim)
    assert np.max(np.abs(v - truth)) < 2e-3 * v0
    assert out.peak_acceleration[1, 0] == pytest.approx(f0 / m, rel=1e-3)
    assert out.peak_force[0, 0] == pytest.approx(f0, rel=1e-3)


# --------------------------------------------------------------------------------------------------
# failure
# --------------------------------------------------------------------------------------------------


K_BREAK, M_BREAK, V_BREAK, E_FAIL = 1.0e4, 1.0, 2.0, 0.01  # amplitude v0 / w = 0.02 m


def _breaking(direction: float, dim: int, failure: dict[str, float]) -> dict[str, Any]:
    """A linear spring (k = 1e4 N/m) under a 1 kg mass leaving (direction 1) or crushing (-1) at 2 m/s,
    run to 6 ms: 0.76 ms (76 samples) past the break at 5.24 ms; the spring that holds reaches 0.0113 m
    (6000 reference steps at dt = 1e-6 s per lane; 10 ms, 10000 steps before)."""
    return _one_spring(
        {"type": "linear_elastic", "stiffness": K_BREAK},
        M_BREAK,
        direction * V_BREAK,
        dim,
        end_time=0.006,
        dt=1.0e-6,
        interval=1.0e-5,
        failure=failure,
    )


@pytest.fixture(scope="module")
def breaking_springs() -> Callable[[int], list[Any]]:
    """dim -> the reference's outputs of (breaking in tension, breaking in compression, and in 1-D a
    spring that holds: failure at +-0.03 m): one kernel call per dimension (tests/lanes.py)."""

    @functools.cache
    def runs(dim: int) -> list[Any]:
        models = [
            _breaking(1.0, dim, {"tension": E_FAIL}),
            _breaking(-1.0, dim, {"compression": -E_FAIL}),
        ]
        if dim == 1:
            models.append(_breaking(1.0, dim, {"tension": 0.03, "compression": -0.03}))
        return run_lanes(models)[0]

    return runs


@pytest.mark.parametrize("dim", [1, 2])
def test_spring_breaks_at_its_failure_elongation_and_the_mass_flies_on_at_the_speed_left(
    dim: int, breaking_springs: Callable[[int], list[Any]]
) -> None:
    """A linear spring (k = 1e4 N/m) under a 1 kg mass at 2 m/s, breaking at |e| = 0.01 m (amplitude 0.02 m):
    ``e = (v0 / w) sin(w t)``, so it breaks at ``t_f = asin(e_f w / v0) / w`` and the mass goes on at
    ``sqrt(v0^2 - w^2 e_f^2)`` with no force; the variant stays ok, ``absorbed_energy`` is the ``k e_f^2 / 2``
    stored when it broke, ``max_elongation`` (or ``max_crush``) the failure elongation.
    Tolerances 1e-4 relative (dt = 1e-6 s, the crossing time interpolated within its step), 1e-3 for the
    energy. In tension (only a tension failure set) and in compression (only a compression failure):
    two lanes of one reference run."""
    k, m, v0, ef = K_BREAK, M_BREAK, V_BREAK, E_FAIL
    w = math.sqrt(k / m)
    t_f = math.asin(ef * w / v0) / w
    for direction, out in zip((1.0, -1.0), breaking_springs(dim)[:2], strict=True):
        assert out.status[0] == 0, direction
        assert out.spring_fail_time[0, 0] == pytest.approx(t_f, rel=1e-4), direction
        v = _along(out, "velocity", dim)
        assert v[-1] == pytest.approx(direction * math.sqrt(v0**2 - (w * ef) ** 2), rel=1e-4), direction
        after = np.arange(len(v)) * 1.0e-5 > t_f + 1.0e-5
        assert np.all(out.histories["spring_force"][after, 0, 0] == 0.0), direction
        # the force stops at the first step past the break; that step books half of F de: O(v dt / e_f) ~ 2e-4
        assert out.absorbed_energy[0, 0] == pytest.approx(0.5 * k * ef**2, rel=1e-3), direction
        extreme = out.max_elongation[0, 0] if direction > 0 else out.max_crush[0, 0]
        assert extreme == pytest.approx(ef, rel=1e-12), direction
        assert out.energy_error[0] < 1e-3, direction


def test_failure_time_is_nan_while_the_spring_holds(breaking_springs: Callable[[int], list[Any]]) -> None:
    """Amplitude 0.02 m, failure at 0.03 m: it never breaks (NaN), and the force history stays ``k e``."""
    out = breaking_springs(1)[2]
    assert np.isnan(out.spring_fail_time[0, 0])
    h = out.histories
    assert np.allclose(
        h["spring_force"][:, 0, 0], 1.0e4 * h["spring_elongation"][:, 0, 0], rtol=1e-12, atol=0
    )


def test_each_lane_of_a_shared_run_is_bitwise_its_model_run_alone() -> None:
    """tests/lanes.py's premise, on the two breaking springs (one fails in tension, the other has only a
    compression failure and crushes): each lane of one call is bit for bit its model's run alone."""
    from helpers import output_differences

    models = [_breaking(1.0, 1, {"tension": E_FAIL}), _breaking(-1.0, 1, {"compression": -E_FAIL})]
    together, _, _ = run_lanes(models, kernel="generic")
    for model, out in zip(models, together, strict=True):
        alone, _, _ = run_model(model, kernel="generic")
        assert output_differences(alone, out) == []


# --------------------------------------------------------------------------------------------------
# initial_elongation: the pre-stressed defect and its closed form
# --------------------------------------------------------------------------------------------------

PRESTRESSED_SHIFTED = """\
name: prestressed
curves:
  pull: {x: [-0.1, 0.1], y: [-5.0, 15.0]}
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [1.0], mass: 1.0}
springs:
  s:
    nodes: [a, b]
    material: {type: nonlinear_elastic, curve: pull}
end_time: 0.5
"""


def test_prestressed_curve_through_5_newton_at_rest_is_an_input_error_that_names_initial_elongation() -> None:
    """The defect: a curve through (0, 5 N) on a mass at rest failed as "numerical instability" (1-D) or
    reported energy_error 3e292 (2-D). It is now refused, with the file, line and field of the curve
    reference and a message that says to write the preload with initial_elongation."""
    with pytest.raises(InputError) as err:
        parse_model(loads_yaml(PRESTRESSED_SHIFTED, file="prestressed.yaml"))
    (problem,) = err.value.problems
    assert problem.field == "springs.s.material.curve"
    assert problem.line == 10
    assert "initial_elongation" in problem.message and "force at e=0 is 5" in problem.message


def _prestressed(dim: int, curve: bool) -> dict[str, Any]:
    """The same model written with initial_elongation: F = 100 e through the origin, e0 = 0.05 m (5 N)."""
    material: dict[str, Any] = {"type": "linear_elastic", "stiffness": 100.0}
    if curve:
        material = {
            "type": "nonlinear_elastic",
            "curve": "pull",
            "_curves": {"pull": {"x": [-0.1, 0.1], "y": [-10.0, 10.0]}},
        }
    model = _one_spring(material, 1.0, 0.0, dim, end_time=0.5, interval=1.0e-3, initial_elongation=0.05)
    return model


@pytest.mark.parametrize("curve", [True, False], ids=["nonlinear_elastic", "linear_elastic"])
@pytest.mark.parametrize("dim", [1, 2])
def test_prestressed_release_follows_the_closed_form_and_keeps_the_energy_balance(
    dim: int, curve: bool
) -> None:
    """Released from rest, the mass oscillates about the free length: ``u(t) = -e0 (1 - cos(w t))`` along the
    spring, ``w = sqrt(k / m) = 10 rad/s``. With the default time step (tolerance 1e-3): ``u`` within 1e-3 of
    ``2 e0`` at every sample, the variant ok with ``energy_error < 1e-3`` (IE0 = k e0^2 / 2 = 0.125 J
    in the balance and its scale), ``max_elongation`` = e0 and ``max_crush`` = e0 to 1e-3."""
    e0, w = 0.05, 10.0
    out, batch, plan = run_model(_prestressed(dim, curve), kernel="reference")
    assert out.status[0] == 0
    assert batch.ie0[0, 0] == pytest.approx(0.5 * 100.0 * e0**2, rel=1e-12)
    t = np.arange(plan.n_out) * 1.0e-3
    u = _along(out, "displacement", dim)
    assert np.max(np.abs(u + e0 * (1.0 - np.cos(w * t)))) < 1e-3 * 2 * e0
    assert out.energy_error[0] < 1e-3
    assert out.max_elongation[0, 0] == pytest.approx(e0, rel=1e-3)
    assert out.max_crush[0, 0] == pytest.approx(e0, rel=1e-3)
    ie = out.histories["internal_energy"][:, 0]
    assert ie[0] == pytest.approx(0.125, rel=1e-12)


def test_prestressed_release_energy_balance_is_round_off_in_every_history_sample() -> None:
    """KE + IE - IE0 stays 0 at every sample (not only in energy_error): the first half step books the
    preload force on the mean of the rates at 0 and 1/2, as the external work does for a force at t = 0."""
    out, _, _ = run_model(_prestressed(1, curve=False), kernel="reference")
    h = out.histories
    balance = h["kinetic_energy"][:, 0] + h["internal_energy"][:, 0] - 0.125
    assert np.max(np.abs(balance)) < 1e-12 * 0.125 * 1e3
    assert out.energy_error[0] < 1e-12


def test_preloaded_elastoplastic_crush_and_general_nonlinear_start_as_if_loaded_monotonically() -> None:
    """Each law walked from 0 to e0: the force at t = 0 and IE0 are the closed-form integrals.

    - elastoplastic (K 4e4, KT 1e4, FY 2e3), e0 = 0.1 m past ey = 0.05: F0 = FY + KT (e0 - ey) = 2500 N,
      IE0 = FY ey / 2 + FY (e0 - ey) + KT (e0 - ey)^2 / 2 = 162.5 J;
    - crush, L through (-0.01, -1000), (-0.1, -1500), e0 = -0.05: F0 = -1000 - 500 * 0.04 / 0.09,
      IE0 = the area under |L| from 0 to 0.05;
    - general_nonlinear whose loading curve peaks at 500 N (tension_yield 400 N) at 0.01 m and falls to
      300 N at 0.02 m, e0 = 0.03 m: it yielded on the way, so it unloads on F* + U(e - e*) (U slope 1e5),
      not on L: the force after release is ``F(e0) + 1e5 (e - e0)`` while it unloads.
    """
    plastic = _one_spring(
        {"type": "elastoplastic", "stiffness": K, "tangent_stiffness": KT, "yield_force": FY},
        MASS,
        end_time=1.0e-4,
        dt=1.0e-6,
        initial_elongation=0.1,
    )
    out, batch, _ = run_model(plastic, kernel="reference")
    assert out.histories["spring_force"][0, 0, 0] == pytest.approx(2500.0, rel=1e-12)
    assert batch.ie0[0, 0] == pytest.approx(0.5 * FY * 0.05 + FY * 0.05 + 0.5 * KT * 0.05**2, rel=1e-12)

    crush_curve = {"x": [-0.1, -0.01, 0.0], "y": [-1500.0, -1000.0, 0.0]}
    crush = _one_spring(
        {"type": "crush", "loading": "c", "unloading_stiffness": 1.0e6, "_curves": {"c": crush_curve}},
        MASS,
        end_time=1.0e-4,
        dt=1.0e-6,
        initial_elongation=-0.05,
    )
    out, batch, _ = run_model(crush, kernel="reference")
    f_e0 = -1000.0 - 500.0 * 0.04 / 0.09
    assert out.histories["spring_force"][0, 0, 0] == pytest.approx(f_e0, rel=1e-12)
    assert batch.ie0[0, 0] == pytest.approx(0.5 * 1000.0 * 0.01 + 0.5 * (1000.0 - f_e0) * 0.04, rel=1e-12)

    curves = {
        "load": {"x": [-0.1, 0.0, 0.01, 0.02, 0.1], "y": [-1.0e4, 0.0, 500.0, 300.0, 300.0]},
        "unload": {"x": [-0.1, 0.0, 0.1], "y": [-1.0e4, 0.0, 1.0e4]},
    }
    general = _one_spring(
        {
            "type": "general_nonlinear",
            "loading": "load",
            "unloading": "unload",
            "tension_yield": 400.0,
            "_curves": curves,
        },
        1.0,
        end_time=0.002,
        dt=1.0e-6,
        interval=1.0e-6,
        initial_elongation=0.03,
    )
    out, batch, _ = run_model(general, kernel="reference")
    e = out.histories["spring_elongation"][:, 0, 0]
    f = out.histories["spring_force"][:, 0, 0]
    assert f[0] == pytest.approx(300.0, rel=1e-12)
    unloading = (e < 0.03) & (f > -300.0)
    assert unloading.sum() > 100
    assert np.allclose(f[unloading], 300.0 + 1.0e5 * (e[unloading] - 0.03), rtol=0, atol=1e-9 * 300.0)
    assert batch.ie0[0, 0] == pytest.approx(0.5 * 500 * 0.01 + 0.5 * 800 * 0.01 + 300 * 0.01, rel=1e-12)


# --------------------------------------------------------------------------------------------------
# max_elongation, summaries, kernel choice, input errors
# --------------------------------------------------------------------------------------------------


def test_max_elongation_of_a_linear_oscillator_is_its_amplitude_in_summary_csv(tmp_path: Path) -> None:
    """k = 1e4 N/m, m = 1 kg, v0 = 2 m/s: amplitude v0 / w = 0.02 m both ways; ``summary.csv`` has
    ``max_elongation.s`` = 0.02 (1e-3, default step) and ``failure_time.s`` empty (NaN): a model with no
    failure option. The numbers come from every time step (the histories are not kept)."""
    model = _one_spring({"type": "linear_elastic", "stiffness": 1.0e4}, 1.0, 2.0, end_time=0.05)
    model["output"] = {"histories": "none"}
    path = tmp_path / "osc.yaml"
    path.write_text(yaml.safe_dump(model, sort_keys=False))
    rc, _, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    assert rc == 0, err
    row = pd.read_csv(tmp_path / "out" / "summary.csv").iloc[0]
    assert row["max_elongation.s"] == pytest.approx(0.02, rel=1e-3)
    assert row["max_crush.s"] == pytest.approx(0.02, rel=1e-3)
    assert math.isnan(row["failure_time.s"])
    pq = pd.read_parquet(tmp_path / "out" / "summary.parquet").iloc[0]
    assert pq["max_elongation.s"] == row["max_elongation.s"]


@pytest.mark.parametrize("kernel", ["generic", "generated"])
def test_fast_kernels_give_the_reference_numbers_for_a_breaking_spring(kernel: str) -> None:
    """A spring that breaks, on each fast kernel (the generated one runs it itself, as a part of the one
    model of :func:`models.generated_parts`): bitwise the reference's failure time, max elongation and
    velocities (the full twin cases are in test_kernel_twins)."""
    model = breaking_spring()
    ref, batch, _ = run_model(model, kernel="reference")
    assert generated.unsupported(batch) is None
    assert choice.pick(batch, (), None, kernel) == kernel
    got = generated_part("break", model) if kernel == "generated" else run_model(model, kernel=kernel)[0]
    assert np.isfinite(ref.spring_fail_time[0, 0])
    assert got.spring_fail_time[0, 0] == ref.spring_fail_time[0, 0]
    assert got.max_elongation[0, 0] == ref.max_elongation[0, 0]
    assert np.array_equal(got.histories["velocity"], ref.histories["velocity"], equal_nan=True)


BAD = {
    "tangent-not-below-stiffness": (
        {"type": "elastoplastic", "stiffness": 100.0, "tangent_stiffness": 100.0, "yield_force": 1.0},
        {},
        "springs.s.material.tangent_stiffness",
        "tangent_stiffness must be below stiffness",
    ),
    "damper-with-initial-elongation": (
        {"type": "damper", "damping": 1.0},
        {"initial_elongation": 0.1},
        "springs.s.initial_elongation",
        "initial elongation",
    ),
    "failure-below-initial-elongation": (
        {"type": "linear_elastic", "stiffness": 1.0},
        {"initial_elongation": 0.1, "failure": {"tension": 0.05}},
        "springs.s.failure.tension",
        "above initial_elongation",
    ),
    "compression-failure-positive": (
        {"type": "linear_elastic", "stiffness": 1.0},
        {"failure": {"compression": 0.05}},
        "springs.s.failure.compression",
        "less than 0",
    ),
    "damper-curve-decreasing": (
        {
            "type": "nonlinear_damper",
            "curve": "c",
            "_curves": {"c": {"x": [-1.0, 0.0, 1.0], "y": [1.0, 0.0, -1.0]}},
        },
        {},
        "springs.s.material.curve",
        "must be increasing",
    ),
    "crush-curve-off-origin": (
        {
            "type": "crush",
            "loading": "c",
            "unloading_stiffness": 1.0,
            "_curves": {"c": {"x": [-1.0, 0.0], "y": [-2.0, -1.0]}},
        },
        {},
        "springs.s.material.loading",
        "initial_elongation",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_v2_spring_input_is_refused_with_field_and_expectation(case: str) -> None:
    material, options, field, text = BAD[case]
    model = _one_spring(material, 1.0, **options)
    with pytest.raises(InputError) as err:
        parse_model(loads_yaml(yaml.safe_dump(model, sort_keys=False), file="bad.yaml"))
    found = [p for p in err.value.problems if p.field == field]
    assert found, [(p.field, p.message) for p in err.value.problems]
    assert text in found[0].message and found[0].line is not None


def test_study_axis_values_that_break_a_v2_rule_are_refused_per_variant() -> None:
    """The per-variant check of a study's axis values (parameter_checks.check_parameters) holds the same rules as the
    schema: a failure elongation on the wrong side of the initial elongation, a tangent stiffness not below
    the stiffness, a damper curve point that takes the curve off the origin (the reason names
    initial_elongation). Valid columns pass."""
    model = _one_spring(
        {"type": "elastoplastic", "stiffness": 100.0, "tangent_stiffness": 10.0, "yield_force": 1.0},
        1.0,
        1.0,
        initial_elongation=0.01,
        failure={"tension": 0.05},
    )
    plan = model_plan(model)
    topo = plan.topology
    P = np.repeat(plan.base[:, None], 4, axis=1)
    apply_axis(P, topo.paths["springs.s.failure.tension"], np.array([0.05, 0.005, 0.05, 0.05]))
    apply_axis(P, topo.paths["springs.s.material.tangent_stiffness"], np.array([10.0, 10.0, 100.0, 10.0]))
    apply_axis(P, topo.paths["springs.s.initial_elongation"], np.array([0.01, 0.01, 0.01, -0.2]))
    check = check_parameters(topo, P, plan.interval)
    assert check.bad.tolist() == [False, True, True, False]
    assert (
        "springs.s.failure.tension: expected an elongation above initial_elongation (0.01)" in check.reason(1)
    )
    assert (
        "springs.s.material.tangent_stiffness: expected a tangent_stiffness >= 0 and below stiffness"
        in check.reason(2)
    )

    damper = _one_spring(
        {
            "type": "nonlinear_damper",
            "curve": "c",
            "_curves": {"c": {"x": [-1.0, 0.0, 1.0], "y": [-1.0, 0.0, 1.0]}},
        },
        1.0,
        1.0,
    )
    plan = model_plan(damper)
    P = np.repeat(plan.base[:, None], 2, axis=1)
    apply_axis(P, plan.topology.paths["curves.c.y.1"], np.array([0.0, 0.5]))
    check = check_parameters(plan.topology, P, plan.interval)
    assert check.bad.tolist() == [False, True]
    assert "must pass through the origin" in check.reason(1) and "initial_elongation" in check.reason(1)


@pytest.mark.parametrize("kernel", ["reference", "generic", "generated"])
def test_a_spring_only_in_tension_has_a_max_crush_of_plus_zero(kernel: str) -> None:
    """A spring stretched from its rest length (x = sin(10 t) / 10, up to t = 0.1 s) never shortens:
    max_crush is +0.0 on every kernel (the reference's np.maximum(0.0, -0.0) gave -0.0, printed "-0.0"),
    max_elongation sin(1) / 10 (closed form, 1e-3)."""
    from helpers import same_bits

    out = generated_part("pull", PULL) if kernel == "generated" else run_model(PULL, kernel=kernel)[0]
    assert same_bits(out.max_crush, np.zeros_like(out.max_crush))
    assert out.max_elongation[0, 0] == pytest.approx(0.1 * math.sin(1.0), rel=1e-3)


def test_results_files_hold_no_negative_zero(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The reference kernel's acceleration history of tests/test_kernel_twins.py's every-material model
    holds -0.0 samples (a zero force divided by a mass, with its sign); results.nc stores them as +0.0
    and every value is the kernel's (second implementation: the kernel output itself, copied as the
    run's chunk returns it, before anything writes it; one reference run, two before)."""
    import netCDF4

    from crashstudy.run import runner
    from twin_models import one_d_materials

    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(one_d_materials(False)))
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "reference")
    computed: list[np.ndarray] = []
    real = runner.run_chunk

    def kept(*args: Any, **kwargs: Any) -> Any:
        res = real(*args, **kwargs)
        computed.append(res.out.histories["acceleration"].copy())
        return res

    monkeypatch.setattr(runner, "run_chunk", kept)
    runner.simulate(str(path), tmp_path / "out").close()
    assert len(computed) == 1
    acc = computed[0]  # what the run computed
    assert np.any((acc == 0.0) & np.signbit(acc))  # the case has what the files must not show
    with netCDF4.Dataset(tmp_path / "out" / "results.nc") as nc:
        stored = np.moveaxis(np.asarray(nc.variables["acceleration"][:]), 0, -1)
        assert np.array_equal(stored, acc, equal_nan=True)
        for name, var in nc.variables.items():
            if var.dtype.kind == "f":
                values = np.ma.filled(var[:], np.nan)
                assert not np.any((values == 0.0) & np.signbit(values)), name


def test_a_preload_against_a_curve_that_pushes_the_wrong_way_is_refused() -> None:
    """Found by the model generator (2026-11-25): a nonlinear_elastic curve with F = -514 e (positive force
    in compression) preloaded to e0 = -0.0312 stores IE0 = -257 e0^2 < 0, and the instability test failed at
    t = 0 (the kernels now scale it by KE0 + |IE0|). Such a curve is a negative stiffness, a sign slip: since
    issue 23 item 2 it is refused before anything runs, naming the curve and its first wrong point."""
    model = {
        "name": "wrong-way",
        "curves": {"c": {"x": [-0.5, 0.0, 0.5], "y": [257.0, 0.0, -257.0]}},
        "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [-1.0], "mass": 0.5}},
        "springs": {
            "s": {
                "nodes": ["b", "a"],
                "material": {"type": "nonlinear_elastic", "curve": "c"},
                "initial_elongation": -0.0312,
            }
        },
        "initial_velocity": {"b": [1.0]},
        "end_time": 0.002,
        "output": {"histories": ["internal_energy"]},
    }
    with pytest.raises(InputError) as err:
        run_model(model)
    assert "curve 'c' has force 257 at x = -0.5 (point 0)" in str(err.value)
