"""scipy ``solve_ivp`` per variant, as a user would write it: the baseline of the benchmarks.

A lean right-hand side (small NumPy arrays, no leading time axis) for the models of docs/format.md
without prescribed motion or walls, in 1-D and 2-D. The state is the one of
``tests/reference_scipy.py`` (displacements, velocities, external work, work done on every spring), so
for smooth models the two take the same steps. History-dependent materials (``crush``,
``general_nonlinear``) are integrated as a hybrid system: within a segment every spring follows one
branch of its law (a continuous function of its elongation), and terminal ``solve_ivp`` events end the
segment where a branch changes (a crush spring starts or stops crushing; a general_nonlinear spring
yields, turns, rejoins its loading curve or reaches the other direction's yield force); the branch
state is updated there, as docs/format.md describes in continuous time, and integration restarts.

:func:`solve` is what is timed; :meth:`Solution.peaks` (dense-output search for peak |F| and |a|)
and the absorbed energies are evaluated afterwards and not timed.

Modules: this one (:func:`solve`, :class:`Solution`), scipy_model_compile.py (a model dict read into
arrays) and scipy_model_equations.py (the right-hand side, the branch events and the branch switch)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from scipy_model_compile import Branch, Model, compile_model
from scipy_model_equations import _one, events_for, ext_force, force, kinematics, make_rhs, switch


@dataclass
class Segment:
    t0: float
    t1: float
    sol: Any
    ts: np.ndarray
    branches: dict[int, Branch]


@dataclass
class Solution:
    mdl: Model
    segments: list[Segment]
    nfev: int
    n_events: int
    y_end: np.ndarray

    def absorbed_energy(self) -> np.ndarray:
        return self.y_end[2 * self.mdl.nd + 1 :].copy()

    def _eval(self, seg: Segment, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """|F| (S, T) and |a| (N, T) on segment ``seg`` at times ``t``."""
        mdl = self.mdl
        N, D, nd = mdl.x0.shape[0], mdl.dim, mdl.nd
        y = seg.sol(t)
        u = y[:nd].reshape(N, D, -1)
        v = y[nd : 2 * nd].reshape(N, D, -1)
        e, edot, n = kinematics(mdl, u, v)
        F = np.array(
            [
                force(sp, seg.branches.get(s), e[s], edot[s]) * np.ones(t.size)
                for s, sp in enumerate(mdl.springs)
            ]
        )
        acc = (np.einsum("ns,sdt->ndt", mdl.incidence, F[:, None, :] * n) + ext_force(mdl, t)) * mdl.inv_mass[
            ..., None
        ]
        return np.abs(F), np.sqrt((acc * acc).sum(1))

    def peaks(self, sub: int = 16) -> dict[str, np.ndarray]:
        """Peak |F| per spring and |a| per node: dense output sampled ``sub`` times per solver step,
        each maximum then polished by a bounded scalar search."""
        best: dict[str, list[tuple[float, Segment, float, float]]] = {}
        for q, count in (("peak_force", len(self.mdl.springs)), ("peak_deceleration", self.mdl.x0.shape[0])):
            best[q] = [(-1.0, self.segments[0], 0.0, 0.0)] * count
        for seg in self.segments:
            ts = seg.ts
            if ts.size < 2:
                ts = np.array([seg.t0, seg.t1])
            grid = np.unique(
                np.concatenate([np.linspace(a, b, sub + 1) for a, b in zip(ts[:-1], ts[1:], strict=True)])
            )
            vals = dict(zip(("peak_force", "peak_deceleration"), self._eval(seg, grid), strict=True))
            h = np.diff(grid).max() if grid.size > 1 else 0.0
            for q, arr in vals.items():
                k = np.argmax(arr, axis=1)
                for c in range(arr.shape[0]):
                    if arr[c, k[c]] > best[q][c][0]:
                        t = grid[k[c]]
                        best[q][c] = (float(arr[c, k[c]]), seg, max(seg.t0, t - h), min(seg.t1, t + h))
        out = {}
        for q, items in best.items():
            row = 0 if q == "peak_force" else 1
            vals_out = []
            for c, (val, seg, a, b) in enumerate(items):
                if b > a and val > 0:
                    res = minimize_scalar(
                        lambda t, c=c, seg=seg, row=row: -self._eval(seg, np.array([t]))[row][c, 0],
                        bounds=(a, b),
                        method="bounded",
                        options={"xatol": 1e-14 * max(b, 1e-300)},
                    )
                    val = max(val, -float(res.fun))
                vals_out.append(val)
            out[q] = np.array(vals_out)
        return out


def solve(
    m: dict[str, Any] | Model,
    method: str = "DOP853",
    rtol: float = 1e-6,
    atol: float = 1e-9,
    max_segments: int = 100_000,
) -> Solution:
    """Integrate one variant (see the module docstring); ``atol`` in the model's units."""
    mdl = m if isinstance(m, Model) else compile_model(m)
    nd = mdl.nd
    knots = {0.0, mdl.end_time}
    for _, _, c in mdl.loads:
        if c is not None:
            knots.update(float(x) for x in c.x if 0.0 < x < mdl.end_time)
    bounds = sorted(knots)
    y = np.concatenate((np.zeros(nd), mdl.v0.ravel(), np.zeros(1 + len(mdl.springs))))
    branches: dict[int, Branch] = {}
    for s in mdl.hyst:
        br = Branch()
        if mdl.springs[s].kind == "crush":
            _, edot, _ = _one(mdl, s, np.zeros_like(mdl.x0), mdl.v0)
            br.mode = -1 if edot < 0 else 0
        branches[s] = br
    segments: list[Segment] = []
    nfev = n_events = 0
    t = 0.0
    for b in bounds[1:]:
        while t < b:
            rhs = make_rhs(mdl, branches)
            evs = events_for(mdl, branches)
            sol = solve_ivp(
                rhs, (t, b), y, method=method, rtol=rtol, atol=atol, dense_output=True, events=evs or None
            )
            if not sol.success and sol.status != 1:
                raise RuntimeError(sol.message)
            nfev += sol.nfev
            snap = {s: Branch(**vars(br)) for s, br in branches.items()}
            segments.append(Segment(t, float(sol.t[-1]), sol.sol, np.asarray(sol.t), snap))
            y = sol.y[:, -1].copy()
            t_new = float(sol.t[-1])
            if sol.status == 1:  # a branch changed
                fired = [k for k, te in enumerate(sol.t_events) if len(te)]
                k = fired[0]
                ev = evs[k]
                t_new = float(sol.t_events[k][0])
                y = sol.y_events[k][0].copy()
                e, _, _ = _one(
                    mdl, ev.spring, y[:nd].reshape(mdl.x0.shape), y[nd : 2 * nd].reshape(mdl.x0.shape)
                )
                switch(mdl, ev.spring, ev.what, ev.up, branches[ev.spring], e)
                n_events += 1
                if len(segments) > max_segments:
                    raise RuntimeError("too many branch changes")
            t = t_new
    return Solution(mdl, segments, nfev, n_events, y)
