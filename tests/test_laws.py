"""Each compiled law of ``kernel/laws.py`` against its NumPy twin (``arrays/material_laws.py``,
``kernel/reference.py``) on random inputs, bit for bit: a law bug shows here as that law's failure,
not only as "a kernel differs" in tests/test_kernel_twins.py.

The laws are called one number at a time (as the fast kernels call them per lane); the twins take
arrays over variants (as the reference calls them). The state laws walk a random elongation path, so
loading, unloading, reloading, yielding and crushing are all met.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from conftest import model_batch
from crashstudy.arrays import material_laws as twin
from crashstudy.kernel import laws
from crashstudy.kernel.reference import (
    energy_balance_np,
    knot_peak_np,
    prescribed_step_np,
    prescribed_time_np,
    prescribed_velocity_np,
    stop_test_np,
    unstable_limit_np,
    unstable_np,
    wall_hold_np,
    wall_penalty_np,
)

RNG_SEED = 20261126
CURVES = {
    "load": {"x": [-0.1, 0.0, 0.01, 0.02, 0.2], "y": [-1.0e4, 0.0, 600.0, 400.0, 900.0]},
    "unload": {"x": [-0.1, 0.0, 0.1], "y": [-1.0e4, 0.0, 1.0e4]},
    "crush": {"x": [-0.3, -0.01, 0.0], "y": [-3000.0, -1500.0, 0.0]},
    "soft": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-800.0, -500.0, 0.0, 500.0, 800.0]},
    "stiff": {"x": [-0.2, 0.0, 0.1, 0.2], "y": [-4000.0, 0.0, 1500.0, 2500.0]},
    "pulse": {"x": [0.0, 0.01, 0.03], "y": [0.0, 1.0, 0.0]},
}  # fmt: skip


@pytest.fixture(scope="module")
def curves() -> tuple[Any, dict[str, int]]:
    """The curve arrays of a batch holding CURVES (one variant) and each curve's index."""
    model = {
        "name": "law-curves", "curves": CURVES,
        "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
        "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 1.0}}},
        "loads": [{"node": "b", "force": [1.0], "curve": "pulse"}], "end_time": 0.01,
    }  # fmt: skip
    b, _ = model_batch(model)
    return b, {cid: i for i, cid in enumerate(CURVES)}


def _args(b: Any) -> tuple[np.ndarray, ...]:
    return b.cx, b.cy, b.cds, b.cs0, b.curve_off


def _path(rng: np.random.Generator, lo: float, hi: float, n: int = 400) -> np.ndarray:
    """A random walk of elongations that reverses often, kept inside [lo, hi]."""
    steps = rng.normal(0.0, (hi - lo) / 40.0, n)
    return np.clip(np.cumsum(steps), lo, hi)


def _cycles(rng: np.random.Generator, amplitude: float, n: int = 600) -> np.ndarray:
    """Growing load cycles in both directions with noise: tension and compression extremes, reversals."""
    t = np.linspace(0.0, 1.0, n)
    return amplitude * (0.1 + 0.9 * t) * np.sin(14.0 * np.pi * t) + rng.normal(0.0, amplitude / 200.0, n)


def test_curve_at_and_time_curve_at_equal_their_twins(curves: tuple[Any, dict[str, int]]) -> None:
    b, idx = curves
    rng = np.random.default_rng(RNG_SEED)
    cx, cy, cds, cs0, off = _args(b)
    for name, c in idx.items():
        for e in rng.uniform(-0.4, 0.4, 50):
            assert laws.curve_at(c, e, 0, cx, cy, cds, cs0, off) == twin.curve_eval(c, np.array([e]), cx, cy, cds, cs0,
                                                                                   off)[0], name  # fmt: skip
    c = idx["pulse"]
    for t in np.concatenate([rng.uniform(-0.01, 0.04, 50), [0.0, 0.03, 0.03 + 1e-12, -1e-12]]):
        assert laws.time_curve_at(c, t, 0, cx, cy, cds, cs0, off) == twin.time_curve_eval(c, np.array([t]), cx, cy,
                                                                                         cds, cs0, off)[0]  # fmt: skip


def test_curve_inverses_equal_their_twins(curves: tuple[Any, dict[str, int]]) -> None:
    b, idx = curves
    rng = np.random.default_rng(RNG_SEED + 1)
    cx, cy, cds, cs0, off = _args(b)
    for f in rng.uniform(-1.2e4, 1.2e4, 60):
        for direction in (1.0, -1.0):
            got = laws.curve_inverse(idx["load"], f, direction, 0, cx, cy, cds, cs0, b.cs1, off)
            want = twin.curve_inverse(idx["load"], np.array([f]), direction, cx, cy, cds, cs0, b.cs1, off)[0]
            assert got == want, (f, direction)
        got = laws.unloading_inverse(idx["unload"], f, 0, cx, cy, cs0, b.cs1, off)
        assert got == twin.unloading_inverse(idx["unload"], np.array([f]), cx, cy, cds, cs0, b.cs1, off)[0], f


def test_crush_law_equals_its_twin_along_a_random_path(curves: tuple[Any, dict[str, int]]) -> None:
    b, idx = curves
    c, ku = idx["crush"], 2.0e5
    cx, cy, cds, cs0, off = _args(b)
    emin = fstar = 0.0
    st = np.zeros((8, 1))
    for e in _path(np.random.default_rng(RNG_SEED + 2), -0.35, 0.05):
        L = laws.curve_at(c, e, 0, cx, cy, cds, cs0, off)
        F, emin, fstar = laws.crush_law(e, emin, fstar, L, ku)
        want = twin.crush(np.array([e]), st, c, np.array([ku]), cx, cy, cds, cs0, off)[0]
        assert (F, emin, fstar) == (want, st[0, 0], st[1, 0]), e


def test_elastoplastic_law_equals_its_twin_along_a_random_path() -> None:
    k, kt, fy = 4.0e4, 1.0e4, 2.0e3
    ep = p = 0.0
    st = np.zeros((8, 1))
    for e in _path(np.random.default_rng(RNG_SEED + 3), -0.3, 0.3):
        F, ep, p = laws.elastoplastic_law(e, ep, p, k, kt, fy)
        want = twin.elastoplastic(np.array([e]), st, np.array([k]), np.array([kt]), np.array([fy]))[0]
        assert (F, ep, p) == (want, st[0, 0], st[1, 0]), e


@pytest.mark.parametrize("yields", [(500.0, -2000.0), (np.inf, -np.inf), (800.0, -np.inf)])
def test_general_law_and_reversal_equal_their_twin_along_a_random_path(curves: tuple[Any, dict[str, int]],
                                                                        yields: tuple[float, float]) -> None:  # fmt: skip
    """Rules 1-3 (``general_law``) and rule 4 (``general_reverse``, when ``general_law`` flags a reversal)
    against ``materials.general_nonlinear``, with the state handed on from step to step."""
    b, idx = curves
    ca, cb = idx["load"], idx["unload"]
    cx, cy, cds, cs0, off = _args(b)
    yt, yc = yields
    s = [0.0] * 8  # mode, e_t*, F_t*, e_c*, F_c*, shift, yielded_t, yielded_c
    st = np.zeros((8, 1))
    reversals = 0
    for e in _cycles(np.random.default_rng(RNG_SEED + 4), 0.12):
        L = laws.curve_at(ca, e - s[5], 0, cx, cy, cds, cs0, off)
        Ut = laws.curve_at(cb, e - s[1], 0, cx, cy, cds, cs0, off)
        Uc = laws.curve_at(cb, e - s[3], 0, cx, cy, cds, cs0, off)
        F, s[0], s[1], s[2], s[3], s[4], s[6], s[7], rev = laws.general_law(e, s[0], s[1], s[2], s[3], s[4], s[6],
                                                                             s[7], L, Ut, Uc, yt, yc)  # fmt: skip
        if rev:
            reversals += 1
            before = [float(v) for v in st[:, 0]]  # rule 4 starts from the state before the step
            F, s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7] = laws.general_reverse(
                e, *before[:5], before[6], before[7], yt, yc, ca, cb, 0, cx, cy, cds, cs0, b.cs1, off)
        want = twin.general_nonlinear(np.array([e]), st, ca, cb, np.array([yt]), np.array([yc]), cx, cy, cds, cs0,
                                      b.cs1, off)[0]  # fmt: skip
        assert F == want and s == [float(v) for v in st[:, 0]], e
    if np.isfinite(yt) and np.isfinite(yc):
        assert reversals > 0  # the path reaches rule 4


def test_rate_segment_fold_equals_the_rate_elastic_twin(curves: tuple[Any, dict[str, int]]) -> None:
    """``rate_segment`` folded over the neighbouring pairs, as both fast kernels do, against
    ``materials.rate_elastic`` at random elongations and rates (below, between, above the rates)."""
    b, idx = curves
    cx, cy, cds, cs0, off = _args(b)
    rc = np.array([idx["soft"], idx["load"], idx["stiff"]])
    rates = np.array([[0.5], [2.0], [6.0]])
    rng = np.random.default_rng(RNG_SEED + 5)
    for e, r in zip(rng.uniform(-0.25, 0.25, 200), rng.uniform(-9.0, 9.0, 200), strict=True):
        F = laws.curve_at(rc[0], e, 0, cx, cy, cds, cs0, off)
        for k in range(len(rc) - 1):
            F = laws.rate_segment(F, abs(r), rates[k, 0], rates[k + 1, 0],
                                  laws.curve_at(rc[k], e, 0, cx, cy, cds, cs0, off),
                                  laws.curve_at(rc[k + 1], e, 0, cx, cy, cds, cs0, off))  # fmt: skip
        assert F == twin.rate_elastic(np.array([e]), np.array([r]), rc, rates, cx, cy, cds, cs0, off)[0], (e, r)


def test_small_laws_equal_their_twins() -> None:
    """The one-line laws and the reference's NumPy twins of the knot and wall laws."""
    rng = np.random.default_rng(RNG_SEED + 6)
    for _ in range(200):
        a, bb, c, d, e = rng.normal(0.0, 1.0, 5)
        assert laws.linear_force(a, bb) == a * bb and laws.damper_force(a, bb) == a * bb
        assert laws.nonlinear_force(a) == a
        assert laws.knot_peak(abs(a), bb, bb + abs(c), d, e) == knot_peak_np(np.array([abs(a)]), np.array([bb]),
                                                                             np.array([bb + abs(c)]), np.array([d]),
                                                                             np.array([e]))[0]  # fmt: skip
        assert laws.wall_hold(a, bb, abs(c) + 0.1) == wall_hold_np(np.array([a]), np.array([bb]),
                                                                   np.array([abs(c) + 0.1]))[0]  # fmt: skip
        fp, energy = wall_penalty_np(np.array([abs(a)]), np.array([bb]))
        assert laws.wall_penalty(abs(a), bb) == (fp[0], energy[0])


def test_energy_balance_and_instability_laws_equal_their_twins() -> None:
    """``energy_balance``, ``unstable_limit`` and ``unstable`` against the reference's NumPy twins, bit
    for bit, on random energies, and the instability verdict on balance errors at, above and below the
    limit, infinite and not a number (a NaN balance is unstable)."""
    rng = np.random.default_rng(RNG_SEED + 7)
    for _ in range(200):
        ke, ie, wall, e0, work = rng.normal(0.0, 1.0e3, 5)
        scale, wmax, floor = np.abs(rng.normal(0.0, 1.0e3, 3))
        bal = laws.energy_balance(ke, ie, wall, e0, work)
        assert bal == energy_balance_np(*(np.array([x]) for x in (ke, ie, wall, e0, work)))[0]
        limit = laws.unstable_limit(scale, wmax, floor)
        assert limit == unstable_limit_np(np.array([scale]), np.array([wmax]), np.array([floor]))[0]
        for b in (bal, limit, np.nextafter(limit, np.inf), 0.0, np.inf, np.nan):
            assert laws.unstable(b, limit) == unstable_np(np.array([b]), np.array([limit]))[0], (b, limit)
    assert laws.unstable(np.nan, 1.0) and laws.unstable(2.0, 1.0) and not laws.unstable(1.0, 1.0)


def test_prescribed_motion_laws_equal_their_twins() -> None:
    """``prescribed_time``, ``prescribed_velocity`` and ``prescribed_step`` against the reference's NumPy
    twins, bit for bit, for each kind of prescribed motion, in the last step and before it; and the
    closed forms: a displacement curve lands the dof on ``x0 + scale tc``, a velocity curve is the velocity."""
    from crashstudy.vocabulary.codes import PM_CODES

    rng = np.random.default_rng(RNG_SEED + 8)
    arr = lambda *xs: tuple(np.array([x]) for x in xs)  # noqa: E731
    for _ in range(100):
        t, dt = abs(rng.normal(0.0, 1.0)), abs(rng.normal(0.0, 1e-3)) + 1e-6
        x0, scale, tc, x, vo, pa = rng.normal(0.0, 1.0, 6)
        dtn = 0.5 * dt if rng.random() < 0.2 else dt
        for kind in PM_CODES.values():
            assert laws.prescribed_time(kind, t, dt) == prescribed_time_np(kind, *arr(t, dt))[0]
            vn = laws.prescribed_velocity(kind, x0, scale, tc, x, vo, dt, dtn)
            assert vn == prescribed_velocity_np(kind, *arr(x0, scale, tc, x, vo, dt, dtn))[0]
            for last in (False, True):
                got = laws.prescribed_step(last, vn, vo, pa, dtn)
                want = prescribed_step_np(np.array([last]), *arr(vn, vo, pa, dtn))
                assert got == (want[0][0], want[1][0])
        landed = x + dt * laws.prescribed_velocity(PM_CODES["displacement"], x0, scale, tc, x, vo, dt, dtn)
        assert abs(landed - (x0 + scale * tc)) <= 1e-12 * (1.0 + abs(x0 + scale * tc) + abs(x) / dt * dt)
        assert laws.prescribed_velocity(PM_CODES["velocity"], x0, scale, tc, x, vo, dt, dtn) == scale * tc


def test_stop_test_law_equals_its_twin() -> None:
    """``stop_test`` against the reference's twin on random sums (a quarter of them at the thresholds
    exactly, both sides of ``<=``), with and without ``opening``."""
    rng = np.random.default_rng(RNG_SEED + 9)
    for _ in range(300):
        kef, psum, scale, wmax = rng.uniform(0.0, 1.0, 4)
        fsum, ke = rng.uniform(0.0, 1.0, 2) * np.array([psum, scale + wmax])
        if rng.random() < 0.25:
            fsum, ke = kef * psum, kef * (scale + wmax)
        for opening in (False, True):
            got = laws.stop_test(kef, fsum, psum, ke, scale, wmax, opening)
            want = stop_test_np(*(np.array([x]) for x in (kef, fsum, psum, ke, scale, wmax, opening)))[0]
            assert got == want, (kef, fsum, psum, ke, scale, wmax, opening)
    assert laws.stop_test(0.1, 1.0, 10.0, 5.0, 10.0, 0.0, True) and not laws.stop_test(0.1, 1.0, 10.0, 5.0, 10.0, 0.0, False)
