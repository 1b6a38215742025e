"""The SPEC v2 spring option ``initial_elongation`` (the pre-stressed defect, with IE0 in the energy
balance) against closed forms, and preloads that are input errors.

Every model is a single mass on one spring (1-D, and 2-D along a slanted axis where the feature has a 2-D
form), so the truth is a formula of mechanics, written here from docs/format.md, not from the kernels.
Most tests run the NumPy reference; tests/test_kernel_twins.py holds both fast kernels bitwise equal to it
on every feature."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from crashstudy.errors import InputError
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import loads_yaml
from helpers import run_model
from models import one_spring as _one_spring
from spring_feature_runs import FY, KT, MASS, K, _along

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
