"""Spring material laws on NumPy arrays (one value per variant), used by the reference kernel.

State layout shared with the compiled kernel: ``state`` has shape (S, NSTATE, V).

- ``crush``: 0 ``e_min`` (most compressed elongation so far), 1 ``F*`` (force there).
- ``general_nonlinear``: 0 ``mode`` (0 never yielded, +1 last yielded in tension, -1 in
  compression), 1 ``e_t*``, 2 ``F_t*``, 3 ``e_c*``, 4 ``F_c*``, 5 shift of the loading curve along
  the elongation axis, 6 tension yielded (0/1), 7 compression yielded (0/1).
- ``elastoplastic``: 0 ``e_p`` (plastic elongation), 1 ``p`` (accumulated plastic elongation, sum of |de_p|).
"""

from __future__ import annotations

import numpy as np

from crashstudy.vocabulary.codes import NSTATE, TIME_EPS

__all__ = [
    "NSTATE",
    "TIME_EPS",
    "crush",
    "curve_eval",
    "general_nonlinear",
    "rate_elastic",
    "time_curve_eval",
]


def curve_eval(
    c: int, e: np.ndarray, cx: np.ndarray, cy: np.ndarray, cds: np.ndarray, cs0: np.ndarray, off: np.ndarray
) -> np.ndarray:
    """Piecewise-linear curve ``c`` at ``e`` (V,), extrapolated along its end segments (ramp sum)."""
    a, b = int(off[c]), int(off[c + 1])
    y = cy[a] + cs0[c] * (e - cx[a])
    for k in range(a + 1, b - 1):
        y = y + cds[k] * np.maximum(0.0, e - cx[k])
    return y


def time_curve_eval(
    c: int, t: np.ndarray, cx: np.ndarray, cy: np.ndarray, cds: np.ndarray, cs0: np.ndarray, off: np.ndarray
) -> np.ndarray:
    """Curve ``c`` as a function of time: interpolated inside its range, zero outside."""
    a, b = int(off[c]), int(off[c + 1])
    eps = TIME_EPS * (cx[b - 1] - cx[a])  # t = n dt carries round-off: a knot at end_time is inside
    inside = (t >= cx[a] - eps) & (t <= cx[b - 1] + eps)
    return np.where(inside, curve_eval(c, t, cx, cy, cds, cs0, off), 0.0)


def curve_inverse(
    c: int,
    f: np.ndarray,
    direction: float,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    cs1: np.ndarray,
    off: np.ndarray,
) -> np.ndarray:
    """Elongation where curve ``c`` first reaches force ``f``, walking from e = 0 toward ``direction``.

    The walk starts at the origin and follows the segments outward (compression: toward -inf,
    tension: toward +inf), returning the first crossing; beyond the last knot the end segment is
    extended. If the curve never reaches ``f`` the end knot is returned.
    """
    a, b = int(off[c]), int(off[c + 1])
    V = f.shape[0]
    out = np.full(V, np.nan)
    x, y = cx[a:b], cy[a:b]
    n = b - a
    # knots ordered outward from the origin, starting with the origin's own value
    if direction > 0:
        order = list(range(n))
    else:
        order = list(range(n - 1, -1, -1))
    zero = np.zeros(V)
    y0 = curve_eval(c, zero, cx, cy, cds, cs0, off)
    prev_x, prev_y = zero, y0
    for k in order:
        beyond = (x[k] - 0.0) * direction > 0
        lo = np.minimum(prev_y, y[k])
        hi = np.maximum(prev_y, y[k])
        hit = beyond & np.isnan(out) & (f >= lo) & (f <= hi) & (hi > lo)
        frac = np.divide(f - prev_y, y[k] - prev_y, out=np.zeros(V), where=hi > lo)
        out = np.where(hit, prev_x + frac * (x[k] - prev_x), out)
        prev_x = np.where(beyond, x[k], prev_x)
        prev_y = np.where(beyond, y[k], prev_y)
    slope = cs1[c] if direction > 0 else cs0[c]
    ext = np.divide(f - prev_y, slope, out=np.zeros(V), where=slope != 0)
    extended = prev_x + ext
    ok = (ext * direction >= 0) & (slope != 0)
    return np.where(np.isnan(out), np.where(ok, extended, prev_x), out)


def unloading_inverse(
    c: int,
    f: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    cs1: np.ndarray,
    off: np.ndarray,
) -> np.ndarray:
    """Elongation where the increasing curve ``c`` has force ``f`` (linear extrapolation at ends)."""
    a, b = int(off[c]), int(off[c + 1])
    x, y = cx[a:b], cy[a:b]
    out = np.where(f <= y[0], x[0] + (f - y[0]) / cs0[c], x[-1] + (f - y[-1]) / cs1[c])
    for k in range(b - a - 1):
        inside = (f > y[k]) & (f <= y[k + 1])
        frac = (f - y[k]) / (y[k + 1] - y[k])
        out = np.where(inside, x[k] + frac * (x[k + 1] - x[k]), out)
    return out


def general_nonlinear(
    e: np.ndarray,
    st: np.ndarray,
    ca: int,
    cb: int,
    yt: np.ndarray,
    yc: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    cs1: np.ndarray,
    off: np.ndarray,
) -> np.ndarray:
    """Force of a ``general_nonlinear`` spring at elongation ``e``; updates ``st`` (NSTATE, V) in place.

    Implements rules 1-4 of docs/format.md (elastic band, yield, shifted unloading line, reverse yield).
    """
    mode, et, ft, ec, fc, shift, yld_t, yld_c = (st[k].copy() for k in range(NSTATE))
    L = curve_eval(ca, e - shift, cx, cy, cds, cs0, off)
    thr_t = np.where(yld_t > 0, ft, yt)  # force that (re)starts tension loading
    thr_c = np.where(yld_c > 0, fc, yc)

    # rule 1: never yielded -> elastic on L; yielding when L reaches a yield force
    m0 = mode == 0
    F = np.where(m0, L, 0.0)
    to_t = m0 & (L >= yt)
    to_c = m0 & (L <= yc)

    # mode +1: on L beyond e_t*, else on the unloading line anchored at (e_t*, F_t*)
    mt = mode > 0
    on_l = mt & (e >= et)
    branch_t = ft + curve_eval(cb, e - et, cx, cy, cds, cs0, off)
    F = np.where(on_l, L, np.where(mt, branch_t, F))
    et = np.where(on_l, e, et)
    ft = np.where(on_l, L, ft)
    rev_c = mt & ~on_l & (branch_t <= thr_c)

    # mode -1: mirror image
    mc = mode < 0
    on_lc = mc & (e <= ec)
    branch_c = fc + curve_eval(cb, e - ec, cx, cy, cds, cs0, off)
    F = np.where(on_lc, L, np.where(mc, branch_c, F))
    ec = np.where(on_lc, e, ec)
    fc = np.where(on_lc, L, fc)
    rev_t = mc & ~on_lc & (branch_c >= thr_t)

    # rule 4: reverse yield -> the other direction's loading curve, shifted through the crossing
    if np.any(rev_c):
        cross = et + unloading_inverse(cb, thr_c - ft, cx, cy, cds, cs0, cs1, off)
        new_shift = cross - curve_inverse(ca, thr_c, -1.0, cx, cy, cds, cs0, cs1, off)
        shift = np.where(rev_c, new_shift, shift)
    if np.any(rev_t):
        cross = ec + unloading_inverse(cb, thr_t - fc, cx, cy, cds, cs0, cs1, off)
        new_shift = cross - curve_inverse(ca, thr_t, 1.0, cx, cy, cds, cs0, cs1, off)
        shift = np.where(rev_t, new_shift, shift)
    if np.any(rev_c | rev_t):
        Ls = curve_eval(ca, e - shift, cx, cy, cds, cs0, off)
        F = np.where(rev_c | rev_t, Ls, F)
        ec = np.where(rev_c, e, ec)
        fc = np.where(rev_c, Ls, fc)
        et = np.where(rev_t, e, et)
        ft = np.where(rev_t, Ls, ft)

    # first yield from the elastic range
    et = np.where(to_t, e, et)
    ft = np.where(to_t, L, ft)
    ec = np.where(to_c, e, ec)
    fc = np.where(to_c, L, fc)
    mode = np.where(to_t | rev_t, 1.0, np.where(to_c | rev_c, -1.0, mode))
    yld_t = np.where(to_t | rev_t, 1.0, yld_t)
    yld_c = np.where(to_c | rev_c, 1.0, yld_c)
    for k, arr in enumerate((mode, et, ft, ec, fc, shift, yld_t, yld_c)):
        st[k] = arr
    return F


def crush(
    e: np.ndarray,
    st: np.ndarray,
    ca: int,
    ku: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    off: np.ndarray,
) -> np.ndarray:
    """Force of a ``crush`` spring (compression only, elastic spring-back, separation); updates ``st``."""
    emin, fstar = st[0], st[1]
    on = e <= emin
    f_load = np.minimum(0.0, curve_eval(ca, e, cx, cy, cds, cs0, off))
    f_unl = np.minimum(0.0, fstar + ku * (e - emin))
    F = np.where(on, f_load, f_unl)
    st[0] = np.where(on, e, emin)
    st[1] = np.where(on, f_load, fstar)
    return F


def elastoplastic(e: np.ndarray, st: np.ndarray, k: np.ndarray, kt: np.ndarray, fy: np.ndarray) -> np.ndarray:
    """Force of an ``elastoplastic`` spring (LS-DYNA S03, isotropic hardening); updates ``st`` in place.

    Elastic trial ``F = K (e - e_p)``; where ``|F|`` exceeds ``FY + H p`` (``H = K KT / (K - KT)``) the
    return to the yield surface is exact for the linear hardening: ``dp = (|F| - FY - H p) / (K + H)``,
    ``e_p += sign(F) dp``, ``p += dp``, ``F -= sign(F) K dp``.
    """
    ep, p = st[0], st[1]
    h = k * kt / (k - kt)
    trial = k * (e - ep)
    over = np.abs(trial) - (fy + h * p)
    dp = np.where(over > 0.0, over / (k + h), 0.0)
    sg = np.sign(trial)
    st[0] = ep + sg * dp
    st[1] = p + dp
    return trial - sg * k * dp


def rate_elastic(
    e: np.ndarray,
    rate: np.ndarray,
    curves: np.ndarray,
    rates: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    cds: np.ndarray,
    cs0: np.ndarray,
    off: np.ndarray,
) -> np.ndarray:
    """Force of a ``rate_elastic`` spring, ``C(e, |de/dt|)``: the curves ``curves`` (R,) at rates ``rates``
    (R, V), increasing; linear in the rate between the two curves that bracket ``|rate|``, the first curve
    below the first rate, the last above the last (docs/format.md)."""
    r = np.abs(rate)
    F = curve_eval(int(curves[0]), e, cx, cy, cds, cs0, off)
    for k in range(len(curves) - 1):
        ck = curve_eval(int(curves[k]), e, cx, cy, cds, cs0, off)
        ck1 = curve_eval(int(curves[k + 1]), e, cx, cy, cds, cs0, off)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (r - rates[k]) / (rates[k + 1] - rates[k])
        t = np.where(t < 1.0, t, 1.0)
        F = np.where(r > rates[k], ck + t * (ck1 - ck), F)
    return F
