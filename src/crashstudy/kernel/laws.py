"""The spring laws of the fast kernels (forces, state, knots, geometry, curves), written once: small pure
compiled scalar functions (the other per-step laws: :mod:`crashstudy.kernel.step_laws`).

Numbers in, a number or a tuple of numbers out (curve tables are read from arrays, column ``v``).
The generic kernel (:mod:`crashstudy.kernel.compiled`) calls them per lane on its block arrays,
the generated kernels (:mod:`crashstudy.kernel.gen_springs`, :mod:`crashstudy.kernel.gen_nodes`)
emit calls to them on their local scalars. Each law but two (``_inl`` below) is compiled once
(numba's default ``inline="never"``) and LLVM inlines it at its call sites at -O3, so the machine code is still that of
a hand-written formula without numba typing and lowering it again at each of ~40 call sites
(``error_model="numpy"``: no division-by-zero branch, so the generated kernel's loops stay as fast
as with the laws inlined; benchmarks/results/compile_inline.md). The NumPy reference
(:mod:`crashstudy.kernel.reference`, :mod:`crashstudy.arrays.material_laws`) is the independent twin:
every function here does its operations in the same order, so both fast kernels stay bitwise equal
to it (no fastmath).

A new material is one law function here, one dispatch line in each fast kernel
(the force dispatch of ``compiled._run`` and ``gen_springs.pass_b_springs``) and its NumPy twin in arrays/material_laws.py.
"""

from __future__ import annotations

import numpy as np

from crashstudy.kernel.cache import cached_njit
from crashstudy.vocabulary.codes import (
    TIME_EPS,
    TINY_LENGTH,
)

_jit = cached_njit(nogil=True, error_model="numpy")
# per-step laws of the generic kernel that LLVM did not inline as well (time curves: arrays in;
# general_law: 13 numbers in, 9 out): numba IR inlining, 16-19% faster on general-nonlinear-tension
_inl = cached_njit(nogil=True, inline="always")


# ---- numbers ---------------------------------------------------------------------------------


@_jit
def peak(p, x):  # pragma: no cover - compiled
    """Running maximum: ``x`` when it is larger than ``p`` (peaks are >= 0; a stopped lane passes 0)."""
    return x if x > p else p


@_jit
def least(p, x):  # pragma: no cover - compiled
    return x if x < p else p


# ---- spring forces and state (docs/format.md) ------------------------------------------------


@_jit
def linear_force(k, e):  # pragma: no cover - compiled
    """``linear_elastic``: F = k e."""
    return k * e


@_jit
def damper_force(c, edot):  # pragma: no cover - compiled
    """``damper``: F = c de/dt."""
    return c * edot


@_jit
def rate_segment(F, r, rk, rk1, Ck, Ck1):  # pragma: no cover - compiled
    """``rate_elastic``, one pair of neighbouring curves (rates ``rk < rk1``, forces ``Ck``, ``Ck1`` at e):
    above ``rk`` the force interpolated linearly in the rate magnitude ``r`` (held at ``Ck1`` above
    ``rk1``), else ``F`` unchanged. Folded over the pairs in rate order, starting from the first curve's
    force, it gives the first curve below ``r_1``, the bracketing pair's interpolation between, the last
    curve above the last rate."""
    if r > rk:
        t = (r - rk) / (rk1 - rk)
        t = t if t < 1.0 else 1.0
        return Ck + t * (Ck1 - Ck)
    return F


@_jit
def nonlinear_force(L):  # pragma: no cover - compiled
    """``nonlinear_elastic``: the loading curve at e (``L``, evaluated by the caller)."""
    return L


@_jit
def crush_law(e, emin, fstar, L, ku):  # pragma: no cover - compiled
    """``crush``: compression only, elastic spring-back with ``ku``, separation.

    ``(emin, fstar)`` the state (most compressed elongation, force there); ``L`` the loading curve at
    ``e``. Returns (F, emin, fstar) after the step.
    """
    on = e <= emin
    f_load = min(0.0, L)
    f_unl = min(0.0, fstar + ku * (e - emin))
    return (f_load if on else f_unl), (e if on else emin), (f_load if on else fstar)


@_inl
def general_law(e, mode, et, ft, ec, fc, yld_t, yld_c, L, Ut, Uc, yt, yc):  # pragma: no cover - compiled
    """``general_nonlinear`` rules 1-3 (elastic band, yield, shifted unloading line), branch-free.

    State (mode, e_t*, F_t*, e_c*, F_c*, yielded_t, yielded_c) before the step; ``L`` the loading
    curve at e - shift, ``Ut``/``Uc`` the unloading curve at e - e_t* / e - e_c*. Returns
    (F, mode, et, ft, ec, fc, yld_t, yld_c, rev): ``rev`` True when the unloading line reached the
    other direction's yield force (rule 4: :func:`general_reverse` recomputes F and the state).
    """
    thr_t = ft if yld_t > 0 else yt
    thr_c = fc if yld_c > 0 else yc
    is0 = mode == 0
    ist = mode > 0
    isc = mode < 0
    on_l = ist & (e >= et)
    on_lc = isc & (e <= ec)
    bt = ft + Ut
    bc = fc + Uc
    F = L if (is0 | on_l | on_lc) else (bt if ist else bc)
    to_t = is0 & (L >= yt)
    to_c = is0 & (L <= yc)
    rev = (ist & (not on_l) & (bt <= thr_c)) | (isc & (not on_lc) & (bc >= thr_t))
    return (
        F,
        1.0 if to_t else (-1.0 if to_c else mode),
        e if (on_l | to_t) else et,
        L if (on_l | to_t) else ft,
        e if (on_lc | to_c) else ec,
        L if (on_lc | to_c) else fc,
        1.0 if to_t else yld_t,
        1.0 if to_c else yld_c,
        rev,
    )


@_jit
def general_reverse(
    e, mode, et, ft, ec, fc, yld_t, yld_c, yt, yc, ca, cb, v, cx, cy, cds, cs0, cs1, off
):  # pragma: no cover
    """Rule 4 for a lane whose unloading line reached the other direction's yield force (rare).

    The state is the one before the step (a reversing lane is on its unloading line, so rules 1-3
    left it unchanged). Returns (F, mode, et, ft, ec, fc, shift, yld_t, yld_c).
    """
    thr_t = ft if yld_t > 0 else yt
    thr_c = fc if yld_c > 0 else yc
    if mode > 0:  # tension unloading reached compression
        cross = et + unloading_inverse(cb, thr_c - ft, v, cx, cy, cs0, cs1, off)
        shift = cross - curve_inverse(ca, thr_c, -1.0, v, cx, cy, cds, cs0, cs1, off)
        Ls = curve_at(ca, e - shift, v, cx, cy, cds, cs0, off)
        return Ls, -1.0, et, ft, e, Ls, shift, yld_t, 1.0
    cross = ec + unloading_inverse(cb, thr_t - fc, v, cx, cy, cs0, cs1, off)  # compression reached tension
    shift = cross - curve_inverse(ca, thr_t, 1.0, v, cx, cy, cds, cs0, cs1, off)
    Ls = curve_at(ca, e - shift, v, cx, cy, cds, cs0, off)
    return Ls, 1.0, e, Ls, ec, fc, shift, 1.0, yld_c


@_jit
def general_reverse_call(
    e, mode, et, ft, ec, fc, yld_t, yld_c, yt, yc, ca, cb, v, cx, cy, cds, cs0, cs1, off
):  # pragma: no cover
    """:func:`general_reverse` compiled once and called (rarely) by every generated kernel instead of
    being inlined into each."""
    return general_reverse(
        e, mode, et, ft, ec, fc, yld_t, yld_c, yt, yc, ca, cb, v, cx, cy, cds, cs0, cs1, off
    )


@_jit
def elastoplastic_law(e, ep, p, k, kt, fy):  # pragma: no cover - compiled
    """``elastoplastic`` (LS-DYNA S03, isotropic hardening): exact return to ``|F| <= FY + H p``.

    State (e_p, p) before the step. Returns (F, e_p, p) after it."""
    h = k * kt / (k - kt)
    trial = k * (e - ep)
    over = abs(trial) - (fy + h * p)
    dp = over / (k + h) if over > 0.0 else 0.0
    sg = 1.0 if trial > 0.0 else (-1.0 if trial < 0.0 else (0.0 if trial == 0.0 else trial))  # np.sign
    return trial - sg * k * dp, ep + sg * dp, p + dp


@_jit
def broken_at(e, ep, ft, fc, n, dt):  # pragma: no cover - compiled
    """Spring failure: (passes a failure elongation in this step, that elongation, the crossing time
    interpolated within the step)."""
    snaps = (e > ft) | (e < fc)
    limit = ft if e > ft else fc
    t = (n - 1 + (limit - ep) / (e - ep)) * dt if snaps else 0.0
    return snaps, limit, t


# ---- knot crossings (peak force between two steps) -------------------------------------------


@_jit
def nonlinear_window(ep, e):  # pragma: no cover - compiled
    """``nonlinear_elastic`` follows its curve on the whole path: (lo, hi, shift) in the curve's abscissa."""
    return min(ep, e), max(ep, e), 0.0


@_jit
def crush_window(e, emin):  # pragma: no cover - compiled
    """``crush`` follows its curve only when crushing further: (e, e_min before the step)."""
    return e, emin, 0.0


@_jit
def general_window(ep, e, mode, et, ec, sh):  # pragma: no cover - compiled
    """``general_nonlinear`` on its loading curve, in the curve's own (shifted) abscissa; state before the step."""
    lo = et if mode > 0 else (e if mode < 0 else min(ep, e))
    hi = e if mode > 0 else (ec if mode < 0 else max(ep, e))
    return lo - sh, hi - sh, sh


@_jit
def crush_knot_force(yk):  # pragma: no cover - compiled
    """A crush spring's curve counts in compression only."""
    return min(0.0, yk)


@_jit
def knot_inside(xk, lo, hi):  # pragma: no cover - compiled
    return (xk > lo) & (xk < hi)


@_jit
def knot_peak(cand, e_lo, e_hi, xk, yk):  # pragma: no cover - compiled
    """Peak-force candidate of one curve knot: ``max(cand, |yk|)`` when ``e_lo < xk < e_hi``, else ``cand``.

    ``(e_lo, e_hi)`` the part of the path between two steps on which the spring follows its curve,
    in the curve's own abscissa; ``yk`` the knot force (``Batch.knot_y``: 0 where the knot is not a
    local maximum of |curve|). The NumPy twin is :func:`crashstudy.kernel.reference_knots.knot_peak_np`.
    """
    ak = abs(yk)
    return ak if ((xk > e_lo) & (xk < e_hi) & (ak > cand)) else cand


@_jit
def knot_step(c0, kx0, ky0, lo, hi, xk, yk):  # pragma: no cover - compiled
    """One knot of the search: (candidate, its abscissa, its force) after knot (xk, yk)."""
    c1 = knot_peak(c0, lo, hi, xk, yk)
    return c1, (xk if c1 > c0 else kx0), (yk if c1 > c0 else ky0)


@_jit
def knot_crossing(kc, kx, ky, ep, e, sh, fp, F):  # pragma: no cover - compiled
    """The crossing of the winning knot (kc > 0: one was passed): (fraction of the step th, knot force
    minus the force interpolated in time dF)."""
    hit = kc > 0.0
    epa = ep - sh
    ea = e - sh
    th = (kx - epa) / ((ea - epa) if hit else 1.0)
    dF = (ky - ((1.0 - th) * fp + th * F)) if hit else 0.0
    return th, dF


@_jit
def knot_accel(ao, a, th, dfax, im, side):  # pragma: no cover - compiled
    """Acceleration of a spring end at the crossing: a interpolated in time plus the kink's correction
    (``side`` 0: node i, +; 1: node j, -)."""
    ai = (1.0 - th) * ao + th * a
    cr = dfax * im
    return ai + cr if side == 0 else ai - cr


# ---- geometry --------------------------------------------------------------------------------


@_jit
def elongation_1d(sg, dj, di):  # pragma: no cover - compiled
    """1-D elongation from the end displacements (sg = +-1, the spring's orientation)."""
    return sg * (dj - di)


@_jit
def end_rate(v, a, dt):  # pragma: no cover - compiled
    """Velocity estimate v^n ~ v^{n-1/2} + dt/2 a^{n-1} of one dof."""
    return v + 0.5 * dt * a


@_jit
def collapsed(ln, l0, turn):  # pragma: no cover - compiled
    """A 2-D spring has collapsed: (nearly) zero length, or its direction turned by 90 degrees or more."""
    return (ln <= TINY_LENGTH * l0) | (turn <= 0.0)


@_jit
def elongation_2d(ln, l0):  # pragma: no cover - compiled
    return ln - l0


@_jit
def axis_2d(u0, u1, p0, p1, l0):  # pragma: no cover - compiled
    """A 2-D spring's unit direction ``(ax0, ax1)``, length and collapse flag from its end-to-end vector
    ``u`` and its previous one ``p`` (a collapsed spring keeps ``u`` as its axis: no division by ~0)."""
    ln = np.sqrt((0.0 + u0 * u0) + u1 * u1)
    gone = collapsed(ln, l0, (0.0 + u0 * p0) + u1 * p1)
    dn = 1.0 if gone else ln
    return u0 / dn, u1 / dn, ln, gone


# ---- curves ----------------------------------------------------------------------------------


@_jit
def ramp_start(y0, s0, e, x0):  # pragma: no cover - compiled
    """A curve's ramp sum begins with its first segment's line through (x0, y0) of slope s0 (batch.py)."""
    return y0 + s0 * (e - x0)


@_jit
def ramp_knot(y, ds, e, xk):  # pragma: no cover - compiled
    """One interior knot of the ramp sum: its slope change ``ds`` times the ramp max(0, e - xk)."""
    return y + ds * peak(0.0, e - xk)


@_jit
def curve_at(c, e, v, cx, cy, cds, cs0, off):  # pragma: no cover - compiled
    """Curve ``c`` of variant column ``v`` at elongation ``e`` (ramp sum, linear extrapolation)."""
    a = off[c]
    b = off[c + 1]
    y = ramp_start(cy[a, v], cs0[c, v], e, cx[a, v])
    for k in range(a + 1, b - 1):
        y = ramp_knot(y, cds[k, v], e, cx[k, v])
    return y


@_jit
def time_window(t, t0, t1):  # pragma: no cover - compiled
    """A time curve acts on [t0, t1] with a margin of TIME_EPS of its span."""
    eps = TIME_EPS * (t1 - t0)
    return not ((t < t0 - eps) | (t > t1 + eps))


@_inl
def time_curve_at(c, t, v, cx, cy, cds, cs0, off):  # pragma: no cover - compiled
    a = off[c]
    b = off[c + 1]
    if not time_window(t, cx[a, v], cx[b - 1, v]):
        return 0.0
    return curve_at(c, t, v, cx, cy, cds, cs0, off)


@_jit
def curve_inverse(c, f, direction, v, cx, cy, cds, cs0, cs1, off):  # pragma: no cover - compiled
    a = off[c]
    b = off[c + 1]
    n = b - a
    prev_x = 0.0
    prev_y = curve_at(c, 0.0, v, cx, cy, cds, cs0, off)
    for q in range(n):
        k = a + q if direction > 0 else b - 1 - q
        if cx[k, v] * direction > 0:
            lo = min(prev_y, cy[k, v])
            hi = max(prev_y, cy[k, v])
            if hi > lo and f >= lo and f <= hi:
                return prev_x + (f - prev_y) / (cy[k, v] - prev_y) * (cx[k, v] - prev_x)
            prev_x = cx[k, v]
            prev_y = cy[k, v]
    slope = cs1[c, v] if direction > 0 else cs0[c, v]
    if slope != 0.0:
        ext = (f - prev_y) / slope
        if ext * direction >= 0:
            return prev_x + ext
    return prev_x


@_jit
def unloading_inverse(c, f, v, cx, cy, cs0, cs1, off):  # pragma: no cover - compiled
    a = off[c]
    b = off[c + 1]
    if f <= cy[a, v]:
        out = cx[a, v] + (f - cy[a, v]) / cs0[c, v]
    else:
        out = cx[b - 1, v] + (f - cy[b - 1, v]) / cs1[c, v]
    for k in range(a, b - 1):
        if f > cy[k, v] and f <= cy[k + 1, v]:
            out = cx[k, v] + (f - cy[k, v]) / (cy[k + 1, v] - cy[k, v]) * (cx[k + 1, v] - cx[k, v])
    return out


_ = np  # numpy is used by numba typing of the arrays passed in
