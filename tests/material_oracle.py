"""The independent oracle of the material-law tests (tests/test_materials_*.py) and the driving of one
spring through a prescribed elongation history.

The oracle is a small pure-Python, scalar, event-by-event implementation of docs/format.md
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
is massless); it only sets the critical step that a fixed ``dt`` must stay below."""

from __future__ import annotations

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


# --------------------------------------------------------------------------------------------------
# Driving a spring through a prescribed elongation history
# --------------------------------------------------------------------------------------------------


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
