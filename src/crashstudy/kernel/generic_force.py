"""The generic kernel's material dispatch: a spring's force over the block and its new state, one branch per
material of :mod:`crashstudy.vocabulary.materials`, each the law of :mod:`crashstudy.kernel.laws`.

Numba-inlined into :func:`crashstudy.kernel.compiled._run` (``inline="always"``) and, like the stages of
:mod:`crashstudy.kernel.generic_springs`, given only the arrays it uses (not the block record).
"""

from __future__ import annotations

import numba as nb

from crashstudy.kernel.generic_springs import ramp
from crashstudy.kernel.laws import (
    crush_law,
    damper_force,
    elastoplastic_law,
    general_law,
    general_reverse,
    linear_force,
    nonlinear_force,
    rate_segment,
)
from crashstudy.vocabulary.codes import (
    CRUSH,
    DAMPER,
    ELASTOPLASTIC,
    LINEAR,
    NONLINEAR,
    NONLINEAR_DAMPER,
    RATE_ELASTIC,
)


@nb.njit(cache=True, nogil=True, inline="always")
def force(s, kind, lo, B, T, P, cx_b, cy_b, ds_b, s0_b, kp_b, yt_b, yc_b, e_tmp, ed_tmp, F_tmp, state, g_arg, g_argt,
           g_argc, g_L, g_Ut, g_Uc, g_rev):  # pragma: no cover - compiled
    """Spring s's force over the block (F_tmp) and its new state: the material dispatch (one branch per
    material of :mod:`crashstudy.vocabulary.materials`, each the law of :mod:`crashstudy.kernel.laws`)."""
    off = T.curve_off
    if kind == LINEAR:
        for w in range(B):
            F_tmp[w] = linear_force(kp_b[s, w], e_tmp[w])
    elif kind == DAMPER:
        for w in range(B):
            F_tmp[w] = damper_force(kp_b[s, w], ed_tmp[w])
    elif kind == NONLINEAR:
        ramp(T.curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for w in range(B):
            F_tmp[w] = nonlinear_force(F_tmp[w])
    elif kind == CRUSH:
        ramp(T.curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for w in range(B):
            F_tmp[w], state[s, 0, w], state[s, 1, w] = crush_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], F_tmp[w], kp_b[s, w])
    elif kind == ELASTOPLASTIC:
        for w in range(B):
            F_tmp[w], state[s, 0, w], state[s, 1, w] = elastoplastic_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], kp_b[s, w], P.ktan[s, lo + w], P.fy[s, lo + w])
    elif kind == NONLINEAR_DAMPER:
        ramp(T.curve_a[s], ed_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
    elif kind == RATE_ELASTIC:  # its first curve, then each neighbouring pair folded in by the rate
        r_a, r_z = T.rate_off[s], T.rate_off[s + 1]
        ramp(T.rate_curve[r_a], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for k in range(r_a, r_z - 1):
            ramp(T.rate_curve[k], e_tmp, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
            ramp(T.rate_curve[k + 1], e_tmp, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
            for w in range(B):
                F_tmp[w] = rate_segment(
                    F_tmp[w], abs(ed_tmp[w]), P.rate_at[k, lo + w], P.rate_at[k + 1, lo + w], g_L[w], g_Ut[w])
    else:  # GENERAL: rules 1-4 of docs/format.md, branch-free over the block; reversals (rare) per lane
        ca = T.curve_a[s]
        cb = T.curve_b[s]
        for w in range(B):
            g_arg[w] = e_tmp[w] - state[s, 5, w]
            g_argt[w] = e_tmp[w] - state[s, 1, w]
            g_argc[w] = e_tmp[w] - state[s, 3, w]
        ramp(ca, g_arg, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
        ramp(cb, g_argt, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
        ramp(cb, g_argc, g_Uc, off, cx_b, cy_b, ds_b, s0_b, B)
        nrev = 0
        for w in range(B):
            (F_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w], state[s, 4, w],
             state[s, 6, w], state[s, 7, w], rev) = general_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w], state[s, 4, w],
                state[s, 6, w], state[s, 7, w], g_L[w], g_Ut[w], g_Uc[w], yt_b[s, w], yc_b[s, w])
            g_rev[w] = rev
            nrev += rev
        if nrev > 0:
            for w in range(B):
                if g_rev[w]:
                    (F_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w], state[s, 4, w],
                     state[s, 5, w], state[s, 6, w], state[s, 7, w]) = general_reverse(
                        e_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w],
                        state[s, 4, w], state[s, 6, w], state[s, 7, w], yt_b[s, w], yc_b[s, w], ca, cb,
                        lo + w, P.cx, P.cy, P.cds, P.cs0, P.cs1, off)
