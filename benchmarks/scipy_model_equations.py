"""The scipy baseline's equations: the lean right-hand side (kinematics, spring and external forces),
the terminal events where a spring's branch changes, and the branch switch at an event.

Part of the scipy baseline of the benchmarks (scipy_models.py, which describes it)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from scipy_model_compile import Branch, Model, Spring


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
