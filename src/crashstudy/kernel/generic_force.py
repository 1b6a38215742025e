"""The generic kernel's material dispatch: a spring's force over the block and its new state, one branch per
material of :mod:`crashstudy.vocabulary.materials`, each the law of :mod:`crashstudy.kernel.laws`.

Compiled once and called by :func:`crashstudy.kernel.compiled._run` (no numba IR inlining, no CPython or C
wrapper) and, like the stages of :mod:`crashstudy.kernel.generic_springs`, given only the arrays it uses (not
the block record). :func:`force` is LLVM ``alwaysinline`` (:data:`generic_block.hot_stage`, called on every
spring and step); :func:`general` stays a call (inlined too, with ``knots_passed``, the grid ran 2.1x slower).
"""

from __future__ import annotations

from crashstudy.kernel.generic_block import hot_stage, stage
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


@hot_stage
def force(
    s,
    kind,
    lo,
    B,
    ca,
    off,
    rate_off,
    rate_curve,
    ktan,
    fy,
    rate_at,
    cx_b,
    cy_b,
    ds_b,
    s0_b,
    kp_b,
    e_tmp,
    ed_tmp,
    F_tmp,
    state,
    g_L,
    g_Ut,
):  # pragma: no cover - compiled
    """Spring s's force over the block (F_tmp) and its new state, every material but ``general_nonlinear``
    (:func:`general`; ``compiled._run`` picks): one branch per material, each the law of
    :mod:`crashstudy.kernel.laws`. ``ca`` is its curve, the other arrays those of the topology and input
    records, not the records (passed per spring and step, a record costs an incref per array)."""
    if kind == LINEAR:
        for w in range(B):
            F_tmp[w] = linear_force(kp_b[s, w], e_tmp[w])
    elif kind == DAMPER:
        for w in range(B):
            F_tmp[w] = damper_force(kp_b[s, w], ed_tmp[w])
    elif kind == NONLINEAR:
        ramp(ca, e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for w in range(B):
            F_tmp[w] = nonlinear_force(F_tmp[w])
    elif kind == CRUSH:
        ramp(ca, e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for w in range(B):
            F_tmp[w], state[s, 0, w], state[s, 1, w] = crush_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], F_tmp[w], kp_b[s, w]
            )
    elif kind == ELASTOPLASTIC:
        for w in range(B):
            F_tmp[w], state[s, 0, w], state[s, 1, w] = elastoplastic_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], kp_b[s, w], ktan[s, lo + w], fy[s, lo + w]
            )
    elif kind == NONLINEAR_DAMPER:
        ramp(ca, ed_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
    elif kind == RATE_ELASTIC:  # its first curve, then each neighbouring pair folded in by the rate
        r_a, r_z = rate_off[s], rate_off[s + 1]
        ramp(rate_curve[r_a], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for k in range(r_a, r_z - 1):
            ramp(rate_curve[k], e_tmp, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
            ramp(rate_curve[k + 1], e_tmp, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
            for w in range(B):
                F_tmp[w] = rate_segment(
                    F_tmp[w], abs(ed_tmp[w]), rate_at[k, lo + w], rate_at[k + 1, lo + w], g_L[w], g_Ut[w]
                )


@stage
def general(
    s,
    lo,
    B,
    ca,
    cb,
    off,
    cx,
    cy,
    cds,
    cs0,
    cs1,
    cx_b,
    cy_b,
    ds_b,
    s0_b,
    yt_b,
    yc_b,
    e_tmp,
    F_tmp,
    state,
    g_arg,
    g_argt,
    g_argc,
    g_L,
    g_Ut,
    g_Uc,
    g_rev,
):  # pragma: no cover - compiled
    """A ``general_nonlinear`` spring's force (F_tmp) and state: rules 1-4 of docs/format.md, branch-free over
    the block; reversals (rare) lane by lane from the curves ``ca`` (loading) and ``cb`` (unloading)."""
    for w in range(B):
        g_arg[w] = e_tmp[w] - state[s, 5, w]
        g_argt[w] = e_tmp[w] - state[s, 1, w]
        g_argc[w] = e_tmp[w] - state[s, 3, w]
    ramp(ca, g_arg, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
    ramp(cb, g_argt, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
    ramp(cb, g_argc, g_Uc, off, cx_b, cy_b, ds_b, s0_b, B)
    nrev = 0
    for w in range(B):
        (
            F_tmp[w],
            state[s, 0, w],
            state[s, 1, w],
            state[s, 2, w],
            state[s, 3, w],
            state[s, 4, w],
            state[s, 6, w],
            state[s, 7, w],
            rev,
        ) = general_law(
            e_tmp[w],
            state[s, 0, w],
            state[s, 1, w],
            state[s, 2, w],
            state[s, 3, w],
            state[s, 4, w],
            state[s, 6, w],
            state[s, 7, w],
            g_L[w],
            g_Ut[w],
            g_Uc[w],
            yt_b[s, w],
            yc_b[s, w],
        )
        g_rev[w] = rev
        nrev += rev
    if nrev > 0:
        for w in range(B):
            if g_rev[w]:
                (
                    F_tmp[w],
                    state[s, 0, w],
                    state[s, 1, w],
                    state[s, 2, w],
                    state[s, 3, w],
                    state[s, 4, w],
                    state[s, 5, w],
                    state[s, 6, w],
                    state[s, 7, w],
                ) = general_reverse(
                    e_tmp[w],
                    state[s, 0, w],
                    state[s, 1, w],
                    state[s, 2, w],
                    state[s, 3, w],
                    state[s, 4, w],
                    state[s, 6, w],
                    state[s, 7, w],
                    yt_b[s, w],
                    yc_b[s, w],
                    ca,
                    cb,
                    lo + w,
                    cx,
                    cy,
                    cds,
                    cs0,
                    cs1,
                    off,
                )
