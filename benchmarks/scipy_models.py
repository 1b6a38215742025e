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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

_AXES = ("x", "y")


@dataclass
class Curve:
    x: np.ndarray
    y: np.ndarray

    def __post_init__(self) -> None:
        self.s0 = float((self.y[1] - self.y[0]) / (self.x[1] - self.x[0]))
        self.s1 = float((self.y[-1] - self.y[-2]) / (self.x[-1] - self.x[-2]))
        self.xl, self.yl = list(map(float, self.x)), list(map(float, self.y))

    def __call__(self, e: Any) -> Any:
        """Linear interpolation, linear extrapolation along the end segments (material curves)."""
        if np.ndim(e) == 0:
            e = float(e)
            if e <= self.xl[0]:
                return self.yl[0] + self.s0 * (e - self.xl[0])
            if e >= self.xl[-1]:
                return self.yl[-1] + self.s1 * (e - self.xl[-1])
            return float(np.interp(e, self.x, self.y))
        out = np.interp(e, self.x, self.y)
        out = np.where(e < self.x[0], self.y[0] + self.s0 * (e - self.x[0]), out)
        return np.where(e > self.x[-1], self.y[-1] + self.s1 * (e - self.x[-1]), out)

    def in_time(self, t: Any) -> Any:
        """Time curve: interpolated inside its range, zero outside."""
        inside = (t >= self.x[0]) & (t <= self.x[-1])
        return np.where(inside, np.interp(t, self.x, self.y), 0.0)

    def inverse(self, f: float, direction: float) -> float:
        """Elongation where the curve reaches ``f``, searched from the origin outward (as the kernel's
        ``curve_inverse``)."""
        prev_x, prev_y = 0.0, float(self(0.0))
        xs = self.xl if direction > 0 else self.xl[::-1]
        ys = self.yl if direction > 0 else self.yl[::-1]
        for xk, yk in zip(xs, ys, strict=True):
            if xk * direction > 0:
                lo, hi = min(prev_y, yk), max(prev_y, yk)
                if hi > lo and lo <= f <= hi:
                    return prev_x + (f - prev_y) / (yk - prev_y) * (xk - prev_x)
                prev_x, prev_y = xk, yk
        slope = self.s1 if direction > 0 else self.s0
        if slope != 0.0 and (f - prev_y) / slope * direction >= 0:
            return prev_x + (f - prev_y) / slope
        return prev_x


@dataclass
class Spring:
    kind: str
    i: int
    j: int
    k: float = 0.0  # stiffness / damping / unloading stiffness
    L: Curve | None = None  # curve / loading curve
    U: Curve | None = None  # unloading curve (general_nonlinear)
    yt: float = math.inf
    yc: float = -math.inf


@dataclass
class Branch:
    """The branch of a history-dependent spring (docs/format.md, in continuous time)."""

    mode: int = 0  # crush: -1 crushing, 0 not; general_nonlinear: 0 elastic, +1 / -1 yielded direction
    loading: bool = True  # general_nonlinear, mode != 0: on the (shifted) loading curve, else unloading
    emin: float = 0.0  # crush e_min
    fstar: float = 0.0  # crush F*
    et: float = 0.0
    ft: float = 0.0
    ec: float = 0.0
    fc: float = 0.0
    shift: float = 0.0
    yld_t: bool = False
    yld_c: bool = False


@dataclass
class Model:
    dim: int
    x0: np.ndarray  # (N, D)
    mass: np.ndarray
    free: np.ndarray  # (N, D) float
    inv_mass: np.ndarray  # (N, D)
    v0: np.ndarray
    gravity: np.ndarray
    springs: list[Spring]
    ni: np.ndarray
    nj: np.ndarray
    d0: np.ndarray  # (S, D)
    l0: np.ndarray
    sign: np.ndarray
    incidence: np.ndarray  # (N, S)
    loads: list[tuple[int, np.ndarray, Curve | None]]
    end_time: float
    node_ids: tuple[str, ...]
    spring_ids: tuple[str, ...]
    hyst: list[int] = field(default_factory=list)  # indices of crush / general_nonlinear springs

    @property
    def nd(self) -> int:
        return self.x0.size


def compile_model(m: dict[str, Any]) -> Model:
    """A model dict (as the YAML file loads) -> arrays. No prescribed motion, no walls."""
    if m.get("prescribed_motion") or m.get("rigid_walls"):
        raise NotImplementedError("prescribed_motion / rigid_walls")
    curves = {}
    for cid, raw in (m.get("curves") or {}).items():
        x = np.asarray(raw["x"], float) * float(raw.get("x_scale", 1.0))
        curves[cid] = Curve(x, np.asarray(raw["y"], float) * float(raw.get("scale", 1.0)))
    nodes = m["nodes"]
    node_ids = tuple(nodes)
    index = {n: k for k, n in enumerate(node_ids)}
    x0 = np.array([np.atleast_1d(np.asarray(nodes[n]["position"], float)) for n in node_ids])
    N, D = x0.shape
    free = np.ones((N, D))
    mass = np.zeros(N)
    for k, n in enumerate(node_ids):
        fx = nodes[n].get("fixed")
        if fx is True:
            free[k] = 0.0
        elif fx:
            for a in [fx] if isinstance(fx, str) else fx:
                free[k, _AXES.index(str(a))] = 0.0
        mass[k] = float(nodes[n].get("mass") or 0.0)
    inv_mass = np.where(free > 0, 1.0 / np.where(mass > 0, mass, 1.0)[:, None], 0.0)
    v0 = np.zeros((N, D))
    for n, vel in (m.get("initial_velocity") or {}).items():
        v0[index[n]] = np.asarray(vel, float)
    gravity = np.asarray(m.get("gravity") or [0.0] * D, float)
    springs, spring_ids = [], tuple(m["springs"])
    for sid in spring_ids:
        raw = m["springs"][sid]
        i, j = index[raw["nodes"][0]], index[raw["nodes"][1]]
        mat = raw["material"]
        t = mat["type"]
        if t == "linear_elastic":
            springs.append(Spring(t, i, j, k=float(mat["stiffness"])))
        elif t == "damper":
            springs.append(Spring(t, i, j, k=float(mat["damping"])))
        elif t == "nonlinear_elastic":
            springs.append(Spring(t, i, j, L=curves[mat["curve"]]))
        elif t == "crush":
            springs.append(Spring(t, i, j, k=float(mat["unloading_stiffness"]), L=curves[mat["loading"]]))
        elif t == "general_nonlinear":
            springs.append(
                Spring(
                    t,
                    i,
                    j,
                    L=curves[mat["loading"]],
                    U=curves[mat["unloading"]],
                    yt=float(mat.get("tension_yield", math.inf)),
                    yc=float(mat.get("compression_yield", -math.inf)),
                )
            )
        else:
            raise NotImplementedError(t)
    ni = np.array([s.i for s in springs])
    nj = np.array([s.j for s in springs])
    d0 = x0[nj] - x0[ni]
    S = len(springs)
    inc = np.zeros((N, S))
    inc[ni, np.arange(S)] += 1.0
    inc[nj, np.arange(S)] -= 1.0
    loads = [
        (index[ld["node"]], np.asarray(ld["force"], float), curves[ld["curve"]] if ld.get("curve") else None)
        for ld in (m.get("loads") or [])
    ]
    return Model(
        D,
        x0,
        mass,
        free,
        inv_mass,
        v0,
        gravity,
        springs,
        ni,
        nj,
        d0,
        np.sqrt((d0 * d0).sum(-1)),
        np.sign(d0[:, 0]) if D == 1 else np.ones(S),
        inc,
        loads,
        float(m["end_time"]),
        node_ids,
        spring_ids,
        [k for k, s in enumerate(springs) if s.kind in ("crush", "general_nonlinear")],
    )


def kinematics(mdl: Model, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(e, edot, n) for u, v of shape (N, D, ...): e, edot (S, ...), n (S, D, ...)."""
    du = u[mdl.nj] - u[mdl.ni]
    dv = v[mdl.nj] - v[mdl.ni]
    if mdl.dim == 1:
        sg = mdl.sign.reshape((-1,) + (1,) * (du.ndim - 1))
        return sg[:, 0] * du[:, 0], sg[:, 0] * dv[:, 0], sg + 0.0 * du
    extra = (1,) * (du.ndim - 2)
    d = mdl.d0.reshape(mdl.d0.shape + extra) + du
    length = np.sqrt((d * d).sum(1))
    n = d / length[:, None]
    l0 = mdl.l0.reshape((-1,) + extra)
    e = (2.0 * (mdl.d0.reshape(mdl.d0.shape + extra) * du).sum(1) + (du * du).sum(1)) / (length + l0)
    return e, (n * dv).sum(1), n


def force(sp: Spring, br: Branch | None, e: Any, edot: Any) -> Any:
    """Spring force on the current branch (scalar or array)."""
    if sp.kind == "linear_elastic":
        return sp.k * e
    if sp.kind == "damper":
        return sp.k * edot
    assert sp.L is not None
    if sp.kind == "nonlinear_elastic":
        return sp.L(e)
    assert br is not None
    if sp.kind == "crush":
        if br.mode < 0:
            return np.minimum(0.0, sp.L(e))
        return np.minimum(0.0, br.fstar + sp.k * (e - br.emin))
    assert sp.U is not None
    if br.mode == 0 or br.loading:
        return sp.L(e - br.shift)
    if br.mode > 0:
        return br.ft + sp.U(e - br.et)
    return br.fc + sp.U(e - br.ec)


def ext_force(mdl: Model, t: Any) -> np.ndarray:
    """External forces (N, D[, T])."""
    t_arr = np.asarray(t, float)
    f = mdl.mass[:, None] * mdl.gravity[None, :] * (mdl.free > 0)
    if t_arr.ndim:
        f = np.repeat(f[..., None], t_arr.size, axis=-1)
    for node, vec, curve in mdl.loads:
        scale = curve.in_time(t_arr) if curve is not None else np.ones_like(t_arr)
        f[node] = f[node] + (vec[:, None] * scale if t_arr.ndim else vec * scale)
    return f


def make_rhs(mdl: Model, branches: dict[int, Branch]):
    N, D, S, nd = mdl.x0.shape[0], mdl.dim, len(mdl.springs), mdl.nd
    inc, inv_m, free = mdl.incidence, mdl.inv_mass, mdl.free
    static_ext = not mdl.loads
    f_ext0 = ext_force(mdl, 0.0)
    springs = mdl.springs

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        u = y[:nd].reshape(N, D)
        v = y[nd : 2 * nd].reshape(N, D)
        e, edot, n = kinematics(mdl, u, v)
        F = np.empty(S)
        for s, sp in enumerate(springs):
            F[s] = force(sp, branches.get(s), e[s], edot[s])
        fe = f_ext0 if static_ext else ext_force(mdl, t)
        acc = (inc @ (F[:, None] * n) + fe) * inv_m
        return np.concatenate((y[nd : 2 * nd], acc.ravel(), [float((fe * v * free).sum())], F * edot))

    return rhs


def _ev(mdl: Model, s: int, what: str, level: float, direction: float, br: Branch):
    """Event function g(t, y) of spring ``s``: ``what`` in e, edot, L (loading curve), F (force)."""
    nd, N, D = mdl.nd, mdl.x0.shape[0], mdl.dim
    sp = mdl.springs[s]

    def g(t: float, y: np.ndarray) -> float:
        u = y[:nd].reshape(N, D)
        v = y[nd : 2 * nd].reshape(N, D)
        e, edot, _ = _one(mdl, s, u, v)
        if what == "e":
            return e - level
        if what == "edot":
            return edot
        if what == "L":
            assert sp.L is not None
            return float(sp.L(e - br.shift)) - level
        return float(force(sp, br, e, edot)) - level

    g.terminal = True  # type: ignore[attr-defined]
    g.direction = direction  # type: ignore[attr-defined]
    g.spring = s  # type: ignore[attr-defined]
    g.what = what  # type: ignore[attr-defined]
    g.up = direction > 0  # type: ignore[attr-defined]
    return g


def _one(mdl: Model, s: int, u: np.ndarray, v: np.ndarray) -> tuple[float, float, None]:
    """Elongation and its rate of one spring."""
    i, j = mdl.ni[s], mdl.nj[s]
    if mdl.dim == 1:
        sg = mdl.sign[s]
        return sg * (u[j, 0] - u[i, 0]), sg * (v[j, 0] - v[i, 0]), None
    du = u[j] - u[i]
    d = mdl.d0[s] + du
    length = math.sqrt(float(d @ d))
    e = (2.0 * float(mdl.d0[s] @ du) + float(du @ du)) / (length + mdl.l0[s])
    return e, float(d @ (v[j] - v[i])) / length, None


def events_for(mdl: Model, branches: dict[int, Branch]) -> list[Any]:
    evs = []
    for s, br in branches.items():
        sp = mdl.springs[s]
        if sp.kind == "crush":
            evs.append(
                _ev(mdl, s, "edot", 0.0, 1.0, br) if br.mode < 0 else _ev(mdl, s, "e", br.emin, -1.0, br)
            )
            continue
        if br.mode == 0:
            if math.isfinite(sp.yt):
                evs.append(_ev(mdl, s, "L", sp.yt, 1.0, br))
            if math.isfinite(sp.yc):
                evs.append(_ev(mdl, s, "L", sp.yc, -1.0, br))
        elif br.mode > 0:
            if br.loading:
                evs.append(_ev(mdl, s, "edot", 0.0, -1.0, br))
            else:
                evs.append(_ev(mdl, s, "e", br.et, 1.0, br))
                thr_c = br.fc if br.yld_c else sp.yc
                if math.isfinite(thr_c):
                    evs.append(_ev(mdl, s, "F", thr_c, -1.0, br))
        else:
            if br.loading:
                evs.append(_ev(mdl, s, "edot", 0.0, 1.0, br))
            else:
                evs.append(_ev(mdl, s, "e", br.ec, -1.0, br))
                thr_t = br.ft if br.yld_t else sp.yt
                if math.isfinite(thr_t):
                    evs.append(_ev(mdl, s, "F", thr_t, 1.0, br))
    return evs


def switch(mdl: Model, s: int, what: str, up: bool, br: Branch, e: float) -> None:
    """Apply the branch change of spring ``s`` whose event ``what`` (rising: ``up``) fired at elongation ``e``."""
    sp = mdl.springs[s]
    assert sp.L is not None
    if sp.kind == "crush":
        if br.mode < 0:  # stops crushing: spring-back from here
            br.mode, br.emin, br.fstar = 0, e, min(0.0, float(sp.L(e)))
        else:  # back at e_min: crushing resumes
            br.mode = -1
        return
    if br.mode == 0:
        if up:  # tension yield reached
            br.mode, br.yld_t, br.et, br.ft = 1, True, e, float(sp.L(e - br.shift))
        else:
            br.mode, br.yld_c, br.ec, br.fc = -1, True, e, float(sp.L(e - br.shift))
        br.loading = True
        return
    if what == "edot":  # turns: unloading from the extreme
        if br.mode > 0:
            br.et, br.ft = e, float(sp.L(e - br.shift))
        else:
            br.ec, br.fc = e, float(sp.L(e - br.shift))
        br.loading = False
    elif what == "e":  # rejoins the loading curve at the extreme
        br.loading = True
    else:  # reaches the other direction's yield force: its loading curve, shifted through this point
        if br.mode > 0:
            thr = br.fc if br.yld_c else sp.yc
            br.shift = e - sp.L.inverse(thr, -1.0)
            br.mode, br.yld_c, br.ec, br.fc = -1, True, e, float(sp.L(e - br.shift))
        else:
            thr = br.ft if br.yld_t else sp.yt
            br.shift = e - sp.L.inverse(thr, 1.0)
            br.mode, br.yld_t, br.et, br.ft = 1, True, e, float(sp.L(e - br.shift))
        br.loading = True


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
