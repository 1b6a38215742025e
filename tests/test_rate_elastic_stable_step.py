"""The stable step of a rate-stiff ``rate_elastic`` spring (arrays/timestep.py, rule ``rate_curves``).

A spring whose force rises steeply with the elongation RATE acts as a damper, ``c = dF/d(rate)``; an
explicit damper is stable only for ``dt <= (2 / omega) (sqrt(1 + xi^2) - xi)``. The bound from the
steepest curve slope alone let a rate-stiff table run far above that limit.

The model: a 1 kg mass on a spring to an anchor, two curves: the soft ``K1 e`` at rate 0 and, at rate
``R``, a plateau ``K1 e + F1`` beyond ``|e| >= D`` (steep ``K1 + F1 / D`` inside). Crushed beyond ``D``
at rates below ``R`` the force is ``K1 e + (F1 / R) de/dt``: exactly a linear spring-damper with
``c = F1 / R``. Preloaded to ``E0`` at rest and pushed by a constant load ``P``, it creeps
(overdamped, so the rate never changes sign) towards ``-P / K1``: a closed form.

Before the rule the automatic step (tolerance 1e-3) was 6.25e-5 s, ``c dt / m = 63``: the run ended
0.38 m away from the closed form's 1.5e-5 m of creep (the energy balance did not see it: central
difference balances the work of any force it applies). With it, dt = 2.2e-7 s and the run follows
the closed form to 4e-13 m.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from helpers import model_batch, run_model

K1, F1, D, R, M, P, E0 = 100.0, 1.0e4, 0.01, 0.1, 1.0, 50.0, -0.2  # N/m, N, m, m/s, kg, N, m
C = F1 / R  # the damper it is [N s/m]
KMAX = K1 + F1 / D  # its steepest curve slope [N/m]


def _model(time_step: dict[str, float], end_time: float = 0.005) -> dict[str, Any]:
    return {
        "name": "rate-stiff",
        "curves": {
            "soft": {"x": [-1.0, 0.0, 1.0], "y": [-K1, 0.0, K1]},
            "plateau": {
                "x": [-1.0, -D, 0.0, D, 1.0],
                "y": [-(K1 + F1), -(K1 * D + F1), 0.0, K1 * D + F1, K1 + F1],
            },
        },
        "nodes": {"anchor": {"position": [0.0], "fixed": True}, "end": {"position": [1.0], "mass": M}},
        "springs": {
            "s": {
                "nodes": ["anchor", "end"],
                "initial_elongation": E0,
                "material": {
                    "type": "rate_elastic",
                    "curves": [{"rate": 0.0, "curve": "soft"}, {"rate": R, "curve": "plateau"}],
                },
            }
        },
        "loads": [{"node": "end", "force": [-P]}],
        "end_time": end_time,
        "time_step": time_step,
        "output": {"interval": 0.001, "histories": ["spring_elongation"]},
    }


def _creep(t: np.ndarray) -> np.ndarray:
    """M e'' = -K1 e - C e' - P, e(0) = E0, e'(0) = 0 (overdamped: C^2 > 4 K1 M)."""
    root = np.sqrt(C * C - 4.0 * K1 * M)
    l1, l2 = (-C + root) / (2.0 * M), (-C - root) / (2.0 * M)
    eeq = -P / K1
    b = (E0 - eeq) * l1 / (l1 - l2)
    return eeq + (E0 - eeq - b) * np.exp(l1 * t) + b * np.exp(l2 * t)


def _limit(k: float, c: float) -> float:
    """The spring-damper's stable step as the nodal bound states it (omega^2 = 2 k / m, gamma = 2 c / m),
    with the kernels' 1 % margin."""
    omega, gamma = np.sqrt(2.0 * k / M), 2.0 * c / M
    xi = gamma / omega
    return float(0.99 * (2.0 / omega) * (np.sqrt(1.0 + xi * xi) - xi))


def test_rate_stiff_spring_follows_the_closed_form_at_the_automatic_step() -> None:
    """Default step (tolerance 1e-3): the creep within 1e-10 m of the closed form (it moves 1.5e-5 m;
    measured 4e-13; 0.38 m before the damping term). The step is the subject (arrays/timestep.py, the same
    for every kernel): its 22700 steps run on the generic compiled kernel, which tests/test_kernel_twins.py
    holds bitwise equal to the NumPy reference on rate_elastic springs (the reference took 8 s here)."""
    out, _, _ = run_model(_model({"tolerance": 1.0e-3}), kernel="generic")
    e = out.histories["spring_elongation"][:, 0, 0]
    t = np.arange(len(e)) * 0.001
    assert out.status[0] == 0
    assert np.all(np.diff(e) < 0)  # it creeps inwards: the rate never changes sign, the closed form holds
    np.testing.assert_allclose(e, _creep(t), rtol=0.0, atol=1e-10)


@pytest.mark.parametrize("second", [False, True])
def test_critical_step_is_the_spring_damper_limit(second: bool) -> None:
    """A fixed dt just below the closed-form limit of k = KMAX, c = F1 / R runs, just above it is
    refused; the same for a linear_elastic KMAX and a damper C side by side (the second
    implementation: the damper's own rule). The old bound (KMAX alone) was 11x higher."""
    model = _model({"dt": 1.0e-6})
    if second:
        model["springs"] = {
            "k": {"nodes": ["anchor", "end"], "material": {"type": "linear_elastic", "stiffness": KMAX}},
            "c": {"nodes": ["anchor", "end"], "material": {"type": "damper", "damping": C}},
        }
    limit = _limit(KMAX, C)
    assert limit < _limit(KMAX, 0.0) / 10.0
    for factor, refused in ((1.0 - 1e-9, 0), (1.0 + 1e-9, 1)):
        model["time_step"] = {"dt": factor * limit}
        batch, _ = model_batch(model)
        assert batch.invalid[0] == refused, (factor, limit)
