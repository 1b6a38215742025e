"""The generic kernel's spring stage: one spring over a block of variants (geometry, knot crossings,
force and state, scatter and summaries), calling :mod:`crashstudy.kernel.laws` per lane.

Block arrays: ``In`` the block-local inputs and ``Z`` the block state (:mod:`crashstudy.kernel.compiled`
builds both); ``T``/``P`` the topology and per-variant records of :mod:`crashstudy.kernel.driver`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from crashstudy.kernel.codes import CRUSH, DAMPER, ELASTOPLASTIC, GENERAL, LINEAR, NONLINEAR, NONLINEAR_DAMPER
from crashstudy.kernel.laws import (
    broken_at,
    collapsed,
    crush_knot_force,
    crush_law,
    crush_window,
    damper_force,
    elastoplastic_law,
    elongation_1d,
    elongation_2d,
    end_rate,
    energy_first_half,
    energy_increment,
    general_law,
    general_reverse,
    general_window,
    knot_crossing,
    knot_inside,
    knot_step,
    least,
    linear_force,
    nonlinear_force,  # fmt: skip
    nonlinear_window,
    peak,
)

_jit = nb.njit(cache=True, nogil=True)


@nb.njit(cache=True, nogil=True, inline="always")
def ramp(c, arg, out, off, cx_b, cy_b, ds_b, s0_b, B):  # pragma: no cover - compiled
    """out = curve c at arg, over the block (ramp sum; see batch.py)."""
    a0 = off[c]
    b0 = off[c + 1]
    for w in range(B):
        out[w] = cy_b[a0, w] + s0_b[c, w] * (arg[w] - cx_b[a0, w])
    for k in range(a0 + 1, b0 - 1):
        for w in range(B):
            out[w] = out[w] + ds_b[k, w] * max(0.0, arg[w] - cx_b[k, w])


@_jit
def geometry(s, i, j, kind, D, rate, B, In, Z):  # pragma: no cover - compiled
    """Elongation e_tmp, rate ed_tmp (when ``rate``) and unit axis ax_tmp of spring s; 2-D: collapse flag."""
    x, v, acc, dt_b = Z.x, Z.v, Z.acc, In.dt
    e_tmp, ed_tmp, ax_tmp = Z.e_tmp, Z.ed_tmp, Z.ax_tmp
    if D == 1:
        for w in range(B):
            sg = In.sg[s, w]
            e_tmp[w] = elongation_1d(sg, x[j, 0, w] - In.x0[j, 0, w], x[i, 0, w] - In.x0[i, 0, w])
            ax_tmp[0, w] = sg
        if kind == DAMPER or kind == NONLINEAR_DAMPER or rate:
            for w in range(B):
                vpj = end_rate(v[j, 0, w], acc[j, 0, w], dt_b[w])
                vpi = end_rate(v[i, 0, w], acc[i, 0, w], dt_b[w])
                ed_tmp[w] = In.sg[s, w] * (vpj - vpi)
        return
    for w in range(B):
        ln2 = 0.0
        for d in range(D):
            dd = x[j, d, w] - x[i, d, w]
            ax_tmp[d, w] = dd
            ln2 += dd * dd
        ln = np.sqrt(ln2)
        turn = 0.0
        for d in range(D):
            turn += ax_tmp[d, w] * Z.axis_prev[s, d, w]
            Z.axis_prev[s, d, w] = ax_tmp[d, w]
        gone = collapsed(ln, In.l0[s, w], turn)
        if gone and Z.crushed[w] < 0 and not Z.broken[s, w]:  # a broken spring may collapse
            Z.crushed[w] = s
        dn = 1.0 if gone else ln
        edot = 0.0
        for d in range(D):
            ax_tmp[d, w] = ax_tmp[d, w] / dn
            edot += ax_tmp[d, w] * (end_rate(v[j, d, w], acc[j, d, w], dt_b[w]) - end_rate(v[i, d, w], acc[i, d, w], dt_b[w]))
        e_tmp[w] = elongation_2d(ln, In.l0[s, w])
        ed_tmp[w] = edot


@nb.njit(cache=True, nogil=True, inline="always")
def window(kind, ep, e, st, s, w):  # pragma: no cover - compiled
    """The knot window (lo, hi, shift) of a lane of spring s: where it follows its curve (state before the step)."""
    if kind == CRUSH:
        return crush_window(e, st[s, 0, w])
    if kind == GENERAL:
        return general_window(ep, e, st[s, 0, w], st[s, 1, w], st[s, 3, w], st[s, 5, w])
    return nonlinear_window(ep, e)


@_jit
def knots(s, kind, T, In, Z, B):  # pragma: no cover - compiled
    """Did any lane pass over a flagged knot of spring s since the previous step? If so (rare), the
    winning knot of each lane (k_c, k_x, k_y, k_sh). Returns the number of lanes that passed one."""
    ca = T.curve_a[s]
    off = T.curve_off
    e_tmp, e_prev, st = Z.e_tmp, Z.e_prev, Z.state
    nhit = 0
    for k in range(off[ca] + 1, off[ca + 1] - 1):  # cheap: no stores
        if T.knot_check[k]:
            for w in range(B):
                lo_, hi_, _ = window(kind, e_prev[s, w], e_tmp[w], st, s, w)
                nhit += knot_inside(In.cx[k, w], lo_, hi_)
    if nhit == 0:
        return 0
    nhit = 0
    first = True
    for k in range(off[ca] + 1, off[ca + 1] - 1):
        if not T.knot_check[k]:
            continue
        for w in range(B):
            lo_, hi_, sh = window(kind, e_prev[s, w], e_tmp[w], st, s, w)
            yk = crush_knot_force(In.ky[k, w]) if kind == CRUSH else In.ky[k, w]
            c0 = 0.0 if first else Z.k_c[w]
            c1, Z.k_x[w], Z.k_y[w] = knot_step(c0, (e_prev[s, w] - sh) if first else Z.k_x[w],
                                               0.0 if first else Z.k_y[w], lo_, hi_, In.cx[k, w], yk)  # fmt: skip
            Z.k_c[w] = c1
            Z.k_sh[w] = sh
            nhit += c1 > c0
        first = False
    return nhit


@_jit
def force(s, kind, lo, T, P, In, Z, B):  # pragma: no cover - compiled
    """F_tmp = the force of spring s (material dispatch: one line per law); updates its state."""
    e_tmp, F_tmp, st = Z.e_tmp, Z.F_tmp, Z.state
    off = T.curve_off
    if kind == LINEAR:
        for w in range(B):
            F_tmp[w] = linear_force(In.kp[s, w], e_tmp[w])
    elif kind == DAMPER:
        for w in range(B):
            F_tmp[w] = damper_force(In.kp[s, w], Z.ed_tmp[w])
    elif kind == NONLINEAR:
        ramp(T.curve_a[s], e_tmp, F_tmp, off, In.cx, In.cy, In.ds, In.s0, B)
        for w in range(B):
            F_tmp[w] = nonlinear_force(F_tmp[w])
    elif kind == CRUSH:
        ramp(T.curve_a[s], e_tmp, F_tmp, off, In.cx, In.cy, In.ds, In.s0, B)
        for w in range(B):
            F_tmp[w], st[s, 0, w], st[s, 1, w] = crush_law(e_tmp[w], st[s, 0, w], st[s, 1, w], F_tmp[w], In.kp[s, w])
    elif kind == ELASTOPLASTIC:
        for w in range(B):
            F_tmp[w], st[s, 0, w], st[s, 1, w] = elastoplastic_law(e_tmp[w], st[s, 0, w], st[s, 1, w], In.kp[s, w],
                                                                   P.ktan[s, lo + w], P.fy[s, lo + w])  # fmt: skip
    elif kind == NONLINEAR_DAMPER:
        ramp(T.curve_a[s], Z.ed_tmp, F_tmp, off, In.cx, In.cy, In.ds, In.s0, B)
    else:  # GENERAL: rules 1-3 over the block; reversals (rare) lane by lane
        ca = T.curve_a[s]
        cb = T.curve_b[s]
        for w in range(B):
            Z.g_arg[w] = e_tmp[w] - st[s, 5, w]
            Z.g_argt[w] = e_tmp[w] - st[s, 1, w]
            Z.g_argc[w] = e_tmp[w] - st[s, 3, w]
        ramp(ca, Z.g_arg, Z.g_L, off, In.cx, In.cy, In.ds, In.s0, B)
        ramp(cb, Z.g_argt, Z.g_Ut, off, In.cx, In.cy, In.ds, In.s0, B)
        ramp(cb, Z.g_argc, Z.g_Uc, off, In.cx, In.cy, In.ds, In.s0, B)
        nrev = 0
        for w in range(B):
            (F_tmp[w], st[s, 0, w], st[s, 1, w], st[s, 2, w], st[s, 3, w], st[s, 4, w], st[s, 6, w], st[s, 7, w],
             rev) = general_law(e_tmp[w], st[s, 0, w], st[s, 1, w], st[s, 2, w], st[s, 3, w], st[s, 4, w],
                                st[s, 6, w], st[s, 7, w], Z.g_L[w], Z.g_Ut[w], Z.g_Uc[w], In.yt[s, w], In.yc[s, w])  # fmt: skip
            Z.g_rev[w] = rev
            nrev += rev
        if nrev > 0:
            for w in range(B):
                if Z.g_rev[w]:
                    (F_tmp[w], st[s, 0, w], st[s, 1, w], st[s, 2, w], st[s, 3, w], st[s, 4, w], st[s, 5, w],
                     st[s, 6, w], st[s, 7, w]) = general_reverse(
                        e_tmp[w], st[s, 0, w], st[s, 1, w], st[s, 2, w], st[s, 3, w], st[s, 4, w], st[s, 6, w],
                        st[s, 7, w], In.yt[s, w], In.yc[s, w], ca, cb, lo + w, P.cx, P.cy, P.cds, P.cs0, P.cs1, off)  # fmt: skip


@_jit
def crossing(s, D, B, Z):  # pragma: no cover - compiled
    """Peak-force candidate and deceleration data of the knots spring s passed this step (see reference)."""
    for w in range(B):
        kcw = Z.k_c[w]
        th, dF = knot_crossing(kcw, Z.k_x[w], Z.k_y[w], Z.e_prev[s, w], Z.e_tmp[w], Z.k_sh[w], Z.f_prev[s, w],
                               Z.F_tmp[w])  # fmt: skip
        kcw = 0.0 if Z.broken[s, w] else kcw  # a spring that breaks in this step: the step's ends only
        Z.k_hit[s, w] = kcw > 0.0
        Z.k_th[s, w] = th
        for d in range(D):
            Z.k_dfax[s, d, w] = dF * Z.ax_tmp[d, w]
        Z.pf[s, w] = peak(Z.pf[s, w], kcw * Z.actf[w])


@_jit
def failure(s, n, lo, P, In, Z, Out, B):  # pragma: no cover - compiled
    """A breakable spring: past a failure elongation it breaks (force 0 from this step on); ftmp[0] / ftmp[1]
    are the elongation and activity its extremes take (the failure elongation, 0 once broken)."""
    for w in range(B):
        q = lo + w
        was = Z.broken[s, w]
        snaps, limit, t = broken_at(Z.e_tmp[w], Z.e_prev[s, w], P.fail_t[s, q], P.fail_c[s, q], n, In.dt[w])
        snaps = snaps and Z.act[w] and not was and n > 0
        Z.ftmp[1, w] = 0.0 if was else Z.actf[w]
        Z.ftmp[0, w] = limit if snaps else Z.e_tmp[w]
        if snaps:
            Out.spring_fail_time[s, q] = t
            Z.broken[s, w] = True
        if Z.broken[s, w]:
            Z.F_tmp[w] = 0.0


@_jit
def scatter(s, i, j, n, first_half, lo, D, B, e0, rate0, dt, Z):  # pragma: no cover - compiled
    """Nodal forces of spring s and its summaries (masked by arithmetic: a stopped variant adds 0 and
    compares against 0; peaks are >= 0)."""
    f, F_tmp, e_tmp, ax_tmp = Z.f, Z.F_tmp, Z.e_tmp, Z.ax_tmp
    if D == 1 and n > 0:  # one pass: scatter and summaries
        for w in range(B):
            fa = F_tmp[w] * ax_tmp[0, w]
            f[i, 0, w] += fa
            f[j, 0, w] -= fa
    else:
        for d in range(D):
            for w in range(B):
                fa = F_tmp[w] * ax_tmp[d, w]
                f[i, d, w] += fa
                f[j, d, w] -= fa
    if not Z.v2[1, s] and not (n == 1 and first_half):  # the common case: one plain pass
        for w in range(B):
            F = F_tmp[w]
            e = e_tmp[w]
            af = Z.actf[w]
            if n > 0:
                Z.ie[s, w] = energy_increment(Z.ie[s, w], F, Z.f_prev[s, w], e, Z.e_prev[s, w], af)
            Z.ie_tot[w] += Z.ie[s, w]
            Z.pf[s, w] = peak(Z.pf[s, w], abs(F) * af)
            Z.mc[s, w] = peak(Z.mc[s, w], -e * af)
            Z.me[s, w] = peak(Z.me[s, w], e * af)
            Z.forces[s, w] = F
            Z.elong[s, w] = e
            Z.f_prev[s, w] = F
            Z.e_prev[s, w] = e
        return
    fr = Z.v2[1, s]
    for w in range(B):  # a preloaded spring's first step, or a breakable spring
        F = F_tmp[w]
        e = e_tmp[w]
        af = Z.actf[w]
        if n == 1 and first_half and e0[s, lo + w] != 0.0:
            Z.ie[s, w] = energy_first_half(Z.ie[s, w], F, Z.f_prev[s, w], e, Z.e_prev[s, w], dt[w], rate0[s, lo + w],
                                           af)  # fmt: skip
        elif n > 0:
            Z.ie[s, w] = energy_increment(Z.ie[s, w], F, Z.f_prev[s, w], e, Z.e_prev[s, w], af)
        Z.ie_tot[w] += Z.ie[s, w]
        Z.pf[s, w] = peak(Z.pf[s, w], abs(F) * af)
        em = Z.ftmp[0, w] if fr else e  # extremes while intact
        ai = Z.ftmp[1, w] if fr else af
        Z.mc[s, w] = peak(Z.mc[s, w], -em * ai)
        Z.me[s, w] = peak(Z.me[s, w], em * ai)
        Z.forces[s, w] = F
        Z.elong[s, w] = e
        Z.f_prev[s, w] = F
        Z.e_prev[s, w] = e


@_jit
def springs(n, lo, B, D, has_term, T, P, In, Z, Out):  # pragma: no cover - compiled
    """Every spring of the block at step n. Returns whether a lane passed over a knot (any_hit)."""
    any_hit = False
    for s in range(T.spring_i.shape[0]):
        i = T.spring_i[s]
        j = T.spring_j[s]
        kind = T.material[s]
        geometry(s, i, j, kind, D, has_term, B, In, Z)
        if Z.v2[0, s]:  # e = e0 + ... (initial_elongation)
            for w in range(B):
                Z.e_tmp[w] = P.e0[s, lo + w] + Z.e_tmp[w]
        nhit = knots(s, kind, T, In, Z, B) if (Z.knotted[s] and n > 0) else 0
        force(s, kind, lo, T, P, In, Z, B)
        if Z.v2[1, s]:
            failure(s, n, lo, P, In, Z, Out, B)
        if Z.knotted[s] and n > 0:
            Z.k_any[s] = nhit > 0
        if nhit > 0:
            any_hit = True
            crossing(s, D, B, Z)
        # (only the arrays it needs: a record argument is copied at every call)
        scatter(s, i, j, n, Z.v2[0, s] and kind != DAMPER and kind != NONLINEAR_DAMPER, lo, D, B, P.e0, P.rate0, In.dt, Z)
        if has_term:
            for w in range(B):
                Z.edot_min[w] = least(Z.edot_min[w], Z.ed_tmp[w])
    return any_hit
