"""Proofs that the scipy reference solver (``tests/reference_scipy.py``) is itself right.

Every test compares the reference with a closed-form solution or with an exact invariant (energy,
mirror symmetry); the tolerance used is stated in each test. Units are SI throughout.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy.optimize import brentq

try:  # ``tests`` as a plain directory on sys.path (pytest's default rootdir-relative import) ...
    from reference_scipy import RefResult, solve_reference
except ImportError:  # ... or as a package, when a ``tests/__init__.py`` exists.
    from tests.reference_scipy import RefResult, solve_reference  # type: ignore[no-redef]


def _crossings(
    res: RefResult, fn: Callable[[RefResult], np.ndarray], t0: float, t1: float, n: int = 4001
) -> list[float]:
    """Times [s] in ``(t0, t1)`` where ``fn`` of the dense solution changes sign (root-polished)."""
    grid = np.linspace(t0, t1, n)
    values = fn(res.sample(grid))
    roots = []
    for k in np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[0]:
        roots.append(brentq(lambda tau: float(fn(res.sample([tau]))[0]), grid[k], grid[k + 1], xtol=1e-15))
    return roots


def _energy_error(res: RefResult) -> float:
    """Largest energy-balance error over the run, relative to the largest ``KE0 + |W_ext|`` reached.

    (A pointwise ``relative_error`` is ill-conditioned where KE0 = 0 and W_ext passes through 0.)
    """
    balance = res.sample(np.linspace(0.0, res.end_time, 4001)).energy_balance()
    ke0 = balance["kinetic"][0]
    return float(np.max(np.abs(balance["error"])) / np.max(ke0 + np.abs(balance["external_work"])))


def _spring_mass(
    k: float = 1.0e5, m: float = 10.0, v0: float = -5.0, drawn: float = 0.01, end: float = 0.1
) -> dict[str, Any]:
    return {
        "name": "spring-mass",
        "units": "SI",
        "nodes": {"ground": {"position": [0.0], "fixed": True}, "mass": {"position": [drawn], "mass": m}},
        "springs": {
            "s": {"nodes": ["ground", "mass"], "material": {"type": "linear_elastic", "stiffness": k}}
        },
        "initial_velocity": {"mass": [v0]},
        "end_time": end,
    }


# --------------------------------------------------------------------------------------------------
# 1. Undamped linear spring-mass
# --------------------------------------------------------------------------------------------------


def test_linear_spring_mass_peak_force_period_and_history() -> None:
    """Peak force ``|v0| sqrt(k m)`` to 1e-9 rel; period ``2 pi sqrt(m/k)`` to 1e-9 rel; u(t) to 1e-9 of amplitude."""
    k, m, v0 = 1.0e5, 10.0, -5.0
    omega = np.sqrt(k / m)
    period = 2.0 * np.pi / omega
    amplitude = abs(v0) / omega  # 0.05 m, five times the drawn length: 1-D crush may exceed it
    res = solve_reference(
        _spring_mass(k, m, v0, drawn=0.01, end=2.5 * period), t_eval=np.linspace(0, 2.5 * period, 2001)
    )

    assert res.peak_force("s") == pytest.approx(abs(v0) * np.sqrt(k * m), rel=1e-9)
    peaks = res.dense_peaks()
    assert peaks["max_crush"]["s"] == pytest.approx(amplitude, rel=1e-9)
    assert peaks["peak_acceleration"]["mass"] == pytest.approx(abs(v0) * omega, rel=1e-9)
    assert peaks["peak_acceleration"]["ground"] == 0.0
    quarters = peaks["time_of"]["peak_force"]["s"] / (0.25 * period)  # any of the equal maxima
    assert round(quarters) % 2 == 1 and abs(quarters - round(quarters)) < 1e-6

    u_exact = v0 / omega * np.sin(omega * res.t)
    np.testing.assert_allclose(res.displacement[:, 1, 0], u_exact, rtol=0, atol=1e-9 * amplitude)
    np.testing.assert_allclose(res.spring_force[:, 0], k * u_exact, rtol=0, atol=1e-9 * k * amplitude)
    np.testing.assert_allclose(
        res.acceleration[:, 1, 0], -k / m * u_exact, rtol=0, atol=1e-9 * omega * abs(v0)
    )
    assert np.all(res.position[:, 0, 0] == 0.0) and np.all(res.velocity[:, 0, 0] == 0.0)

    roots = _crossings(res, lambda r: r.spring_force[:, 0], 0.1 * period, 2.5 * period)
    assert len(roots) == 4  # T/2, T, 3T/2, 2T
    assert roots[3] - roots[1] == pytest.approx(period, rel=1e-9)
    assert 2.0 * (roots[1] - roots[0]) == pytest.approx(period, rel=1e-9)


def test_2d_axial_motion_matches_1d() -> None:
    """A 2-D spring moving along its axis equals the 1-D model: forces to 1e-9 of the peak.

    The drawn length (0.2 m) exceeds the 0.05 m amplitude: in 2-D the spring must not pass through zero.
    """
    one = _spring_mass(drawn=0.2, end=0.05)
    two = copy.deepcopy(one)
    two["nodes"] = {
        "ground": {"position": [0.3, 0.0], "fixed": True},
        "mass": {"position": [0.3, 0.2], "mass": 10.0},
    }
    two["initial_velocity"] = {"mass": [0.0, -5.0]}
    t = np.linspace(0.0, 0.05, 501)
    r1, r2 = solve_reference(one, t_eval=t), solve_reference(two, t_eval=t)
    peak = r1.peak_force("s")
    np.testing.assert_allclose(r2.spring_force, r1.spring_force, rtol=0, atol=1e-9 * peak)
    np.testing.assert_allclose(r2.displacement[:, :, 1], r1.displacement[:, :, 0], rtol=0, atol=1e-9 * 0.05)
    np.testing.assert_allclose(r2.position[:, :, 0], 0.3, rtol=0, atol=1e-14)
    assert r2.peak_force("s") == pytest.approx(peak, rel=1e-10)


def test_nonlinear_curve_that_is_linear_matches_linear_elastic_with_extrapolation() -> None:
    """A two-point curve of slope k (extrapolated 50x beyond its ends) gives the linear result to 1e-9."""
    lin = _spring_mass(end=0.05)
    nl = copy.deepcopy(lin)
    nl["curves"] = {"c": {"x": [-0.001, 0.001], "y": [-100.0, 100.0]}}
    nl["springs"]["s"]["material"] = {"type": "nonlinear_elastic", "curve": "c"}
    r1, r2 = solve_reference(lin), solve_reference(nl)
    np.testing.assert_allclose(r2.spring_force, r1.spring_force, rtol=0, atol=1e-9 * r1.peak_force("s"))
    np.testing.assert_allclose(r2.energy(), r1.energy(), rtol=1e-9)


# --------------------------------------------------------------------------------------------------
# 2. Gravity, fixed directions and load curves
# --------------------------------------------------------------------------------------------------


def test_gravity_on_a_node_fixed_in_x_gives_the_suddenly_applied_load_response() -> None:
    """u_y = (m g / k)(1 - cos wt) to 1e-9 of m g / k; x stays put; peak force 2 m g to 1e-9 rel."""
    k, m, g = 4.0e4, 4.0, 9.81
    omega = np.sqrt(k / m)
    end = 3.0 * 2.0 * np.pi / omega
    model = {
        "nodes": {
            "top": {"position": [0.0, 1.0], "fixed": ["x", "y"]},
            "mass": {"position": [0.0, 0.5], "mass": m, "fixed": ["x"]},
        },
        "springs": {"s": {"nodes": ["top", "mass"], "material": {"type": "linear_elastic", "stiffness": k}}},
        "gravity": [3.0, -g],  # the x part acts on no free direction
        "end_time": end,
    }
    res = solve_reference(model)
    static = m * g / k
    np.testing.assert_allclose(
        res.displacement[:, 1, 1], -static * (1.0 - np.cos(omega * res.t)), rtol=0, atol=1e-9 * static
    )
    assert np.all(res.displacement[:, 1, 0] == 0.0)
    assert res.peak_force("s") == pytest.approx(2.0 * m * g, rel=1e-9)
    assert _energy_error(res) < 1e-9


def test_constant_load_without_curve() -> None:
    """A load with no curve acts for all t: u = F/k (1 - cos wt) to 1e-9 of F/k; peak force 2F to 1e-9 rel."""
    k, m, f = 1.0e5, 10.0, -250.0
    omega = np.sqrt(k / m)
    model = _spring_mass(k, m, 0.0, end=0.05)
    model["loads"] = [{"node": "mass", "force": [f]}]
    res = solve_reference(model)
    exact = f / k * (1.0 - np.cos(omega * res.t))
    np.testing.assert_allclose(res.displacement[:, 1, 0], exact, rtol=0, atol=1e-9 * abs(f) / k)
    assert res.peak_force("s") == pytest.approx(2.0 * abs(f), rel=1e-9)
    assert res.dense_peaks()["max_crush"]["s"] == pytest.approx(2.0 * abs(f) / k, rel=1e-9)


def test_rectangular_load_pulse_from_a_time_curve() -> None:
    """Pulse of length td: u = F/k (1 - cos wt) during, F/k (cos w(t - td) - cos wt) after; to 1e-9 of F/k.

    The curve is zero outside its x range and is cut at t = td, so this also proves that the
    integration restarts at every load knot instead of stepping over the switch-off.
    """
    k, m, f = 1.0e5, 10.0, 250.0
    omega = np.sqrt(k / m)
    td = 0.37 * 2.0 * np.pi / omega
    end = 2.0 * 2.0 * np.pi / omega
    model = _spring_mass(k, m, 0.0, end=end)
    model["curves"] = {"pulse": {"x": [0.0, td], "y": [1.0, 1.0]}}
    model["loads"] = [{"node": "mass", "force": [f], "curve": "pulse"}]
    res = solve_reference(model, t_eval=np.linspace(0.0, end, 3001))
    t = res.t
    exact = np.where(t <= td, 1.0 - np.cos(omega * t), np.cos(omega * (t - td)) - np.cos(omega * t)) * f / k
    np.testing.assert_allclose(res.displacement[:, 1, 0], exact, rtol=0, atol=1e-9 * f / k)
    free_amp = 2.0 * abs(np.sin(0.5 * omega * td)) * f / k
    assert res.dense_peaks()["peak_force"]["s"] == pytest.approx(
        k * max(free_amp, 2.0 * f / k * (omega * td >= np.pi)), rel=1e-9
    )
    assert _energy_error(res) < 1e-9


# --------------------------------------------------------------------------------------------------
# 3. Damped oscillator
# --------------------------------------------------------------------------------------------------


def test_underdamped_oscillator_closed_form() -> None:
    """Spring + parallel damper, zeta = 0.05: x(t) to 1e-9 of v0/w; damper force to 1e-9 of c v0; energy balance 1e-9."""
    k, m, zeta, v0 = 8.0e4, 2.0, 0.05, 3.0
    omega = np.sqrt(k / m)
    c = 2.0 * zeta * np.sqrt(k * m)
    omega_d = omega * np.sqrt(1.0 - zeta**2)
    end = 5.0 * 2.0 * np.pi / omega
    model = {
        "nodes": {"wall": {"position": [0.0], "fixed": True}, "m": {"position": [0.2], "mass": m}},
        "springs": {
            "spring": {"nodes": ["wall", "m"], "material": {"type": "linear_elastic", "stiffness": k}},
            "damper": {"nodes": ["wall", "m"], "material": {"type": "damper", "damping": c}},
        },
        "initial_velocity": {"m": [v0]},
        "end_time": end,
    }
    res = solve_reference(model, t_eval=np.linspace(0.0, end, 2001))
    t = res.t
    decay = np.exp(-zeta * omega * t)
    x = decay * v0 / omega_d * np.sin(omega_d * t)
    v = decay * v0 * (np.cos(omega_d * t) - zeta * omega / omega_d * np.sin(omega_d * t))
    np.testing.assert_allclose(res.displacement[:, 1, 0], x, rtol=0, atol=1e-9 * v0 / omega)
    np.testing.assert_allclose(res.velocity[:, 1, 0], v, rtol=0, atol=1e-9 * v0)
    np.testing.assert_allclose(res.spring_force[:, 1], c * v, rtol=0, atol=1e-9 * c * v0)
    np.testing.assert_allclose(res.spring_elongation[:, 1], x, rtol=0, atol=1e-9 * v0 / omega)
    assert res.peak_force("damper") == pytest.approx(c * v0, rel=1e-9)  # at t = 0

    balance = res.energy_balance()
    assert _energy_error(res) < 1e-9
    # All of the initial kinetic energy not left in the system went into the damper.
    absorbed = res.absorbed_energy()
    left = balance["kinetic"][-1] + balance["strain"][-1]
    assert absorbed["damper"] + left == pytest.approx(0.5 * m * v0**2, rel=1e-9)
    assert absorbed["spring"] == pytest.approx(balance["strain"][-1], rel=1e-6, abs=1e-12 * m * v0**2)


# --------------------------------------------------------------------------------------------------
# 4. 2-D pendulum on a stiff spring
# --------------------------------------------------------------------------------------------------


def test_stiff_spring_pendulum_period() -> None:
    """Small-angle (0.05 rad) swing on a near-rigid rod: period within 1% of 2 pi sqrt(L/g).

    Also within 2e-5 of the period corrected for the static stretch m g / k and the amplitude
    (factor 1 + theta^2 / 16); energy balance (gravity work integrated alongside) to 1e-8.
    """
    length, m, g, k, theta = 1.0, 1.0, 9.81, 1.0e4, 0.05
    period0 = 2.0 * np.pi * np.sqrt(length / g)
    model = {
        "nodes": {
            "pivot": {"position": [0.0, 0.0], "fixed": True},
            "bob": {"position": [0.0, -length], "mass": m},
        },
        "springs": {
            "rod": {"nodes": ["pivot", "bob"], "material": {"type": "linear_elastic", "stiffness": k}}
        },
        "initial_velocity": {"bob": [theta * np.sqrt(g * length), 0.0]},
        "gravity": [0.0, -g],
        "end_time": 1.1 * period0,
    }
    res = solve_reference(model)
    roots = _crossings(res, lambda r: r.position[:, 1, 0], 0.2 * period0, 1.1 * period0, n=1001)
    assert len(roots) == 2  # half and full swing
    period = roots[1]
    assert period == pytest.approx(period0, rel=1e-2)
    corrected = 2.0 * np.pi * np.sqrt((length + m * g / k) / g) * (1.0 + theta**2 / 16.0)
    assert period == pytest.approx(corrected, rel=2e-5)
    assert _energy_error(res) < 1e-8
    # The rod is near rigid: it stretches at most about twice the static m g / k.
    assert np.max(np.abs(res.spring_elongation)) < 2.2 * m * g / k


# --------------------------------------------------------------------------------------------------
# 5. Energy conservation of a nonlinear elastic chain
# --------------------------------------------------------------------------------------------------


def test_nonlinear_elastic_chain_conserves_energy() -> None:
    """ground - s1 - m1 - s2 - m2, both springs nonlinear elastic: KE + int C stays constant to 1e-8 rel.

    The motion runs into both extrapolated ends of the curves, and the stored energy from the
    closed-form curve integral agrees with the work integrated along the motion to 1e-8 of E0.
    """
    model = {
        "curves": {
            "stiffening": {"x": [-0.01, -0.005, 0.0, 0.005], "y": [-1.5e4, -5.0e3, 0.0, 2.5e3]},
            "soft": {"x": [-0.04, -0.005, 0.0, 0.02], "y": [-6.0e3, -4.0e3, 0.0, 2.0e3]},
        },
        "nodes": {
            "ground": {"position": [0.0], "fixed": True},
            "m1": {"position": [0.1], "mass": 1.0},
            "m2": {"position": [0.2], "mass": 2.0},
        },
        "springs": {
            "s1": {
                "nodes": ["ground", "m1"],
                "material": {"type": "nonlinear_elastic", "curve": "stiffening"},
            },
            "s2": {"nodes": ["m1", "m2"], "material": {"type": "nonlinear_elastic", "curve": "soft"}},
        },
        "initial_velocity": {"m1": [-5.0], "m2": [-20.0]},
        "end_time": 0.05,
    }
    res = solve_reference(model)
    t = np.linspace(0.0, 0.05, 20001)
    e0 = 0.5 * 1.0 * 5.0**2 + 0.5 * 2.0 * 20.0**2
    energy = res.energy(t)
    assert energy[0] == pytest.approx(e0, rel=1e-15)
    assert np.max(np.abs(energy - e0)) / e0 < 1e-8

    dense = res.sample(t)
    assert np.min(dense.spring_elongation[:, 0]) < -0.01 and np.max(dense.spring_elongation[:, 0]) > 0.005
    assert np.min(dense.spring_elongation[:, 1]) < -0.04 and np.max(dense.spring_elongation[:, 1]) > 0.02
    balance = res.energy_balance(t)
    assert np.max(np.abs(balance["strain"] - balance["internal_work"])) / e0 < 1e-8


# --------------------------------------------------------------------------------------------------
# 6. 1-D orientation: s = sign(X_j - X_i)
# --------------------------------------------------------------------------------------------------


def _chain_1d() -> dict[str, Any]:
    return {
        "curves": {
            "asym": {"x": [-0.03, 0.0, 0.01], "y": [-9.0e3, 0.0, 1.0e3]},
            "pulse": {"x": [0.0, 0.004, 0.008], "y": [0.0, 1.0, 0.0]},
        },
        "nodes": {
            "ground": {"position": [0.0], "fixed": True},
            "m1": {"position": [1.0], "mass": 2.0},
            "m2": {"position": [2.0], "mass": 3.0},
        },
        "springs": {
            "s1": {"nodes": ["ground", "m1"], "material": {"type": "nonlinear_elastic", "curve": "asym"}},
            "s2": {"nodes": ["m1", "m2"], "material": {"type": "linear_elastic", "stiffness": 2.0e5}},
            "d2": {"nodes": ["m1", "m2"], "material": {"type": "damper", "damping": 80.0}},
        },
        "initial_velocity": {"m2": [-4.0]},
        "gravity": [-9.81],
        "loads": [{"node": "m1", "force": [400.0], "curve": "pulse"}],
        "end_time": 0.06,
    }


def _mirror(model: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(model)
    for node in out["nodes"].values():
        node["position"] = [-x for x in node["position"]]
    out["initial_velocity"] = {n: [-x for x in v] for n, v in out["initial_velocity"].items()}
    out["gravity"] = [-x for x in out["gravity"]]
    for load in out["loads"]:
        load["force"] = [-x for x in load["force"]]
    return out


def test_nodes_drawn_right_to_left_give_the_mirrored_force_history() -> None:
    """Springs with X_j < X_i (s = -1): same forces and elongations as the original to 1e-9 of the peak.

    Two ways: the whole model mirrored (x -> -x, with velocities, gravity and loads), and the
    original with every spring's node pair swapped. The chain has an asymmetric curve (a sign slip
    would swap its tension and compression branches), a damper, gravity and a load pulse.
    """
    base = _chain_1d()
    mirrored = _mirror(base)
    swapped = copy.deepcopy(base)
    for spring in swapped["springs"].values():
        spring["nodes"] = spring["nodes"][::-1]

    t = np.linspace(0.0, 0.06, 1201)
    r0, r1, r2 = (solve_reference(m, t_eval=t) for m in (base, mirrored, swapped))
    scale = max(r0.dense_peaks()["peak_force"].values())
    # s1 is genuinely compressed and also pulled past its last knot (the extrapolated tension branch).
    assert np.min(r0.spring_force[:, 0]) < -1.0e3
    assert np.max(r0.spring_elongation[:, 0]) > 0.01

    for other in (r1, r2):
        np.testing.assert_allclose(other.spring_force, r0.spring_force, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(other.spring_elongation, r0.spring_elongation, rtol=0, atol=1e-12)
        for name in ("peak_force", "max_crush"):
            for sid, value in r0.dense_peaks()[name].items():
                assert other.dense_peaks()[name][sid] == pytest.approx(value, rel=1e-9)
    np.testing.assert_allclose(r1.position, -r0.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r2.position, r0.position, rtol=0, atol=1e-12)
    assert _energy_error(r0) < 1e-9


# --------------------------------------------------------------------------------------------------
# 7. Scope
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "material",
    [
        {"type": "general_nonlinear", "loading": "c", "unloading": "c", "tension_yield": 1.0},
        {"type": "crush", "loading": "c", "unloading_stiffness": 1.0e5},
    ],
)
def test_history_dependent_materials_are_refused(material: dict[str, Any]) -> None:
    model = _spring_mass()
    model["curves"] = {"c": {"x": [-1.0, 0.0, 1.0], "y": [-1.0, 0.0, 1.0]}}
    model["springs"]["s"]["material"] = material
    with pytest.raises(NotImplementedError, match=material["type"]):
        solve_reference(model)


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("prescribed_motion", [{"node": "mass", "quantity": "velocity", "direction": "x", "curve": "c"}]),
        ("rigid_walls", [{"id": "floor", "point": [0.0], "normal": [1.0]}]),
    ],
)
def test_walls_and_prescribed_motion_are_refused(key: str, value: list[dict[str, Any]]) -> None:
    model = _spring_mass()
    model[key] = value
    with pytest.raises(NotImplementedError, match=key):
        solve_reference(model)
