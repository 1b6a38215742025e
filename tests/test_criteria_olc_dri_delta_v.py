"""Crash criteria (SPEC 6b) against independent truths: OLC (closed form of a constant-deceleration
barrier pulse, millimetre units), DRI (solve_ivp of the seat model, the matrix exponential) and delta_v.

Tolerances are stated at each assert. Pulses are written down exactly (prescribed acceleration)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from crashstudy.metrics import criteria as C
from crashstudy.metrics import criteria_rows as R
from pulses import G, half_sine, one, trapezoid

# --------------------------------------------------------------------------- OLC, DRI, delta_v


def olc_barrier(u0: float, decel: float, s_free: float = 0.065, s_rest: float = 0.235) -> float:
    """Closed form for a node decelerating at a constant ``decel`` from ``u0`` to rest (then at rest).
    Free flight ends at t1 = sqrt(2 s_free / decel). If the occupant meets the node while it still
    moves: olc = decel (s_free + s_rest) / s_rest; else both end at rest and the occupant's travel
    u0 t1 + u0^2 / (2 olc) exceeds the node's u0^2 / (2 decel) by s_free + s_rest."""
    t1 = math.sqrt(2 * s_free / decel)
    olc = decel * (s_free + s_rest) / s_rest
    t2 = t1 + 2 * s_rest / (decel * t1)
    if t2 <= u0 / decel:
        return olc
    return u0**2 / (2 * (s_free + s_rest - u0 * t1) + u0**2 / decel)


@pytest.mark.parametrize(("u0", "decel_g"), [(30.0, 20.0), (13.8889, 20.0), (15.6, 35.0), (8.0, 15.0)])
def test_olc_of_constant_deceleration_barrier_pulse_matches_closed_form(u0: float, decel_g: float) -> None:
    decel = decel_g * G
    want = olc_barrier(u0, decel) / G
    dt = 1e-5
    ts = u0 / decel
    # the node's speed, with a step that puts the stop on the grid: piecewise linear, so exact
    steps = int(round(ts / dt))
    h = ts / steps
    tt = np.arange(int(0.25 / h) + 1) * h
    uu = np.maximum(u0 - decel * tt, 0.0)
    olc, t1, t2 = R.olc_row(uu, uu.size, h, u0, 0.065, 0.235)
    assert olc / G == pytest.approx(want, rel=1e-9)  # exact for a piecewise-linear speed
    assert t1 == pytest.approx(math.sqrt(2 * 0.065 / decel), rel=1e-9)
    # through compute(): the square deceleration is CFC-filtered; the filter rounds its corners
    acc = -np.where(tt < ts, decel, 0.0)
    # ("zero" pad: the jump at t = 0 is rounded too; "constant": only the stop, whose effect is symmetric)
    for cfc, tol_zero in ((1000, 1e-3), (180, 4e-3), (60, 1.2e-2)):
        r = one(acc, h, names=("olc",), cfc=cfc, v0=u0, pad="zero")
        assert r["olc"] == pytest.approx(want, rel=tol_zero), cfc  # 0.1 %, 0.4 %, 1.2 %
        assert r["criteria_note"] == ""
        r = one(acc, h, names=("olc",), cfc=cfc, v0=u0)
        assert r["olc"] == pytest.approx(want, rel=2e-4), cfc  # 0.02 %


def test_olc_in_millimetre_units_equals_si() -> None:
    dt = 1e-5
    t = np.arange(20001) * dt
    acc = -half_sine(t, 25 * G, 0.08)
    si = one(acc, dt, names=("olc", "delta_v"), v0=15.0)
    mm = one(acc * 1000, dt, names=("olc", "delta_v"), v0=15000.0, metre=1000.0)
    r = C.compute(
        (acc * 1000)[None, :, None],
        np.array([t.size]),
        np.array([dt]),
        np.array([[15000.0]]),
        np.array([1.0]),
        1000,
        ["olc"],
        G * 1000,
        metre=1000.0,
    )
    assert float(r["olc"][0]) == pytest.approx(si["olc"], rel=1e-12)
    assert mm["delta_v"] == pytest.approx(1000 * si["delta_v"], rel=1e-12)
    ms = C.compute(
        acc[None, :, None] * 1e-6,
        np.array([t.size]),
        np.array([dt * 1e3]),
        np.array([[0.015]]),
        np.array([1.0]),
        1000,
        C.CRITERIA,
        G * 1e-6,
        second=1000.0,
    )  # m, ms
    ref = one(acc, dt, v0=15.0)
    for k in ("peak_g", "hic15", "hic15_t1", "hic36", "clip3ms", "clip3ms_cumulative", "olc", "dri"):
        assert float(ms[k][0]) == pytest.approx(ref[k], rel=1e-9), k
    assert float(ms["delta_v"][0]) == pytest.approx(1e-3 * ref["delta_v"], rel=1e-9)  # in m/ms


def dri_reference(d: np.ndarray, dt: float) -> float:
    """scipy solve_ivp of the seat model x'' + 2 zeta omega x' + omega^2 x = d(t)/g, d linear between samples."""
    t = np.arange(d.size) * dt
    w, z = C.DRI_OMEGA, C.DRI_ZETA

    def rhs(tt: float, y: np.ndarray) -> list[float]:
        return [y[1], np.interp(tt, t, d) / G - 2 * z * w * y[1] - w * w * y[0]]

    sol = solve_ivp(
        rhs, (0.0, t[-1]), [0.0, 0.0], method="DOP853", t_eval=t, rtol=1e-11, atol=1e-14, max_step=5 * dt
    )
    return w * w * max(sol.y[0].max(), 0.0)


def test_dri_matches_solve_ivp_of_the_seat_model() -> None:
    rng = np.random.default_rng(2)
    dt = 1e-4
    t = np.arange(1501) * dt
    pulses = [
        half_sine(t, 20 * G, 0.03),
        trapezoid(t, 0.0, 0.005, 0.01, 0.02, 15 * G),
        np.abs(np.cumsum(rng.normal(size=t.size))) * G * 0.5,
    ]
    for d in pulses:
        want = dri_reference(d, dt)
        got = one(-d, dt, names=("dri",))["dri"]  # deceleration along +x = -acceleration
        assert got == pytest.approx(want, rel=1e-6)  # 1e-6 (the ODE solver's own accuracy ~1e-9)


def test_dri_matrices_equal_matrix_exponential() -> None:
    import scipy.linalg

    for h in (1e-8, 1e-6, 1e-4, 1.9e-3, 2e-3, 0.05):
        phi, g0, gs = C.dri_matrices(np.array([h]))
        w, z = C.DRI_OMEGA, C.DRI_ZETA
        m = np.zeros((4, 4))
        m[0, 1], m[1, 0], m[1, 1], m[1, 2], m[2, 3] = h, -w * w * h, -2 * z * w * h, h, 1.0
        e = scipy.linalg.expm(m)
        assert phi[0] == pytest.approx(e[:2, :2], rel=1e-12, abs=1e-15)
        assert g0[0] == pytest.approx(e[:2, 2], rel=1e-11)
        assert gs[0] == pytest.approx(e[:2, 3], rel=1e-11)


def test_delta_v_of_half_sine_and_of_a_rebound() -> None:
    dt = 1e-5
    t = np.arange(12001) * dt
    r = one(-half_sine(t, 30 * G, 0.06), dt, names=("delta_v",), v0=15.0)
    assert r["delta_v"] == pytest.approx(2 * 30 * G * 0.06 / math.pi, rel=1e-7)  # trapezoid: (pi dt/tau)^2/12
    # rebound: the pulse takes 1.5 u0, the node ends at -0.5 u0: delta_v = 1.5 u0 (not u0)
    peak = 1.5 * 15.0 * math.pi / (2 * 0.06)
    r = one(-half_sine(t, peak, 0.06), dt, names=("delta_v",), v0=15.0)
    assert r["delta_v"] == pytest.approx(22.5, rel=1e-7)
