"""Crash criteria (SPEC 6b) against independent truths: HIC (closed form of a half sine, brute force on
random signals, the window-limited optimum) and the 3 ms clips (square and trapezoid pulses, their
definitions on random signals).

Tolerances are stated at each assert. Pulses are written down exactly (prescribed acceleration)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from crashstudy.metrics import criteria as C
from crashstudy.metrics import criteria_clips as CL
from crashstudy.metrics import criteria_rows as R
from pulses import G, half_sine, one, trapezoid


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
