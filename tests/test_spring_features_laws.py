"""SPEC v2 spring materials against closed forms: ``elastoplastic`` (LS-DYNA S03) and
``nonlinear_damper`` (S05).

Every model is a single mass on one spring (1-D, and 2-D along a slanted axis where the feature has a 2-D
form), so the truth is a formula of mechanics, written here from docs/format.md, not from the kernels.
Most tests run the NumPy reference; tests/test_kernel_twins.py holds both fast kernels bitwise equal to it
on every feature."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from helpers import run_model
from lanes import run_lanes
from models import one_spring as _one_spring
from spring_feature_runs import FY, KT, MASS, K, _along

# --------------------------------------------------------------------------------------------------
# elastoplastic
# --------------------------------------------------------------------------------------------------


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
