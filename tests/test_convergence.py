"""Convergence of the central-difference solver and the promise of ``time_step: {tolerance: ...}``.

Every test compares with an independent truth (the scipy reference of ``tests/reference_scipy.py``,
a closed form, or the solver itself at a step 1000x below critical) and states its tolerance.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest

from helpers import run_model
from reference_scipy import solve_reference

G = 9.80665  # m/s^2
#: the kernel of every run here: the generic compiled one (bitwise the NumPy reference, test_kernel_twins); the
#: automatic choice ("compiled") took the reference, 0.4-1.2 s a run, whenever it expected it to finish within
#: a compiled kernel's load time, even with the generic kernel loaded
FAST = "generic"
INTERVAL = 0.01  # s, history sampling of the convergence runs; every step below divides it
STEPS = (2.0e-3, 1.0e-3, 5.0e-4)  # s: h, h/2, h/4 (all below the critical step of the chains)

# A hardening curve F = k e + k3 e^3 tabulated on 401 knots: the kinks are small enough that the
# second-order behaviour is not blurred by them (41 knots give orders 1.82-2.10).
_E = np.linspace(-0.05, 0.05, 401)
HARDENING = {"x": [float(v) for v in _E], "y": [float(v) for v in 1.0e4 * _E + 4.0e7 * _E**3]}


def _two_mass_chain(kind: str) -> dict[str, Any]:
    """ground -- s1 -- a (1 kg) -- s2 (5e3 N/m) -- b (0.5 kg), b started at 2 m/s; s1 linear or hardening."""
    s1 = (
        {"type": "linear_elastic", "stiffness": 1.0e4}
        if kind == "linear"
        else {"type": "nonlinear_elastic", "curve": "hardening"}
    )
    return {
        "name": f"chain-{kind}",
        "curves": {"hardening": HARDENING},
        "nodes": {
            "ground": {"position": [0.0], "fixed": True},
            "a": {"position": [1.0], "mass": 1.0},
            "b": {"position": [2.0], "mass": 0.5},
        },
        "springs": {
            "s1": {"nodes": ["ground", "a"], "material": s1},
            "s2": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 5.0e3}},
        },
        "initial_velocity": {"b": [2.0]},
        "end_time": 0.2,
        "output": {"interval": INTERVAL},
    }


def _position_errors(model: dict[str, Any], reference: np.ndarray) -> np.ndarray:
    """Max position error [m] over the sampled history of the free nodes, one per step of STEPS."""
    errors = []
    for h in STEPS:
        out, batch, _ = run_model(dict(model, time_step={"dt": h}), FAST)
        assert batch.dt[0] == h, "the step must not be snapped: it divides the output interval"
        assert out.status[0] == 0
        errors.append(np.max(np.abs(out.histories["position"][:, 1:, 0, 0] - reference)))
    return np.array(errors)


@pytest.mark.parametrize("kind", ["linear", "nonlinear"])
def test_central_difference_converges_at_second_order(kind: str) -> None:
    """Positions of a 2-mass chain against DOP853 (rtol 1e-8) with fixed dt 2, 1, 0.5 ms: the observed
    orders log2(e(h) / e(h/2)) are within [1.8, 2.2].

    Measured: linear 2.004, 2.001; nonlinear (hardening curve) 1.985, 2.000 (errors 6.2e-4, 1.6e-4, 3.9e-5 m).
    The reference at rtol 1e-8 is within 4.4e-8 m of DOP853 at rtol 1e-10 (1/900 of the smallest error
    above; the orders move by 1e-3) and takes half its time (the 401-knot curve: 4 s instead of 8 s CPU).
    """
    model = _two_mass_chain(kind)
    t = np.arange(round(model["end_time"] / INTERVAL) + 1) * INTERVAL
    ref = solve_reference(model, t_eval=t, method="DOP853", rtol=1e-8, atol=1e-10)
    errors = _position_errors(model, ref.position[:, 1:, 0])
    orders = np.log2(errors[:-1] / errors[1:])
    assert np.all((orders >= 1.8) & (orders <= 2.2)), f"errors {errors}, orders {orders}"


M_D, K_D, V_D, ZETA = 1.0, 1.0e4, 2.0, 0.1
W_D = float(np.sqrt(K_D / M_D))
WD_D = W_D * float(np.sqrt(1.0 - ZETA**2))


def _damped(**extra: Any) -> dict[str, Any]:
    """Spring k and damper c = 2 zeta sqrt(k m) between a fixed node and a mass started at +v0."""
    model: dict[str, Any] = {
        "name": "damped",
        "nodes": {"ground": {"position": [0.0], "fixed": True}, "mass": {"position": [1.0], "mass": M_D}},
        "springs": {
            "spring": {"nodes": ["ground", "mass"], "material": {"type": "linear_elastic", "stiffness": K_D}},
            "damper": {
                "nodes": ["ground", "mass"],
                "material": {"type": "damper", "damping": 2.0 * ZETA * float(np.sqrt(K_D * M_D))},
            },
        },
        "initial_velocity": {"mass": [V_D]},
        "end_time": 0.1,
        "output": {"interval": INTERVAL},
    }
    model.update(extra)
    return model


def _damped_peak_force() -> float:
    """k x_max of the closed form x(t) = (v0/wd) exp(-zeta w t) sin(wd t), at tan(wd t) = wd / (zeta w)."""
    t = np.arctan(np.sqrt(1.0 - ZETA**2) / ZETA) / WD_D
    return K_D * V_D / WD_D * float(np.exp(-ZETA * W_D * t) * np.sin(WD_D * t))


def test_damped_oscillator_converges_at_second_order() -> None:
    """Linear spring + damper (zeta 0.1) against the closed form, fixed dt 2, 1, 0.5 ms: observed orders
    within [1.8, 2.2] like the undamped chain.

    Measured: orders 2.07, 2.04 (errors 1.3e-4, 3.2e-5, 7.7e-6; with the damper driven by v^{n-1/2} alone
    they were 1.10, 1.05).
    """
    model = _damped()
    t = np.arange(round(model["end_time"] / INTERVAL) + 1) * INTERVAL
    exact = V_D / WD_D * np.exp(-ZETA * W_D * t) * np.sin(WD_D * t) + 1.0
    errors = _position_errors(model, exact[:, None])
    orders = np.log2(errors[:-1] / errors[1:])
    assert np.all((orders >= 1.8) & (orders <= 2.2)), f"errors {errors}, orders {orders}"


# --------------------------------------------------------------------------------------------------
# Tolerance mode
# --------------------------------------------------------------------------------------------------

TOLERANCES = (1.0e-2, 1.0e-3, 1.0e-4)


def _linear_spring(tolerance: float) -> dict[str, Any]:
    """2 kg on a 2e4 N/m spring at 1 m/s; histories off and a coarse interval so the tolerance sets dt."""
    return {
        "name": "linear-spring",
        "nodes": {"anchor": {"position": [0.0], "fixed": True}, "body": {"position": [0.1], "mass": 2.0}},
        "springs": {
            "spring": {
                "nodes": ["anchor", "body"],
                "material": {"type": "linear_elastic", "stiffness": 2.0e4},
            }
        },
        "initial_velocity": {"body": [1.0]},
        "end_time": 0.3,
        "time_step": {"tolerance": tolerance},
        "output": {"interval": 0.03, "histories": "none"},
    }


@pytest.mark.parametrize("tolerance", TOLERANCES)
def test_tolerance_mode_keeps_linear_spring_peak_force_error_below_twice_the_tolerance(
    tolerance: float,
) -> None:
    """Peak force against v0 sqrt(k m) = 200 N: relative error < 2 x tolerance.

    Measured: 0.50, 0.48, 0.50 x tolerance.
    """
    out, _, _ = run_model(_linear_spring(tolerance), FAST)
    err = abs(out.peak_force[0, 0] / (1.0 * np.sqrt(2.0e4 * 2.0)) - 1.0)
    assert err < 2.0 * tolerance, f"peak force error {err:.3g} at tolerance {tolerance}"


HELICOPTER: dict[
    str, Any
] = {  # the two-spring helicopter sub-floor drop of studies/models, to max crush and rebound
    "name": "helicopter-like",
    "curves": {
        "underfloor-loading": {
            "x": [-0.5, -0.223, -0.045, -0.009, 0.0, 10.0],
            "y": [-76000.0, -57200.0, -70000.0, -40000.0, 0.0, 5000.0],
        },
        "underfloor-unloading": {"x": [-0.009, 0.0, 0.009], "y": [-40000.0, 0.0, 40000.0]},
        "cabin-loading": {
            "x": [-0.3, -0.27, -0.225, -0.01, 0.0],
            "y": [-1000000.0, -500000.0, -150000.0, -150000.0, 0.0],
        },
        "cabin-unloading": {"x": [-0.006, 0.0, 0.006], "y": [-170000.0, 0.0, 170000.0]},
    },
    "nodes": {
        "ground": {"position": [0.0, 0.0], "fixed": True},
        "transmission": {"position": [0.0, 0.3], "mass": 100.0},
        "troop_compartment": {"position": [0.0, 0.9], "mass": 300.0},
    },
    "springs": {
        "underfloor": {
            "nodes": ["ground", "transmission"],
            "material": {
                "type": "general_nonlinear",
                "loading": "underfloor-loading",
                "unloading": "underfloor-unloading",
                "tension_yield": 5000.0,
                "compression_yield": -40000.0,
            },
        },
        "cabin": {
            "nodes": ["transmission", "troop_compartment"],
            "material": {
                "type": "general_nonlinear",
                "loading": "cabin-loading",
                "unloading": "cabin-unloading",
                "compression_yield": -150000.0,
            },
        },
    },
    "initial_velocity": {"transmission": [0.0, -8.2], "troop_compartment": [0.0, -8.2]},
    "gravity": [0.0, -G],
    "end_time": 0.1,
    # coarse sampling, histories off: the tolerance, not the interval, sets the step
    "output": {"interval": 0.01, "histories": "none"},
}


@functools.cache
def _helicopter_converged() -> np.ndarray:
    """Peak forces [N] at safety_factor 0.001 (dt 2.5e-6 s, 40 000 steps); half that step moves them 3e-6."""
    out, _, _ = run_model(dict(HELICOPTER, time_step={"safety_factor": 0.001}), FAST)
    assert out.status[0] == 0
    return out.peak_force[:, 0].copy()


@pytest.mark.parametrize("tolerance", TOLERANCES)
def test_tolerance_mode_keeps_helicopter_peak_force_error_below_twice_the_tolerance(tolerance: float) -> None:
    """Both general_nonlinear springs' peak forces against the converged run: relative error < 2 x tolerance.

    Measured (underfloor, cabin) x tolerance: 1e-2: 0.06, 0.15; 1e-3: 0.27, 0.05; 1e-4: 1.20, 0.12.
    """
    converged = _helicopter_converged()
    out, _, _ = run_model(dict(HELICOPTER, time_step={"tolerance": tolerance}), FAST)
    err = np.abs(out.peak_force[:, 0] / converged - 1.0)
    assert out.status[0] == 0
    assert np.all(err < 2.0 * tolerance), f"peak force errors {err} at tolerance {tolerance}"


@pytest.mark.parametrize(
    "tolerance",
    [
        pytest.param(1.0e-2),
        pytest.param(1.0e-3),
        pytest.param(1.0e-4),
    ],
)
def test_tolerance_mode_keeps_damped_oscillator_peak_force_error_below_twice_the_tolerance(
    tolerance: float,
) -> None:
    """Spring + damper (zeta 0.1): peak spring force against the closed form, relative error < 2 x tolerance.

    Measured: 0.02, 0.11, 0.14 x tolerance (0.65, 2.6, 9.6 x while the damper was first order).
    """
    model = _damped(time_step={"tolerance": tolerance}, output={"interval": INTERVAL, "histories": "none"})
    out, _, _ = run_model(model, FAST)
    err = abs(out.peak_force[0, 0] / _damped_peak_force() - 1.0)
    assert err < 2.0 * tolerance, (
        f"peak force error {err:.3g} = {err / tolerance:.2f} x tolerance {tolerance}"
    )
