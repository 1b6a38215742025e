"""Every path of the spring material laws (docs/format.md), checked against an independent oracle.

The oracle below is a small pure-Python, scalar, event-by-event implementation of docs/format.md
(``general_nonlinear`` rules 1-4, ``crush``, ``nonlinear_elastic``), written from that text and not
from :mod:`crashstudy.arrays.material_laws`. Each test drives one 1-D spring through a prescribed
elongation history: node ``a`` fixed at x = 0, node ``b`` at x = 1 whose displacement follows a
piecewise-linear time curve ``path``. The output interval equals the time step, so every step the
kernel takes is sampled and the oracle sees exactly the elongations the kernel saw (it is evaluated
on the ``spring_elongation`` history; the two histories it reads are the only ones kept). Each path's
turning points fall on samples; its time step is a few times below the critical one and still puts 4 to
150 samples in every segment of the path, so every branch of a law is walked step by step (5x more
steps only repeated the same branches: the NumPy reference takes about 1 ms a step here). The spring
force history must match the oracle to 1e-9 of the peak force, pass through hand-computed values at the
turning points, and be the same with the compiled and the reference kernels (to 1e-12 of the peak).

The mass of ``b`` does not enter the spring force (the motion of ``b`` is prescribed and the spring
is massless); it only sets the critical step that a fixed ``dt`` must stay below.
"""

from __future__ import annotations

import inspect
import math
from typing import Any

import numpy as np
import pytest

from helpers import run_model

ORACLE_RTOL = 1e-9  # oracle vs kernel, relative to the peak |force|
KERNEL_RTOL = 1e-12  # compiled vs reference kernel, relative to the peak


# --------------------------------------------------------------------------------------------------
# Independent oracle (from docs/format.md only)
# --------------------------------------------------------------------------------------------------


class PL:
    """Piecewise-linear curve through (x_k, y_k), extended beyond both ends along the end segments."""

    def __init__(self, x: list[float], y: list[float]) -> None:
        assert len(x) == len(y) >= 2 and all(b > a for a, b in zip(x, x[1:], strict=False))
        self.x = [float(v) for v in x]
        self.y = [float(v) for v in y]

    def _segment(self, e: float) -> int:
        n = len(self.x)
        for k in range(n - 2, 0, -1):
            if e >= self.x[k]:
                return k
        return 0

    def __call__(self, e: float) -> float:
        k = self._segment(e)
        x0, x1, y0, y1 = self.x[k], self.x[k + 1], self.y[k], self.y[k + 1]
        return y0 + (y1 - y0) * (e - x0) / (x1 - x0)

    def solve(self, f: float, lo: float = -math.inf, hi: float = math.inf) -> float:
        """The single abscissa in (lo, hi) where the curve equals ``f``; fails if none or several.

        The oracle refuses ambiguous cases (a flat stretch at ``f``, or several crossings) rather
        than guess: the tests are built so that each crossing they need is unique.
        """
        n = len(self.x)
        found: list[float] = []
        for k in range(n - 1):
            x0, x1, y0, y1 = self.x[k], self.x[k + 1], self.y[k], self.y[k + 1]
            left = -math.inf if k == 0 else x0
            right = math.inf if k == n - 2 else x1
            if y1 == y0:
                assert y0 != f, "oracle: the curve is flat at the force sought (ambiguous)"
                continue
            xs = x0 + (f - y0) * (x1 - x0) / (y1 - y0)
            if (
                left <= xs <= right
                and lo < xs < hi
                and not any(abs(xs - z) <= 1e-12 * (1 + abs(z)) for z in found)
            ):
                found.append(xs)
        assert len(found) == 1, f"oracle: {len(found)} crossings of {f} in ({lo}, {hi})"
        return found[0]


class GeneralNonlinearOracle:
    """``general_nonlinear`` (docs/format.md), one elongation at a time.

    State: which direction the spring is currently referenced to (``None`` before any yield, +1
    tension, -1 compression), per direction whether it has yielded and its extreme (e*, F*), and the
    shift of the loading curve along the elongation axis (rule 4).
    """

    def __init__(
        self, loading: PL, unloading: PL, tension_yield: float | None, compression_yield: float | None
    ) -> None:
        self.L, self.U = loading, unloading
        self.initial_yield = {+1: tension_yield, -1: compression_yield}
        self.yielded = {+1: False, -1: False}
        self.extreme: dict[int, tuple[float, float]] = {}
        self.active: int | None = None
        self.shift = 0.0

    def on_loading(self, e: float) -> float:
        return self.L(e - self.shift)

    def threshold(self, d: int) -> float | None:
        """Force at which direction ``d`` (re)starts loading: its F* once yielded, else its yield."""
        return self.extreme[d][1] if self.yielded[d] else self.initial_yield[d]

    def force(self, e: float) -> float:
        if self.active is None:  # rule 1: elastic range, on L both ways
            F = self.on_loading(e)
            for d in (+1, -1):
                y = self.initial_yield[d]
                if y is not None and d * F >= d * y:  # rule 2: the force on L reached a yield force
                    self._start(d, e, F)
            return F
        d = self.active
        e_star, F_star = self.extreme[d]
        if d * (e - e_star) >= 0:  # rule 2: beyond the extreme of this direction -> on L
            F = self.on_loading(e)
            self.extreme[d] = (e, F)
            return F
        F = F_star + self.U(e - e_star)  # rule 3: shifted unloading line
        o = -d
        thr = self.threshold(o)
        if thr is not None and o * (F - thr) >= 0:  # rule 4: the other direction's yield force
            crossing = e_star + self.U.solve(thr - F_star)  # where the line reached thr
            on_l = self.L.solve(thr, *((0.0, math.inf) if o > 0 else (-math.inf, 0.0)))
            self.shift = crossing - on_l  # L(crossing - shift) = thr: shifted through that point
            F = self.on_loading(e)
            self._start(o, e, F)
        return F

    def _start(self, d: int, e: float, F: float) -> None:
        self.yielded[d] = True
        self.active = d
        self.extreme[d] = (e, F)


class CrushOracle:
    """``crush`` (docs/format.md): F = min(0, L(e)) at new crush, elastic spring-back line, separation."""

    def __init__(self, loading: PL, unloading_stiffness: float) -> None:
        self.L, self.k = loading, unloading_stiffness
        self.e_min, self.F_star = 0.0, 0.0

    def force(self, e: float) -> float:
        if e <= self.e_min:
            self.e_min, self.F_star = e, min(0.0, self.L(e))
            return self.F_star
        return min(0.0, self.F_star + self.k * (e - self.e_min))


class ElasticOracle:
    def __init__(self, curve: PL) -> None:
        self.C = curve

    def force(self, e: float) -> float:
        return self.C(e)


def test_oracle_curve_helpers() -> None:
    """The oracle's own curve: interpolation, extrapolation and the crossing finder."""
    c = PL([-1.0, 0.0, 2.0], [-10.0, 0.0, 4.0])
    assert c(-3.0) == -30.0 and c(-0.5) == -5.0 and c(1.0) == 2.0 and c(4.0) == 8.0
    assert c.solve(-30.0) == -3.0 and c.solve(8.0) == 4.0
    dip = PL([0.0, 0.23, 0.6, 0.9, 1.25, 1.5], [0.0, 20.0, 23.0, 18.0, 20.0, 35.0])  # Table 3
    with pytest.raises(AssertionError, match="3 crossings"):
        dip.solve(21.0, 0.0)
    assert dip.solve(30.0, 0.0) == pytest.approx(1.5 - 5.0 / 60.0, abs=1e-15)


# --------------------------------------------------------------------------------------------------
# Driving a spring through a prescribed elongation history
# --------------------------------------------------------------------------------------------------

TABLE3_LOADING = {"x": [0.0, 0.23, 0.6, 0.9, 1.25, 1.5], "y": [0.0, 20.0, 23.0, 18.0, 20.0, 35.0]}  # mm, kN
TABLE2_UNLOADING = {"x": [0.0, 0.1, 7.0], "y": [0.0, 1.0, 70.0]}  # mm, kN (as written: tension only)
TABLE4_LOADING = {"x": [-0.3, -0.27, -0.225, -0.01, 0.0], "y": [-1.0e6, -5.0e5, -1.5e5, -1.5e5, 0.0]}  # m, N
TABLE4_UNLOADING = {"x": [-0.006, 0.0, 0.006], "y": [-1.7e5, 0.0, 1.7e5]}  # m, N


def driven_spring(
    material: dict[str, Any],
    curves: dict[str, dict[str, list[float]]],
    path: list[tuple[float, float]],
    dt: float,
    units: str = "SI",
    mass: float = 1.0,
) -> dict[str, Any]:
    """A 1-D spring a-b, ``a`` fixed, ``b``'s displacement following ``path`` [(t, u), ...]."""
    end = path[-1][0]
    t, u = zip(*path, (end + 0.5, path[-1][1]), strict=True)  # hold past end_time (time curves are 0 outside)
    return {
        "name": "driven-spring",
        "units": units,
        "curves": {**curves, "path": {"x": list(t), "y": list(u)}},
        "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": mass}},
        "springs": {"s": {"nodes": ["a", "b"], "material": material}},
        "prescribed_motion": [{"node": "b", "quantity": "displacement", "direction": "x", "curve": "path"}],
        "end_time": end,
        "time_step": {"dt": dt},
        "output": {"interval": dt, "histories": ["spring_force", "spring_elongation"]},  # every step sampled
    }


class Driven:
    """Histories of one driven-spring run: time, elongation and force (compiled kernel)."""

    def __init__(self, model: dict[str, Any]) -> None:
        out, batch, plan = run_model(model, kernel="generic")
        ref, _, _ = run_model(model, kernel="reference")
        assert out.status[0] == 0 and ref.status[0] == 0
        dt = float(batch.dt[0])
        assert dt == model["time_step"]["dt"] and int(batch.out_every[0]) == 1  # every step is sampled
        self.t = np.arange(plan.n_out) * dt
        self.e = out.histories["spring_elongation"][:, 0, 0]
        self.F = out.histories["spring_force"][:, 0, 0]
        assert np.all(np.isfinite(self.e)) and np.all(np.isfinite(self.F))
        self.peak = float(np.max(np.abs(self.F)))
        # the two kernels agree
        for name in ("spring_force", "spring_elongation"):
            a, b = out.histories[name], ref.histories[name]
            scale = max(float(np.max(np.abs(b))), 1e-300)
            assert float(np.max(np.abs(a - b))) <= KERNEL_RTOL * scale, name
        # the elongation is the prescribed path (1-D, s = +1: e = u_b)
        pc = model["curves"]["path"]
        expected = np.interp(self.t, pc["x"], pc["y"])
        assert float(np.max(np.abs(self.e - expected))) <= 1e-12 * float(np.max(np.abs(expected)))

    def at(self, time: float) -> float:
        """Force at the sample nearest ``time``."""
        k = int(round(time / (self.t[1] - self.t[0])))
        assert abs(self.t[k] - time) < 1e-9 * max(1.0, time)
        return float(self.F[k])

    def check_oracle(self, oracle: Any) -> np.ndarray:
        expected = np.array([oracle.force(float(e)) for e in self.e])
        err = float(np.max(np.abs(self.F - expected)))
        assert err <= ORACLE_RTOL * self.peak, f"max |F - oracle| = {err:.3e} (peak {self.peak:.6g})"
        return expected

    def approx(self, value: float) -> Any:
        return pytest.approx(value, abs=ORACLE_RTOL * self.peak)


def gn(
    loading: dict[str, list[float]], unloading: dict[str, list[float]], ty: float | None, yc: float | None
) -> tuple[dict[str, Any], GeneralNonlinearOracle]:
    """A general_nonlinear material block (curves 'L', 'U') and its oracle."""
    mat: dict[str, Any] = {"type": "general_nonlinear", "loading": "L", "unloading": "U"}
    if ty is not None:
        mat["tension_yield"] = ty
    if yc is not None:
        mat["compression_yield"] = yc
    return mat, GeneralNonlinearOracle(PL(**loading), PL(**unloading), ty, yc)


# --------------------------------------------------------------------------------------------------
# general_nonlinear
# --------------------------------------------------------------------------------------------------


def test_elastic_load_and_unload_inside_the_yield_band_follow_the_loading_curve_both_ways() -> None:
    """Paper points 1-2 (Tables 2-3, mm/kN, tension_yield 20): below yield, unloading stays on L."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, 20.0, None)
    # u [mm] vs t [ms]: 0 -> 0.2 (point 1) -> 0.05 (point 2) -> 0.2 -> -0.1 (compression, elastic) -> 0
    path = [(0.0, 0.0), (2.0, 0.2), (3.5, 0.05), (5.0, 0.2), (8.0, -0.1), (9.0, 0.0)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.05, "mm-ms-kg-kN"))
    expected = run.check_oracle(oracle)
    k = 20.0 / 0.23  # kN/mm, first segment of L (also its extrapolation into compression)
    assert np.max(np.abs(expected - k * run.e)) <= 1e-12 * run.peak  # F = L(e) throughout
    assert run.at(2.0) == run.approx(17.391304347826086)  # point 1
    assert run.at(3.5) == run.approx(4.3478260869565215)  # point 2: on L, not 17.39 + U(-0.15) = 15.89
    assert run.at(5.0) == run.approx(17.391304347826086)
    assert run.at(8.0) == run.approx(-8.695652173913043)
    assert run.at(9.0) == run.approx(0.0)
    assert oracle.active is None  # never yielded


def test_tension_yield_unloads_on_the_shifted_unloading_curve_and_reloads_to_rejoin_loading() -> None:
    """Paper points 3-5 (Tables 2-3, tension_yield 20 kN): the unloading curve is shifted to (e*, F*),
    reloading runs back along it and rejoins L at e*."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, 20.0, None)
    path = [(0.0, 0.0), (2.0, 0.2), (3.5, 0.05), (16.0, 1.3), (21.0, 0.8), (27.0, 1.4), (30.0, 1.4)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.05, "mm-ms-kg-kN"))
    run.check_oracle(oracle)
    assert run.at(2.0) == run.approx(17.391304347826086)  # point 1
    assert run.at(3.5) == run.approx(4.3478260869565215)  # point 2
    assert run.at(16.0) == run.approx(23.0)  # point 3: L(1.3) = 20 + 60 * 0.05; e* = 1.3, F* = 23
    assert run.at(21.0) == run.approx(18.0)  # point 4: 23 + U(0.8 - 1.3) = 23 - 5 (L(0.8) would be 19.67)
    assert run.at(23.0) == run.approx(20.0)  # reloading on the same line, e = 1.0 (L(1.0) = 18.57)
    assert run.at(26.0) == run.approx(23.0)  # back at e* = 1.3
    assert run.at(27.0) == run.approx(29.0)  # point 5: on L again, 20 + 60 * 0.15
    assert oracle.active == +1 and oracle.extreme[+1] == (pytest.approx(1.4), pytest.approx(29.0))


def test_compression_yield_with_table4_cabin_curves() -> None:
    """Table 4 (m, N), compression_yield -150 kN, no tension yield: elastic on L, yield at -10 mm,
    plateau, stiffening, unloading on the shifted unloading line far into tension (never yields in
    tension), reloading back onto L beyond e*."""
    mat, oracle = gn(TABLE4_LOADING, TABLE4_UNLOADING, None, -150000.0)
    path = [
        (0.0, 0.0),
        (0.005, -0.005),
        (0.008, -0.002),
        (0.156, -0.15),
        (0.256, -0.25),
        (0.266, -0.24),
        (0.276, -0.23),
        (0.306, -0.26),
        (0.31, -0.26),
    ]
    run = Driven(driven_spring(mat, {"L": TABLE4_LOADING, "U": TABLE4_UNLOADING}, path, 2.5e-4, "SI"))
    run.check_oracle(oracle)
    ku = 1.7e5 / 0.006
    f_star = -1.5e5 - 0.025 * 3.5e5 / 0.045  # L(-0.25) = -344444.44 N
    assert run.at(0.005) == run.approx(-75000.0)  # elastic, 1.5e7 N/m
    assert run.at(0.008) == run.approx(-30000.0)  # unloaded along L (not yielded)
    assert run.at(0.156) == run.approx(-150000.0)  # yielded at -0.01 m, on the plateau
    assert run.at(0.256) == run.approx(f_star)
    assert run.at(0.266) == run.approx(f_star + 0.01 * ku)  # -61111.11: unloading line through (e*, F*)
    assert run.at(0.276) == run.approx(f_star + 0.02 * ku)  # +222222.22 N: tension on the line
    assert run.at(0.286) == run.approx(f_star + 0.01 * ku)  # reloading on the same line
    assert run.at(0.296) == run.approx(f_star)  # back at e* = -0.25
    assert run.at(0.306) == run.approx(-500000.0 + 0.01 * 3.5e5 / 0.045)  # L(-0.26) = -422222.22
    assert oracle.active == -1 and not oracle.yielded[+1]


def test_reverse_yield_follows_the_shifted_loading_curve_and_the_tension_threshold_becomes_f_star() -> None:
    """Rule 4 both ways. L: slope 100 to +-1 (+-100 N), then 50; U: slope 1000; yields +100 / -100.

    - load to e = 1.5: yield at 1, e_t* = 1.5, F_t* = 125;
    - unload: 125 + 1000 (e - 1.5) reaches -100 (initial compression yield) at 1.275; L(x) = -100 at
      x = -1, so the shift is 2.275; at e = 0.775, F = L(-1.5) = -125 = F_c*;
    - reload: -125 + 1000 (e - 0.775) reaches F_t* = 125 (not the initial 100) at 1.025; L(x) = 125
      at x = 1.5, shift -0.475; at e = 1.525, F = L(2.0) = 150; at 1.825, L(2.3) = 165 (extrapolated);
    - unload again: 165 + 1000 (e - 1.825) reaches F_c* = -125 at 1.535; shift 1.535 + 1.5 = 3.035;
      at e = 1.2, F = L(-1.835) = -141.75; reload to 1.3 on the line: -41.75.
    """
    L = {"x": [-2.0, -1.0, 0.0, 1.0, 2.0], "y": [-150.0, -100.0, 0.0, 100.0, 150.0]}
    U = {"x": [-1.0, 0.0, 1.0], "y": [-1000.0, 0.0, 1000.0]}
    mat, oracle = gn(L, U, 100.0, -100.0)
    path = [(0.0, 0.0), (1.5, 1.5), (2.225, 0.775), (2.975, 1.525), (3.275, 1.825), (3.9, 1.2), (4.0, 1.3)]
    run = Driven(driven_spring(mat, {"L": L, "U": U}, path, 5.0e-3))
    run.check_oracle(oracle)
    assert run.at(1.5) == run.approx(125.0)
    assert run.at(1.6) == run.approx(25.0)  # e = 1.4, on the unloading line
    assert run.at(2.0) == run.approx(-113.75)  # e = 1.0, compression loading curve shifted by 2.275
    assert run.at(2.225) == run.approx(-125.0)
    assert run.at(2.4) == run.approx(50.0)  # e = 0.95, unloading line from the compression extreme
    assert run.at(2.6) == run.approx(131.25)  # e = 1.15, tension curve shifted by -0.475 (not by 0)
    assert run.at(2.975) == run.approx(150.0)
    assert run.at(3.275) == run.approx(165.0)
    assert run.at(3.9) == run.approx(-141.75)
    assert run.at(4.0) == run.approx(-41.75)
    assert oracle.shift == pytest.approx(3.035, abs=1e-6)


def test_absent_tension_yield_never_yields_in_tension() -> None:
    """No tension_yield: far past 20 kN in tension the spring stays on L both ways; after a compression
    yield, the unloading line runs into tension without ever switching to the loading curve."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, None, -5.0)
    path = [(0.0, 0.0), (14.0, 1.4), (25.0, 0.3), (36.5, 1.45), (51.0, 0.0), (52.0, -0.1), (68.0, 1.5)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.1, "mm-ms-kg-kN"))
    expected = run.check_oracle(oracle)
    first = run.t <= 51.0 + 1e-9
    loading = PL(**TABLE3_LOADING)
    on_l = np.array([loading(e) for e in run.e[first]])
    assert np.max(np.abs(expected[first] - on_l)) <= 1e-12 * run.peak  # pure elastic on L in tension
    assert run.at(14.0) == run.approx(29.0)
    assert run.at(25.0) == run.approx(20.0 + 3.0 / 0.37 * 0.07)  # L(0.3), unloading on L
    assert run.at(36.5) == run.approx(32.0)
    assert run.at(51.0) == run.approx(0.0)
    f_c = -0.1 * 20.0 / 0.23  # L(-0.1), extrapolated; compression yielded at -5 kN
    assert run.at(52.0) == run.approx(f_c)
    assert run.at(68.0) == run.approx(f_c + 10.0 * 1.6)  # +7.30 kN in tension, still on the line
    assert not oracle.yielded[+1]


def test_non_monotonic_loading_curve_after_yield_follows_the_dip() -> None:
    """Table 3's dip (23 kN at 0.6 mm, 18 kN at 0.9 mm): past yield the force follows L down the dip
    (e* is the largest elongation, F* the force there, not the largest force); unloading from
    e* = 1.0 runs on the line through (1.0, 18.57)."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, 20.0, None)
    path = [(0.0, 0.0), (10.0, 1.0), (13.0, 0.7), (21.0, 1.5), (26.0, 1.0)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.05, "mm-ms-kg-kN"))
    run.check_oracle(oracle)
    f_star = 18.0 + 2.0 / 0.35 * 0.1  # L(1.0) = 18.571
    assert run.at(6.0) == run.approx(23.0)
    assert run.at(9.0) == run.approx(18.0)  # below the 20 kN yield, still on L
    assert run.at(10.0) == run.approx(f_star)
    assert run.at(13.0) == run.approx(f_star - 3.0)  # 15.57 (L(0.7) would be 21.33)
    assert run.at(16.0) == run.approx(f_star)  # back at e* on the line
    assert run.at(21.0) == run.approx(35.0)
    assert run.at(26.0) == run.approx(30.0)


# --------------------------------------------------------------------------------------------------
# crush and nonlinear_elastic
# --------------------------------------------------------------------------------------------------


def test_crush_loads_springs_back_separates_and_recontacts_on_the_same_line() -> None:
    """crush: F = min(0, L(e)) at new crush; spring-back with unloading_stiffness; no force when
    separated (also in tension, where L > 0); contact resumes on the same line; crushing beyond the
    previous e_min follows L again."""
    L = {"x": [-0.2, -0.01, 0.0, 0.1], "y": [-2.0e4, -1.0e4, 0.0, 5.0e3]}
    ku = 5.0e6
    mat = {"type": "crush", "loading": "L", "unloading_stiffness": ku}
    # 0.5 m/s: crush to -50 mm, spring back 1 mm, separate, pull to +50 mm, come back, crush to -100 mm
    path = [
        (0.0, 0.0),
        (0.1, -0.05),
        (0.102, -0.049),
        (0.12, -0.04),
        (0.3, 0.05),
        (0.496, -0.048),
        (0.5, -0.05),
        (0.6, -0.1),
        (0.8, 0.0),
    ]
    run = Driven(driven_spring(mat, {"L": L}, path, 5.0e-4))
    oracle = CrushOracle(PL(**L), ku)
    run.check_oracle(oracle)
    f_star = -1.0e4 - 0.04 * 1.0e4 / 0.19  # L(-0.05) = -12105.26 N
    assert run.at(0.1) == run.approx(f_star)
    assert run.at(0.102) == run.approx(f_star + ku * 0.001)  # spring-back: -7105.26
    assert run.at(0.12) == run.approx(0.0)  # separated
    assert run.at(0.3) == run.approx(0.0)  # tension: a crush spring cannot pull (L(0.05) = +2500)
    assert run.at(0.496) == run.approx(f_star + ku * 0.002)  # contact again on the same line: -2105.26
    assert run.at(0.5) == run.approx(f_star)
    assert run.at(0.6) == run.approx(-1.0e4 - 0.09 * 1.0e4 / 0.19)  # L(-0.1) = -14736.84
    assert run.at(0.8) == run.approx(0.0)
    assert np.all(run.F <= 0.0)
    assert oracle.e_min == pytest.approx(-0.1)


def test_nonlinear_elastic_extrapolates_beyond_both_ends_of_its_curve() -> None:
    """Material curves extrapolate along their first/last segment (docs/format.md): slope 60 beyond +-1."""
    C = {"x": [-1.0, -0.5, 0.0, 0.5, 1.0], "y": [-80.0, -50.0, 0.0, 60.0, 90.0]}
    mat = {"type": "nonlinear_elastic", "curve": "C"}
    path = [(0.0, 0.0), (3.0, 3.0), (9.0, -3.0), (12.24, 0.24)]
    run = Driven(driven_spring(mat, {"C": C}, path, 2.0e-2))
    run.check_oracle(ElasticOracle(PL(**C)))
    assert run.at(2.0) == run.approx(150.0)
    assert run.at(3.0) == run.approx(210.0)  # 90 + 60 * 2
    assert run.at(5.0) == run.approx(90.0)  # unloads on the same curve
    assert run.at(7.5) == run.approx(-110.0)  # e = -1.5
    assert run.at(9.0) == run.approx(-200.0)  # -80 - 60 * 2
    assert run.at(12.24) == run.approx(28.8)


def test_time_curves_are_zero_outside_their_range() -> None:
    """Loads scaled by time curves act only inside the curve's range (no extrapolation): on a free
    mass the velocity changes by the curves' impulse only. A triangle 0 -> 1 -> 0 on [0.1, 0.3] s
    (force 3 N, impulse 0.3 N s; extrapolated it would be -1 at t = 0) and a rectangle 1 on
    [0.4005, 0.6005] s (force -1 N, impulse -0.2 N s; extrapolated it would act for ever)."""
    model = {
        "name": "free-mass",
        "curves": {
            "tri": {"x": [0.1, 0.2, 0.3], "y": [0.0, 1.0, 0.0]},
            "box": {"x": [0.4005, 0.6005], "y": [1.0, 1.0]},
        },
        "nodes": {"p": {"position": [0.0], "mass": 2.0}},
        "initial_velocity": {"p": [0.5]},
        "loads": [
            {"node": "p", "force": [3.0], "curve": "tri"},
            {"node": "p", "force": [-1.0], "curve": "box"},
        ],
        "end_time": 1.0,
        "time_step": {"dt": 1.0e-3},
        "output": {"interval": 1.0e-3},
    }
    out, _, plan = run_model(model, kernel="generic")
    ref, _, _ = run_model(model, kernel="reference")
    t = np.arange(plan.n_out) * 1.0e-3
    v = out.histories["velocity"][:, 0, 0, 0]
    a = out.histories["acceleration"][:, 0, 0, 0]
    assert np.max(np.abs(v - ref.histories["velocity"][:, 0, 0, 0])) <= KERNEL_RTOL
    assert np.max(np.abs(a - ref.histories["acceleration"][:, 0, 0, 0])) <= KERNEL_RTOL
    tol = 1e-9
    before, between, after = t < 0.1 - 1e-9, (t > 0.3 + 1e-9) & (t < 0.4), t > 0.601
    assert np.max(np.abs(v[before] - 0.5)) <= tol and np.max(np.abs(a[before])) == 0.0
    assert np.max(np.abs(v[between] - (0.5 + 0.3 / 2.0))) <= tol and np.max(np.abs(a[between])) == 0.0
    assert np.max(np.abs(v[after] - (0.5 + 0.1 / 2.0))) <= tol and np.max(np.abs(a[after])) == 0.0
    assert a[int(round(0.2 / 1.0e-3))] == pytest.approx(1.5, abs=1e-9)  # peak of the triangle: 3 N / 2 kg


# --------------------------------------------------------------------------------------------------
# Found while writing these tests: a memory-safety bug of the compiled kernel (regression test)
# --------------------------------------------------------------------------------------------------


def test_compiled_kernel_writes_no_energy_history_when_none_is_requested(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``output: {histories: [spring_force, spring_elongation]}`` must not write energy histories.

    The compiled kernel gets a (1, 4, 1) placeholder for the energy histories when none is requested.
    At commit 142f4f2 it wrote ``h_energy[r, k, q]`` for every sample ``r`` regardless; numba does not
    check bounds, so real runs wrote past the buffer ('free(): invalid pointer', segfaults, hangs and a
    wrong force history were observed). 6e0b3d2 guards the write. Here the placeholder is replaced
    by a C-contiguous view of the first row of a larger NaN array, so any stray write lands,
    harmlessly and visibly, in its other rows (this test fails on 142f4f2's kernel).
    """
    from crashstudy.kernel import compiled

    real = compiled._run
    slot = list(inspect.signature(real.py_func).parameters).index("H")  # the histories record
    caught: dict[str, np.ndarray] = {}

    def guarded(*args: Any) -> Any:
        args = list(args)
        if args[slot].energy.shape == (1, 4, 1):  # the placeholder: no energy history requested
            guard = np.full((64, 4, 1), np.nan)
            caught["guard"] = guard
            args[slot] = args[slot]._replace(energy=guard[:1])
        return real(*args)

    monkeypatch.setattr(compiled, "_run", guarded)
    model = {
        "name": "k",
        "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
        "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
        "initial_velocity": {"b": [1.0]},
        "end_time": 0.5,
        "time_step": {"dt": 0.01},
        "output": {"interval": 0.01, "histories": ["spring_force", "spring_elongation"]},
    }
    out, _, plan = run_model(model, kernel="generic")
    assert plan.n_out == 51 and "guard" in caught
    assert np.all(np.isnan(caught["guard"][1:])), "energy samples written outside the (1, 4, 1) buffer"
