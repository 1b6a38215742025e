"""The frontal loop's branch-free pieces (selects, ``min``/``max``): ramp-sum curves, the crush and
general_nonlinear material laws, the per-step summaries and the node update. Part of the hand-specialised
reference loop for ``studies/models/frontal-9mass.yaml`` (benchmarks only; frontal_specialised.py describes
it)."""

from __future__ import annotations

from frontal_constants import _jit


@_jit
def _max(a, b):  # pragma: no cover - compiled
    """``max(a, b)`` as a select (numba's builtin ``max`` is a call that blocks vectorisation)."""
    return b if b > a else a


@_jit
def _min(a, b):  # pragma: no cover - compiled
    """``_min(a, b)`` as a select."""
    return b if b < a else a


@_jit
def _ramp3(e, c):  # pragma: no cover - compiled
    """Ramp sum with 3 interior knots, coefficients (y0, s0, x0, x1, ds1, ...) as build_batch's."""
    y = c[0] + c[1] * (e - c[2])
    y = y + c[4] * _max(0.0, e - c[3])
    y = y + c[6] * _max(0.0, e - c[5])
    return y + c[8] * _max(0.0, e - c[7])


@_jit
def _ramp4(e, c):  # pragma: no cover - compiled
    """Ramp sum with 4 interior knots."""
    return _ramp3(e, c) + c[10] * _max(0.0, e - c[9])


@_jit
def _ramp5(e, c):  # pragma: no cover - compiled
    """Ramp sum with 5 interior knots."""
    return _ramp4(e, c) + c[12] * _max(0.0, e - c[11])


@_jit
def _line(e, c):  # pragma: no cover - compiled
    """A straight curve (its one interior knot has a zero slope change, which adds exactly 0)."""
    return c[0] + c[1] * (e - c[2])


@_jit
def _crush(e, emin, fstar, ramp, c, ku, ys, ixs):  # pragma: no cover - compiled
    """Crush law (docs/format.md), branch-free: returns (F, e_min, F*) after this step; the loading curve
    is ``ys * curve(e * ixs)`` (a study's curve scale and 1 / x_scale)."""
    on = e <= emin
    f_load = _min(0.0, ys * ramp(e * ixs, c))
    f_unl = _min(0.0, fstar + ku * (e - emin))
    return (f_load if on else f_unl), (e if on else emin), (f_load if on else fstar)


@_jit
def _general(
    e, mode, et, ft, ec, fc, shift, yld_t, yld_c, ramp, cl, ramp_inv, cinv, cu, ku, yt, yc
):  # pragma: no cover - compiled
    """general_nonlinear rules 1-4 (docs/format.md) for a monotone loading curve and a straight unloading
    line: every branch is evaluated and the result selected. State: mode, e*_t, F*_t, e*_c, F*_c,
    shift, yielded_t, yielded_c (as the generic kernel's); returns (F, new state...)."""
    L = ramp(e - shift, cl)
    thr_t = ft if yld_t > 0.0 else yt
    thr_c = fc if yld_c > 0.0 else yc
    m0 = mode == 0.0
    mp = mode > 0.0
    mn = mode < 0.0
    to_t = m0 & (L >= yt)
    to_c = m0 & (L <= yc)
    load_p = mp & (e >= et)
    load_n = mn & (e <= ec)
    fu_p = ft + _line(e - et, cu)
    fu_n = fc + _line(e - ec, cu)
    rev_c = mp & (e < et) & (fu_p <= thr_c)
    rev_t = mn & (e > ec) & (fu_n >= thr_t)
    f_unl = fu_p if mp else fu_n
    F = L if (m0 | load_p | load_n) else f_unl
    et = e if load_p else et
    ft = L if load_p else ft
    ec = e if load_n else ec
    fc = L if load_n else fc
    # rule 4: the loading curve shifted through the current point (computed always, used on reversal)
    thr = thr_c if mp else thr_t
    base_e = et if mp else ec
    base_f = ft if mp else fc
    rev = rev_c | rev_t
    shift_new = base_e + (thr - base_f) / ku - ramp_inv(thr, cinv)
    shift = shift_new if rev else shift
    Ls = ramp(e - shift, cl)
    F = Ls if rev else F
    ec = e if rev_c else ec
    fc = Ls if rev_c else fc
    et = e if rev_t else et
    ft = Ls if rev_t else ft
    et = e if to_t else et
    ft = L if to_t else ft
    ec = e if to_c else ec
    fc = L if to_c else fc
    up = to_t | rev_t
    down = (to_c | rev_c) & (not up)
    mode_dn = -1.0 if down else mode
    mode = 1.0 if up else mode_dn
    yld_t = 1.0 if up else yld_t
    yld_c = 1.0 if down else yld_c
    return F, mode, et, ft, ec, fc, shift, yld_t, yld_c


@_jit
def _summary(F, e, ie, fp, ep, pf, mc, af, wt):  # pragma: no cover - compiled
    """Absorbed work (trapezoid), peak |F| and max crush of one spring after this step."""
    ie = ie + (0.5 * (F + fp) * (e - ep)) * (af * wt)
    return ie, _max(pf, abs(F) * af), _max(mc, -e * af)


@_jit
def _node(f, im, m, vo, u, pa, h, dtw, af):  # pragma: no cover - compiled
    """Central-difference update of one node: (a, v_old, v_new, m v_old v_new / 2, peak a^2, u, v)."""
    a = f * im
    vn = vo + (h * dtw) * a
    return (
        a,
        vo,
        vn,
        0.5 * m * vo * vn,
        _max(pa, (a * a) * af),
        u + (dtw * af) * vn,
        vn * af + vo * (1.0 - af),
    )
