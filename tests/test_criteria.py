"""Crash criteria (SPEC 6b) against independent truths: closed forms, scipy, brute force, dynars.

Tolerances are stated at each assert. Pulses are written down exactly (prescribed acceleration).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from crashstudy.metrics import criteria as C
from crashstudy.metrics import criteria_clips as CL
from crashstudy.metrics import criteria_rows as R
from pulses import G, half_sine, one


def hic_half_sine(peak: float, tau: float, window: float) -> tuple[float, float, float]:
    """Closed form: the best interval is centred on the peak; its length L maximises
    L^-1.5 (2 peak tau / pi)^2.5 sin^2.5(pi L / (2 tau)), i.e. tan(th) = 5/3 th with th = pi L/(2 tau),
    unless the window is shorter (then L = window)."""
    th = brentq(lambda x: math.tan(x) - 5.0 / 3.0 * x, 0.5, 1.5)
    length = min(2.0 * tau * th / math.pi, window)
    th = math.pi * length / (2.0 * tau)
    hic = length**-1.5 * (2.0 * peak * tau / math.pi) ** 2.5 * math.sin(th) ** 2.5
    return hic, tau / 2 - length / 2, tau / 2 + length / 2


# --------------------------------------------------------------------------- HIC


def hic_brute(x: np.ndarray, dt: float, window: float) -> tuple[float, float, float]:
    """Every sample pair within the window, and every interval of exactly the window that starts or
    ends on a sample (the other end on the piecewise-linear curve), in plain NumPy."""
    n = x.size
    cum = np.concatenate([[0.0], np.cumsum(0.5 * dt * (x[1:] + x[:-1]))])
    wn = window / dt
    p = int(np.floor(wn * (1 + 1e-12)))
    best, arg = 0.0, (math.nan, math.nan)
    for i in range(n):
        j = np.arange(i + 1, min(n - 1, i + p) + 1)
        if j.size:
            s, ln = cum[j] - cum[i], (j - i) * dt
            h = np.where(s > 0, np.maximum(s, 0) ** 2.5 / ln**1.5, 0.0)
            k = int(np.argmax(h))
            if h[k] > best:
                best, arg = float(h[k]), (i * dt, j[k] * dt)

    def integral(pos: float) -> float:
        j = min(int(np.floor(pos)), n - 1)
        ph = pos - j
        return cum[j] if ph <= 0 else cum[j] + dt * ph * (x[j] + 0.5 * ph * (x[j + 1] - x[j]))

    for i in range(n):
        if i + wn <= n - 1 + 1e-9:
            s = integral(i + wn) - cum[i]
            if s > 0 and s**2.5 / window**1.5 > best:
                best, arg = s**2.5 / window**1.5, (i * dt, (i + wn) * dt)
        j = i
        if j - wn >= -1e-9:
            s = cum[j] - integral(max(j - wn, 0.0))
            if s > 0 and s**2.5 / window**1.5 > best:
                best, arg = s**2.5 / window**1.5, ((j - wn) * dt, j * dt)
    return best, *arg


def test_hic_search_equals_brute_force_on_random_signals() -> None:
    rng = np.random.default_rng(5)
    for trial in range(45):
        n = int(rng.integers(5, 600))
        dt = float(rng.choice([1e-4, 3e-4, 7e-5]))
        kind = trial % 3
        if kind == 0:
            x = np.abs(rng.normal(size=n)) * 50
        elif kind == 1:
            x = np.abs(np.cumsum(rng.normal(size=n))) * 5
        else:
            x = np.maximum(0, np.sin(np.linspace(0, rng.uniform(1, 20), n))) * 80 + rng.uniform(0, 5, n)
        for window in (0.015, 0.036, 0.003):
            got = R.hic_row(x, n, dt, window, np.empty(n + 1), np.empty(n + 1), False)
            want = hic_brute(x, dt, window)
            assert got[0] == pytest.approx(want[0], rel=1e-12)  # the same maximum
            assert got[1:] == pytest.approx(want[1:], abs=1e-12)  # at the same t1, t2


def test_hic_window_limited_optimum_is_exact_between_samples() -> None:
    """With the window limit active, HIC = window^-1.5 max S(t1)^2.5, S the integral of the
    piecewise-linear curve over [t1, t1 + window]: against a 400-points-per-step scan of t1."""
    rng = np.random.default_rng(8)
    dt = 1e-3
    for _ in range(10):
        n = 60
        x = 40 + 20 * np.sin(np.arange(n) * rng.uniform(0.05, 0.2)) + rng.uniform(0, 2, n)  # long, flat-ish
        t = np.arange(n) * dt
        cum = np.concatenate([[0.0], np.cumsum(0.5 * dt * (x[1:] + x[:-1]))])

        def integral(tt: np.ndarray, x: np.ndarray = x, cum: np.ndarray = cum, n: int = n) -> np.ndarray:
            k = np.minimum((tt / dt).astype(int), n - 2)
            ph = tt / dt - k
            return cum[k] + dt * ph * (x[k] + 0.5 * ph * (x[k + 1] - x[k]))

        t1 = np.arange(0.0, t[-1] - 0.015 + 1e-12, dt / 400)
        scan = (integral(t1 + 0.015) - integral(t1)).max() ** 2.5 / 0.015**1.5
        got = R.hic_row(x, n, dt, 0.015, np.empty(n + 1), np.empty(n + 1), True)
        plain = R.hic_row(x, n, dt, 0.015, np.empty(n + 1), np.empty(n + 1), False)
        assert got[2] - got[1] == pytest.approx(0.015, abs=1e-12)  # the limit is active
        assert scan - 1e-9 * scan <= got[0] <= scan * (1 + 1e-6) and got[0] >= plain[0]  # scan from below


@pytest.mark.parametrize("tau", [0.01, 0.05])
def test_hic_of_half_sine_matches_closed_form_with_t1_t2(tau: float) -> None:
    """tau = 10 ms: both windows unconstrained (L* = 0.67 tau); 50 ms: HIC15 held at 15 ms, HIC36 free."""
    peak = 60.0
    for dt in (2e-5, 1e-5):
        t = np.arange(int(round(0.1 / dt)) + 1) * dt
        x = half_sine(t, peak, tau)
        for window in C.HIC_WINDOWS.values():
            hic, t1, t2 = R.hic_row(x, x.size, dt, window, np.empty(x.size + 1), np.empty(x.size + 1), True)
            want = hic_half_sine(peak, tau, window)
            assert hic == pytest.approx(want[0], rel=3e-5 * (dt / 1e-5) ** 2)  # O(dt^2): 3e-5 at 10 us
            assert t1 == pytest.approx(want[1], abs=dt) and t2 == pytest.approx(want[2], abs=dt)
    # through compute(): CFC 1000 filtering of a 50 ms pulse moves HIC by < 1e-5
    dt = 1e-5
    t = np.arange(10001) * dt
    r = one(-half_sine(t, peak * G, tau), dt, names=("hic15", "hic36"))
    for name, window in C.HIC_WINDOWS.items():
        want = hic_half_sine(peak, tau, window)
        assert r[name] == pytest.approx(want[0], rel=1e-4 if tau == 0.01 else 1e-5)
        assert r[name + "_t1"] == pytest.approx(want[1], abs=2 * dt)
        assert r[name + "_t2"] == pytest.approx(want[2], abs=2 * dt)


# --------------------------------------------------------------------------- clips


def trapezoid(
    t: np.ndarray, start: float, rise: float, flat: float, fall: float, peak: float, base: float = 0.0
):
    return base + (peak - base) * np.interp(
        t,
        [start, start + rise, start + rise + flat, start + rise + flat + fall],
        [0.0, 1.0, 1.0, 0.0],
        left=0.0,
        right=0.0,
    )


def clips(x: np.ndarray, dt: float) -> tuple[float, float]:
    n = x.size
    cont, _ = CL.clip_row(x, n, dt, 0.003, np.empty(n), np.empty(n))
    return cont, CL.clip_cumulative_row(x, n, dt, 0.003, cont, np.empty(n), np.empty(n))


def test_clip_levels_of_square_and_trapezoid_pulses() -> None:
    dt = 1e-5
    t = np.arange(5001) * dt
    # square 50 g for 5 ms (edges one step long): 50 g both ways
    assert clips(trapezoid(t, 0.01, dt, 0.005, dt, 50.0), dt) == pytest.approx((50.0, 50.0), abs=1e-9)
    # trapezoid 2 ms up, 1 ms flat, 2 ms down to 60 g: 3 ms above c when 1 + 4 (1 - c/60) = 3 ms -> 30 g
    assert clips(trapezoid(t, 0.01, 0.002, 0.001, 0.002, 60.0), dt) == pytest.approx((30.0, 30.0), abs=1e-9)
    # same with a 1.5 ms flat top and unequal sides: 1.5 + (2 + 1)(1 - c/60) = 3 -> c = 30 g
    assert clips(trapezoid(t, 0.01, 0.002, 0.0015, 0.001, 60.0), dt) == pytest.approx((30.0, 30.0), abs=1e-9)
    # two 2 ms squares of 50 g on a 10 g floor, 5 ms apart: no 3 ms continuously above 10 g,
    # but 4 ms cumulatively at 50 g (FMVSS 208 counts them together)
    x = trapezoid(t, 0.01, dt, 0.002, dt, 50.0, 10.0) + trapezoid(t, 0.017, dt, 0.002, dt, 40.0)
    assert clips(x, dt) == pytest.approx((10.0, 50.0), abs=1e-9)
    # half-sine: both = peak cos(pi W / (2 tau)), through compute() with the CFC 1000 filter
    r = one(-half_sine(t, 30 * G, 0.04), dt, names=("clip3ms", "clip3ms_cumulative"))
    want = 30.0 * math.cos(math.pi * 0.003 / (2 * 0.04))
    assert r["clip3ms"] == pytest.approx(want, rel=1e-5) and r["clip3ms_cumulative"] == pytest.approx(
        want, rel=1e-5
    )


def test_clips_equal_their_definitions_on_random_signals() -> None:
    """Continuous: max over t1 of the minimum of the piecewise-linear curve on [t1, t1 + 3 ms],
    by a 40-points-per-step scan of t1 (from below, within the scan's resolution). Cumulative:
    the measure of {x >= c} at the returned c is exactly 3 ms, and less just above it."""
    rng = np.random.default_rng(11)
    dt = 2e-4
    for _ in range(30):
        n = int(rng.integers(20, 120))
        x = np.abs(np.cumsum(rng.normal(size=n))) * 10 + rng.uniform(0, 3, n)
        t = np.arange(n) * dt
        cont, cum = clips(x, dt)
        fine = np.arange(0.0, t[-1] - 0.003 + 1e-12, dt / 40)
        mins = [
            min(np.interp([a, a + 0.003], t, x).min(), x[(t > a) & (t < a + 0.003)].min(initial=np.inf))
            for a in fine
        ]
        slope = np.abs(np.diff(x)).max() / dt
        assert cont >= max(mins) - 1e-9 and cont - max(mins) <= slope * dt / 40  # within the scan step
        lo, hi = np.minimum(x[:-1], x[1:]), np.maximum(x[:-1], x[1:])

        def measure(c: float, lo: np.ndarray = lo, hi: np.ndarray = hi) -> float:
            return float(
                np.sum(
                    np.where(lo >= c, dt, np.where(hi > c, dt * (hi - c) / np.where(hi > lo, hi - lo, 1), 0))
                )
            )

        assert measure(cum) == pytest.approx(0.003, rel=1e-9)
        assert measure(cum + 1e-6) < 0.003 and cum >= cont - 1e-12


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


# --------------------------------------------------------------------------- convergence, batching


def smooth_pulse(t: np.ndarray) -> np.ndarray:
    """A smooth (C1) 70 ms deceleration with an 80 Hz ripple, peak ~ 35 g."""
    tau = 0.07
    s = np.clip(t / tau, 0.0, 1.0)
    return np.where(t <= tau, 30 * G * np.sin(np.pi * s) ** 2 * (1 + 0.2 * np.sin(2 * np.pi * 80 * t)), 0.0)


def test_every_criterion_converges_as_dt_is_halved() -> None:
    """dt = 40, 20, 10, 5 us (CFC 180; 25-200 kHz) against dt = 2.5 us: at 40 us every criterion is
    within 0.2 % of the reference, and the error divided by dt^2 does not grow as dt is halved
    (at most 4x its value at 40/20 us, allowing for the samples' phase; a first-order error would
    grow 8x over three halvings), up to 1e-8 of the value for the reference's own error."""
    names = list(C.CRITERIA)
    keys = names + ["hic15_t1", "hic15_t2", "hic36_t1", "hic36_t2"]
    vals: dict[str, list[float]] = {k: [] for k in keys}
    dts = np.array([4e-5, 2e-5, 1e-5, 5e-6, 2.5e-6])
    for dt in dts:
        t = np.arange(int(round(0.12 / dt)) + 1) * dt
        r = one(-smooth_pulse(t), dt, names=names, cfc=180, v0=16.0)
        assert r["criteria_note"] == ""
        for k in keys:
            vals[k].append(r[k])
    for k in names:
        v = np.array(vals[k])
        err = np.abs(v[:-1] - v[-1])
        assert err[0] <= 2e-3 * abs(v[-1]), (k, v)
        scaled = np.maximum(err - 1e-8 * abs(v[-1]), 0.0) / dts[:-1] ** 2
        assert (scaled <= 4 * scaled[:2].max() + 1e-30).all(), (k, v)
    for k in keys[len(names) :]:  # the interval's ends settle to within a step
        assert abs(vals[k][-2] - vals[k][-1]) <= 5e-6, (k, vals[k])


def test_batch_rows_with_own_steps_counts_directions_equal_single_runs() -> None:
    """Variants with different dt, count, 2-D directions and NaN past their count: each equals
    the 1-D run of the same pulse along its direction (resultant and projection are rotation-free)."""
    rng = np.random.default_rng(4)
    nv, nt = 6, 9000
    dts = rng.uniform(1e-5, 2e-5, nv)
    counts = rng.integers(5000, nt + 1, nv)
    counts[2] = 1  # too short
    angles = rng.uniform(0, 2 * np.pi, nv)
    acc = np.full((nv, nt, 2), np.nan)
    v0 = np.zeros((nv, 2))
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    pulses = []
    for v in range(nv):
        t = np.arange(counts[v]) * dts[v]
        p = -smooth_pulse(t * rng.uniform(0.8, 1.2))
        pulses.append(p)
        acc[v, : counts[v]] = p[:, None] * dirs[v]
        v0[v] = 16.0 * dirs[v]
    acc[4, 100, 1] = np.nan  # a variant whose solve failed
    r = C.compute(acc, counts, dts, v0, dirs, 180, C.CRITERIA, G)
    assert all(np.isnan(r[k][4]) for k in r if k != "criteria_note") and "not finite" in r["criteria_note"][4]
    for v in range(nv):
        if v == 4:
            continue
        if counts[v] < 2:
            assert all(np.isnan(r[k][v]) for k in r if k != "criteria_note")
            assert r["criteria_note"][v] == "fewer than 2 samples"
            continue
        ref = one(pulses[v], dts[v], cfc=180, v0=16.0)
        for k in ref:
            if k != "criteria_note":
                assert r[k][v] == pytest.approx(ref[k], rel=1e-9, abs=1e-12, nan_ok=True), (v, k)
        assert r["criteria_note"][v] == ref["criteria_note"]
    # a single (D,) direction broadcasts to every variant
    r1 = C.compute(acc[:1], counts[:1], dts[:1], v0[:1], dirs[0], 180, ["olc", "dri"], G)
    assert r1["olc"][0] == pytest.approx(r["olc"][0], rel=1e-12)


def test_unknown_criterion_or_class_is_refused() -> None:
    acc = np.zeros((1, 10, 1))
    with pytest.raises(ValueError, match="unknown criteria"):
        C.compute(acc, np.array([10]), np.array([1e-5]), np.zeros((1, 1)), np.ones(1), 180, ["hic"], G)
    with pytest.raises(ValueError, match="cfc"):
        C.compute(acc, np.array([10]), np.array([1e-5]), np.zeros((1, 1)), np.ones(1), 100, ["hic15"], G)
    r = C.compute(
        acc, np.array([10]), np.array([1e-5]), np.zeros((1, 1)), np.ones(1), 180, ["hic15", "peak_g"], G
    )
    assert set(r) == {"hic15", "hic15_t1", "hic15_t2", "peak_g", "criteria_note"}
    assert r["hic15"][0] == 0.0 and np.isnan(r["hic15_t1"][0]) and r["peak_g"][0] == 0.0  # a quiet record


def test_variants_split_over_threads_give_the_single_thread_values_bitwise(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The driver runs parts of the variants side by side; each variant's row is its own, so the
    values equal the one-thread run bit for bit (second implementation: the same driver unsplit)."""
    from crashstudy.kernel import driver

    rng = np.random.default_rng(7)
    nv, nt = 7, 3000
    dts = rng.uniform(1e-5, 2e-5, nv)
    counts = rng.integers(1000, nt + 1, nv)
    acc = np.zeros((nv, nt, 1))
    for v in range(nv):
        acc[v, : counts[v], 0] = -smooth_pulse(np.arange(counts[v]) * dts[v] * rng.uniform(0.8, 1.2))
    v0 = np.full((nv, 1), 16.0)
    old = driver.get_threads()
    try:
        driver.set_threads(1)
        one_thread = C.compute(acc, counts, dts, v0, [1.0], 180, C.CRITERIA, G)
        monkeypatch.setattr(C, "MIN_PART", 1)
        driver.set_threads(3)
        split = C.compute(acc, counts, dts, v0, [1.0], 180, C.CRITERIA, G)
    finally:
        driver.set_threads(old)
    for k, arr in one_thread.items():
        assert (
            np.array_equal(arr, split[k], equal_nan=True)
            if k != "criteria_note"
            else list(arr) == list(split[k])
        )


def test_plain_python_criteria_equal_the_compiled_ones_bitwise(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a machine where the criteria are not compiled, a small record runs the driver's own code as
    plain Python (crashstudy.metrics.interpreted): every criterion, t1/t2 and note equals the compiled
    driver's bit for bit (numba compiles without fast-math), and so does the J211 filter; past
    PLAIN_MAX_SAMPLES interpreted samples a process compiles."""
    from crashstudy.metrics import criteria_filter as F
    from crashstudy.metrics import interpreted

    rng = np.random.default_rng(11)
    nv, nt = 5, 2500
    dts = rng.uniform(1e-4, 4e-4, nv)
    counts = rng.integers(300, nt + 1, nv)
    acc = np.zeros((nv, nt, 2))
    for v in range(nv):
        t = np.arange(counts[v]) * dts[v]
        acc[v, : counts[v], 0] = -smooth_pulse(t * rng.uniform(0.8, 1.2)) + rng.normal(0.0, 20.0, counts[v])
        acc[v, : counts[v], 1] = rng.normal(0.0, 30.0, counts[v])
    v0 = np.tile([16.0, 0.0], (nv, 1))
    compiled = C.compute(acc, counts, dts, v0, [1.0, 0.0], 180, C.CRITERIA, G)
    filt = F.j211_filter(acc[:, :, 0], counts, dts, 60)
    monkeypatch.setattr(interpreted, "compiled_or_cached", lambda fn: False)
    monkeypatch.setattr(interpreted, "_SPENT", [0])
    assert interpreted.driver_for(C._driver, 10)[1] is False
    plain = C.compute(acc, counts, dts, v0, [1.0, 0.0], 180, C.CRITERIA, G)
    assert interpreted._SPENT[0] == 10 + int(counts.sum())  # it did run interpreted
    for k, arr in compiled.items():
        assert (
            np.array_equal(arr, plain[k], equal_nan=True)
            if k != "criteria_note"
            else list(arr) == list(plain[k])
        )
    assert np.array_equal(F.j211_filter(acc[:, :, 0], counts, dts, 60), filt, equal_nan=True)
    monkeypatch.setattr(interpreted, "_SPENT", [interpreted.PLAIN_MAX_SAMPLES])
    assert interpreted.driver_for(C._driver, 1) == (C._driver, True)


def test_the_criteria_warm_up_process_takes_the_compiled_functions(monkeypatch: pytest.MonkeyPatch) -> None:
    """The process that compiles the criteria beside a kernel (kernel/warm.py calls
    metrics/warmup.compile_criteria) runs a short pulse, which
    would otherwise run as plain Python and leave nothing compiled: it must call the numba functions
    (recorded by wrapping the driver the warm-up gets)."""
    from crashstudy.metrics import interpreted, warmup

    monkeypatch.setattr(interpreted, "compiled_or_cached", lambda fn: False)
    monkeypatch.setattr(interpreted, "_SPENT", [0])
    got: list[bool] = []
    real = interpreted.driver_for
    monkeypatch.setattr(C, "driver_for", lambda fn, n: got.append(real(fn, n)[1]) or real(fn, n))
    warmup.compile_criteria()
    assert got == [True]
