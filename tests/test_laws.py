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
from crashstudy.kernel import laws, step_laws
from crashstudy.kernel.reference_knots import knot_peak_np
from crashstudy.kernel.step_twins import (
    advance_np,
    axis_2d_np,
    energy_balance_np,
    half_step_np,
    kinetic_np,
    prescribed_step_np,
    prescribed_time_np,
    prescribed_velocity_np,
    spring_extremes_np,
    stop_test_np,
    unstable_limit_np,
    unstable_np,
    wall_dof_np,
    wall_hold_np,
    wall_penalty_np,
    wall_plane_np,
    wall_work_np,
)

RNG_SEED = 20261126
CURVES = {
    "load": {"x": [-0.1, 0.0, 0.01, 0.02, 0.2], "y": [-1.0e4, 0.0, 600.0, 400.0, 900.0]},
    "unload": {"x": [-0.1, 0.0, 0.1], "y": [-1.0e4, 0.0, 1.0e4]},
    "crush": {"x": [-0.3, -0.01, 0.0], "y": [-3000.0, -1500.0, 0.0]},
    "soft": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-800.0, -500.0, 0.0, 500.0, 800.0]},
    "stiff": {"x": [-0.2, 0.0, 0.1, 0.2], "y": [-4000.0, 0.0, 1500.0, 2500.0]},
    "pulse": {"x": [0.0, 0.01, 0.03], "y": [0.0, 1.0, 0.0]},
}


@pytest.fixture(scope="module")
def curves() -> tuple[Any, dict[str, int]]:
    """The curve arrays of a batch holding CURVES (one variant) and each curve's index."""
    model = {
        "name": "law-curves",
        "curves": CURVES,
        "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
        "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 1.0}}},
        "loads": [{"node": "b", "force": [1.0], "curve": "pulse"}],
        "end_time": 0.01,
    }
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
            assert (
                laws.curve_at(c, e, 0, cx, cy, cds, cs0, off)
                == twin.curve_eval(c, np.array([e]), cx, cy, cds, cs0, off)[0]
            ), name
    c = idx["pulse"]
    for t in np.concatenate([rng.uniform(-0.01, 0.04, 50), [0.0, 0.03, 0.03 + 1e-12, -1e-12]]):
        assert (
            laws.time_curve_at(c, t, 0, cx, cy, cds, cs0, off)
            == twin.time_curve_eval(c, np.array([t]), cx, cy, cds, cs0, off)[0]
        )


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
def test_general_law_and_reversal_equal_their_twin_along_a_random_path(
    curves: tuple[Any, dict[str, int]], yields: tuple[float, float]
) -> None:
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
        F, s[0], s[1], s[2], s[3], s[4], s[6], s[7], rev = laws.general_law(
            e, s[0], s[1], s[2], s[3], s[4], s[6], s[7], L, Ut, Uc, yt, yc
        )
        if rev:
            reversals += 1
            before = [float(v) for v in st[:, 0]]  # rule 4 starts from the state before the step
            F, s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7] = laws.general_reverse(
                e, *before[:5], before[6], before[7], yt, yc, ca, cb, 0, cx, cy, cds, cs0, b.cs1, off
            )
        want = twin.general_nonlinear(
            np.array([e]), st, ca, cb, np.array([yt]), np.array([yc]), cx, cy, cds, cs0, b.cs1, off
        )[0]
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
            F = laws.rate_segment(
                F,
                abs(r),
                rates[k, 0],
                rates[k + 1, 0],
                laws.curve_at(rc[k], e, 0, cx, cy, cds, cs0, off),
                laws.curve_at(rc[k + 1], e, 0, cx, cy, cds, cs0, off),
            )
        assert F == twin.rate_elastic(np.array([e]), np.array([r]), rc, rates, cx, cy, cds, cs0, off)[0], (
            e,
            r,
        )


def test_small_laws_equal_their_twins() -> None:
    """The one-line laws and the reference's NumPy twins of the knot and wall laws."""
    rng = np.random.default_rng(RNG_SEED + 6)
    for _ in range(200):
        a, bb, c, d, e = rng.normal(0.0, 1.0, 5)
        assert laws.linear_force(a, bb) == a * bb and laws.damper_force(a, bb) == a * bb
        assert laws.nonlinear_force(a) == a
        assert (
            laws.knot_peak(abs(a), bb, bb + abs(c), d, e)
            == knot_peak_np(
                np.array([abs(a)]), np.array([bb]), np.array([bb + abs(c)]), np.array([d]), np.array([e])
            )[0]
        )
        assert (
            step_laws.wall_hold(a, bb, abs(c) + 0.1)
            == wall_hold_np(np.array([a]), np.array([bb]), np.array([abs(c) + 0.1]))[0]
        )
        fp, energy = wall_penalty_np(np.array([abs(a)]), np.array([bb]))
        assert step_laws.wall_penalty(abs(a), bb) == (fp[0], energy[0])


def test_energy_balance_and_instability_laws_equal_their_twins() -> None:
    """``energy_balance``, ``unstable_limit`` and ``unstable`` against the reference's NumPy twins, bit
    for bit, on random energies, and the instability verdict on balance errors at, above and below the
    limit, infinite and not a number (a NaN balance is unstable)."""
    rng = np.random.default_rng(RNG_SEED + 7)
    for _ in range(200):
        ke, ie, wall, e0, work = rng.normal(0.0, 1.0e3, 5)
        scale, wmax, floor = np.abs(rng.normal(0.0, 1.0e3, 3))
        bal = step_laws.energy_balance(ke, ie, wall, e0, work)
        assert bal == energy_balance_np(*(np.array([x]) for x in (ke, ie, wall, e0, work)))[0]
        limit = step_laws.unstable_limit(scale, wmax, floor)
        assert limit == unstable_limit_np(np.array([scale]), np.array([wmax]), np.array([floor]))[0]
        for b in (bal, limit, np.nextafter(limit, np.inf), 0.0, np.inf, np.nan):
            assert step_laws.unstable(b, limit) == unstable_np(np.array([b]), np.array([limit]))[0], (
                b,
                limit,
            )
    assert (
        step_laws.unstable(np.nan, 1.0) and step_laws.unstable(2.0, 1.0) and not step_laws.unstable(1.0, 1.0)
    )


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
            assert step_laws.prescribed_time(kind, t, dt) == prescribed_time_np(kind, *arr(t, dt))[0]
            vn = step_laws.prescribed_velocity(kind, x0, scale, tc, x, vo, dt, dtn)
            assert vn == prescribed_velocity_np(kind, *arr(x0, scale, tc, x, vo, dt, dtn))[0]
            for last in (False, True):
                got = step_laws.prescribed_step(last, vn, vo, pa, dtn)
                want = prescribed_step_np(np.array([last]), *arr(vn, vo, pa, dtn))
                assert got == (want[0][0], want[1][0])
        landed = x + dt * step_laws.prescribed_velocity(
            PM_CODES["displacement"], x0, scale, tc, x, vo, dt, dtn
        )
        assert abs(landed - (x0 + scale * tc)) <= 1e-12 * (1.0 + abs(x0 + scale * tc) + abs(x) / dt * dt)
        assert (
            step_laws.prescribed_velocity(PM_CODES["velocity"], x0, scale, tc, x, vo, dt, dtn) == scale * tc
        )


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
            got = step_laws.stop_test(kef, fsum, psum, ke, scale, wmax, opening)
            want = stop_test_np(*(np.array([x]) for x in (kef, fsum, psum, ke, scale, wmax, opening)))[0]
            assert got == want, (kef, fsum, psum, ke, scale, wmax, opening)
    assert step_laws.stop_test(0.1, 1.0, 10.0, 5.0, 10.0, 0.0, True) and not step_laws.stop_test(
        0.1, 1.0, 10.0, 5.0, 10.0, 0.0, False
    )


def test_node_update_laws_equal_their_twins_and_integrate_constant_acceleration_exactly() -> None:
    """``half_step``, ``advance`` and ``kinetic`` (the central-difference update both fast kernels call)
    against their NumPy twins bit for bit on random inputs, running (af 1) and stopped (af 0: x and v
    kept exactly); and the closed form: under a constant acceleration a from rest, n steps of dt land on
    x = a (n dt)^2 / 2 (central difference is exact for a quadratic path) to 1e-12 relative."""
    rng = np.random.default_rng(RNG_SEED + 10)
    arr = lambda *xs: tuple(np.array([x]) for x in xs)  # noqa: E731
    for _ in range(300):
        x, vo, a, m = rng.normal(0.0, 1.0, 4)
        dt = abs(rng.normal(0.0, 1e-3)) + 1e-7
        dtn = 0.5 * dt if rng.random() < 0.2 else dt
        vn = step_laws.half_step(vo, a, dtn)
        assert vn == half_step_np(*arr(vo, a, dtn))[0]
        for af in (1.0, 0.0):
            got = step_laws.advance(x, vo, vn, dt, af)
            want = advance_np(*arr(x, vo, vn, dt, af))
            assert got == (want[0][0], want[1][0])
        assert step_laws.advance(x, vo, vn, dt, 0.0) == (x, vo)
        assert step_laws.kinetic(a, abs(m), vo, vn) == kinetic_np(*arr(a, abs(m), vo, vn))[0]
    acc, dt, n = 3.0, 1.0e-3, 500
    x, v = 0.0, 0.0
    for k in range(n):
        vn = step_laws.half_step(v, acc, dt if k > 0 else 0.5 * dt)
        x, v = step_laws.advance(x, v, vn, dt, 1.0)
    assert abs(x - 0.5 * acc * (n * dt) ** 2) <= 1e-12 * 0.5 * acc * (n * dt) ** 2


def test_spring_extremes_law_equals_its_twin() -> None:
    """``spring_extremes`` (peak force, crush, elongation of every spring in both fast kernels) against
    its twin bit for bit, with running and stopped lanes and a breakable spring's extremes (em, ai), and
    the running maximum's closed form."""
    rng = np.random.default_rng(RNG_SEED + 11)
    for _ in range(300):
        pf, mc, me = np.abs(rng.normal(0.0, 1.0, 3))
        F, em = rng.normal(0.0, 1.0, 2)
        for af, ai in ((1.0, 1.0), (0.0, 0.0), (1.0, 0.0)):
            got = step_laws.spring_extremes(pf, mc, me, F, af, em, ai)
            want = spring_extremes_np(*(np.array([x]) for x in (pf, mc, me, F, af, em, ai)))
            assert got == tuple(w[0] for w in want)
            assert got == (max(pf, abs(F) * af), max(mc, -em * ai), max(me, em * ai))


def test_axis_2d_law_equals_its_twin_and_is_a_unit_vector() -> None:
    """``axis_2d`` (the 2-D spring direction both fast kernels call) against its twin bit for bit on
    random vectors, turned ones (previous direction reversed: collapsed) and ones of nearly zero length;
    the closed form: a spring that did not collapse has |axis| = 1 within 2 ulp and length = hypot(u)."""
    rng = np.random.default_rng(RNG_SEED + 12)
    for _ in range(300):
        u0, u1, p0, p1 = rng.normal(0.0, 1.0, 4)
        l0 = abs(rng.normal(1.0, 0.3))
        for scale, pp in ((1.0, (p0, p1)), (1.0e-12, (u0, u1)), (1.0, (-u0, -u1))):
            got = laws.axis_2d(u0 * scale, u1 * scale, pp[0], pp[1], l0)
            want = axis_2d_np(*(np.array([v]) for v in (u0 * scale, u1 * scale, pp[0], pp[1], l0)))
            assert got == tuple(w[0] for w in want)
            ax0, ax1, ln, gone = got
            assert abs(ln - np.hypot(u0 * scale, u1 * scale)) <= 4e-16 * ln
            if not gone:
                assert abs(np.hypot(ax0, ax1) - 1.0) <= 4.5e-16
    assert laws.axis_2d(1.0, 0.0, -1.0, 0.0, 1.0)[3] and laws.axis_2d(1e-13, 0.0, 1.0, 0.0, 1.0)[3]


def test_wall_geometry_and_energy_laws_equal_their_twins() -> None:
    """``wall_plane``, ``wall_dof`` and ``wall_work`` (a rigid wall's geometry and energy in both fast
    kernels) against their twins bit for bit on random 2-D nodes and walls; closed forms: the sums over
    the dofs are the dot products with the normal (1e-15), a jump along the normal of a node from rest at
    v^{n-1/2} = 0 does no wall work, and a fixed dof (free 0) keeps its velocity and acceleration."""
    rng = np.random.default_rng(RNG_SEED + 13)
    arr = lambda *xs: tuple(np.array([x]) for x in xs)  # noqa: E731
    for _ in range(200):
        v, x, p, nr = rng.normal(0.0, 1.0, (4, 2))
        nr = nr / np.hypot(*nr)
        dt = abs(rng.normal(0.0, 1e-3)) + 1e-6
        vn = gap = dist = 0.0
        for d in range(2):
            got = step_laws.wall_plane(vn, gap, dist, v[d], x[d], p[d], nr[d], dt)
            want = wall_plane_np(*arr(vn, gap, dist, v[d], x[d], p[d], nr[d], dt))
            assert got == tuple(w[0] for w in want)
            vn, gap, dist = got
        assert abs(vn - v @ nr) <= 1e-15 * (1.0 + abs(v) @ abs(nr))
        assert abs(gap - (x - p) @ nr) <= 1e-15 * (1.0 + abs(x - p) @ abs(nr))
        dvn, c, a, vo, jp, we, m = rng.normal(0.0, 1.0, 7)
        for free in (1.0, 0.0):
            got = step_laws.wall_dof(dvn, c, nr[0], free, v[0], a, vo, jp, we)
            assert got == tuple(w[0] for w in wall_dof_np(*arr(dvn, c, nr[0], free, v[0], a, vo, jp, we)))
        assert step_laws.wall_dof(dvn, c, nr[0], 0.0, v[0], a, vo, jp, we)[:2] == (v[0], a)
        assert step_laws.wall_dof(dvn, c, nr[0], 1.0, v[0], a, 0.0, jp, we)[2] == we
        assert step_laws.wall_work(abs(m), we) == wall_work_np(*arr(abs(m), we))[0] == -0.5 * abs(m) * we


def test_ramp_laws_are_the_ramp_sum(curves: tuple[Any, dict[str, int]]) -> None:
    """``ramp_start`` / ``ramp_knot`` (the curve ramp sum of ``laws.curve_at``, the generic kernel's block
    ramp and the emitted ramp) against the closed form y0 + s0 (e - x0) + sum ds_k max(0, e - x_k), bit
    for bit, and against the curve's own linear interpolation inside its points (1e-12 relative)."""
    b, idx = curves
    cx, cy, cds, cs0, off = _args(b)
    rng = np.random.default_rng(RNG_SEED + 14)
    for _ in range(200):
        y, ds, e, xk = rng.normal(0.0, 1.0, 4)
        assert laws.ramp_knot(y, ds, e, xk) == y + ds * max(0.0, e - xk)
        assert laws.ramp_start(y, ds, e, xk) == y + ds * (e - xk)
    for name in ("load", "crush", "stiff"):
        pts = CURVES[name]
        for e in rng.uniform(min(pts["x"]), max(pts["x"]), 50):
            got = laws.curve_at(idx[name], e, 0, cx, cy, cds, cs0, off)
            assert abs(got - np.interp(e, pts["x"], pts["y"])) <= 1e-12 * max(map(abs, pts["y"])), (name, e)
