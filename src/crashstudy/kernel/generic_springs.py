"""The generic kernel's spring stage over a block, one spring at a time: geometry, curve ramps, the knot
search, failure, and the scatter of the spring's force to its nodes with its summaries.

Every function is compiled once (:data:`generic_block.stage`: numba's default ``inline="never"``, no
CPython or C wrapper, so it is callable from compiled code only) and called by
:func:`crashstudy.kernel.compiled._run`, without NRT; the ones called on every spring and step
(:data:`generic_block.hot_stage`: ``geometry``, ``scatter``, ``_forces_on_nodes``) are LLVM ``alwaysinline``
(the grid, 1 variant: 0.23x the kernel time; inlining ``ramp`` and ``failure`` too made it 1.29x slower,
docs/kernels.md), LLVM inlines the rest when worth it. numba IR inlining
(``inline="always"``, 3c0414e to 1ab7358) re-typed and re-lowered every copy inside one huge function: the
generic kernel's cold compile took 1.6x longer (benchmarks/results/generic_compile.md). Each takes only the
arrays it uses, never the :data:`generic_block.Block` record (passed per spring and step, the record cost
+33% compile time and +40% run time); every per-lane formula is a law of
:mod:`crashstudy.kernel.laws` / :mod:`crashstudy.kernel.step_laws`.
"""

from __future__ import annotations

from crashstudy.kernel.generic_block import hot_stage, stage
from crashstudy.kernel.laws import (
    axis_2d,
    broken_at,
    crush_knot_force,
    crush_window,
    elongation_1d,
    elongation_2d,
    end_rate,
    general_window,
    knot_crossing,
    knot_inside,
    knot_step,
    nonlinear_window,
    peak,
    ramp_knot,
    ramp_start,
)
from crashstudy.kernel.step_laws import energy_first_half, energy_increment, spring_extremes
from crashstudy.vocabulary.codes import CRUSH, GENERAL


@stage
def ramp(c, arg, out, off, cx_b, cy_b, ds_b, s0_b, B):  # pragma: no cover - compiled
    """out = curve c at arg, over the block (the ramp sum of ``laws.ramp_start`` / ``ramp_knot``)."""
    a0 = off[c]
    b0 = off[c + 1]
    for w in range(B):
        out[w] = ramp_start(cy_b[a0, w], s0_b[c, w], arg[w], cx_b[a0, w])
    for k in range(a0 + 1, b0 - 1):
        for w in range(B):
            out[w] = ramp_knot(out[w], ds_b[k, w], arg[w], cx_b[k, w])


@hot_stage
def geometry(
    s,
    i,
    j,
    D,
    B,
    rates,
    pm_disp,
    x,
    x0_b,
    v,
    acc,
    dt_b,
    sg_b,
    l0_b,
    axis_prev,
    broken,
    crushed,
    e_tmp,
    ed_tmp,
    ax_tmp,
):  # pragma: no cover - compiled
    """Spring s's elongation ``e_tmp``, axis ``ax_tmp`` and (``rates``, always in 2-D) elongation rate
    ``ed_tmp`` from v^{n-1/2} + dt/2 a^{n-1}; in 2-D the previous direction and the first collapsed spring
    (models are 1-D or 2-D: schema ``Vector``)."""
    if D == 1:
        for w in range(B):
            sg = sg_b[s, w]
            e_tmp[w] = elongation_1d(sg, x[j, 0, w] - x0_b[j, 0, w], x[i, 0, w] - x0_b[i, 0, w])
            ax_tmp[0, w] = sg
        if rates:
            for w in range(B):
                vpj = end_rate(v[j, 0, w], 0.0 if pm_disp[j, 0] else acc[j, 0, w], dt_b[w])
                vpi = end_rate(v[i, 0, w], 0.0 if pm_disp[i, 0] else acc[i, 0, w], dt_b[w])
                ed_tmp[w] = sg_b[s, w] * (vpj - vpi)
        return
    for w in range(B):
        u0 = x[j, 0, w] - x[i, 0, w]
        u1 = x[j, 1, w] - x[i, 1, w]
        ax_tmp[0, w], ax_tmp[1, w], ln, gone = axis_2d(
            u0, u1, axis_prev[s, 0, w], axis_prev[s, 1, w], l0_b[s, w]
        )
        axis_prev[s, 0, w] = u0
        axis_prev[s, 1, w] = u1
        if gone and crushed[w] < 0 and not broken[s, w]:  # a broken spring may collapse
            crushed[w] = s
        edot = 0.0
        for d in range(D):
            vpj = end_rate(v[j, d, w], 0.0 if pm_disp[j, d] else acc[j, d, w], dt_b[w])
            vpi = end_rate(v[i, d, w], 0.0 if pm_disp[i, d] else acc[i, d, w], dt_b[w])
            edot += ax_tmp[d, w] * (vpj - vpi)
        e_tmp[w] = elongation_2d(ln, l0_b[s, w])
        ed_tmp[w] = edot


@stage
def knots_passed(
    s, kind, B, off, ca, knot_check, cx_b, ky_b, e_tmp, e_prev, state, k_c, k_x, k_y, k_sh
):  # pragma: no cover - compiled
    """How many lanes passed over a flagged knot of spring s's curve since the previous step (a cheap test
    without stores; the state is still the one before the step); if any, :func:`knot_search` (rare)."""
    nhit = 0
    for k in range(off[ca] + 1, off[ca + 1] - 1):
        if not knot_check[k]:
            continue
        if kind == CRUSH:
            for w in range(B):
                lo_, hi_, _ = crush_window(e_tmp[w], state[s, 0, w])
                nhit += knot_inside(cx_b[k, w], lo_, hi_)
        elif kind == GENERAL:
            for w in range(B):
                lo_, hi_, _ = general_window(
                    e_prev[s, w], e_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 3, w], state[s, 5, w]
                )
                nhit += knot_inside(cx_b[k, w], lo_, hi_)
        else:
            for w in range(B):
                lo_, hi_, _ = nonlinear_window(e_prev[s, w], e_tmp[w])
                nhit += knot_inside(cx_b[k, w], lo_, hi_)
    if nhit > 0:
        nhit = knot_search(
            s, kind, B, off, ca, knot_check, cx_b, ky_b, e_tmp, e_prev, state, k_c, k_x, k_y, k_sh
        )
    return nhit


@stage
def knot_search(
    s, kind, B, off, ca, knot_check, cx_b, ky_b, e_tmp, e_prev, state, k_c, k_x, k_y, k_sh
):  # pragma: no cover - compiled
    """The knots of spring s's curve that its lanes passed over this step (rare): each lane's winning
    knot (k_c, k_x, k_y, k_sh; the state is still the one before the step). Returns how many lanes
    passed one."""
    nhit = 0
    first = True
    for k in range(off[ca] + 1, off[ca + 1] - 1):
        if not knot_check[k]:
            continue
        for w in range(B):
            if kind == CRUSH:  # (e, e_min): crushing further
                lo_, hi_, sh = crush_window(e_tmp[w], state[s, 0, w])
                yk = crush_knot_force(ky_b[k, w])
            elif kind == GENERAL:  # on the loading curve, in its own (shifted) abscissa
                lo_, hi_, sh = general_window(
                    e_prev[s, w], e_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 3, w], state[s, 5, w]
                )
                yk = ky_b[k, w]
            else:  # nonlinear_elastic: the whole path
                lo_, hi_, sh = nonlinear_window(e_prev[s, w], e_tmp[w])
                yk = ky_b[k, w]
            c0 = 0.0 if first else k_c[w]
            x0 = (e_prev[s, w] - sh) if first else k_x[w]
            c1, k_x[w], k_y[w] = knot_step(c0, x0, 0.0 if first else k_y[w], lo_, hi_, cx_b[k, w], yk)
            k_c[w] = c1
            k_sh[w] = sh
            nhit += c1 > c0
        first = False
    return nhit


@stage
def knot_peaks(
    s, B, D, k_c, k_x, k_y, k_sh, e_prev, e_tmp, f_prev, F_tmp, ax_tmp, broken, actf, k_hit, k_th, k_dfax, pf
):  # pragma: no cover - compiled
    """After a knot crossing (rare): the peak-force candidate, and the crossing fraction and force jump
    x axis for the deceleration at the crossing (see the reference)."""
    for w in range(B):
        kcw = k_c[w]
        th, dF = knot_crossing(kcw, k_x[w], k_y[w], e_prev[s, w], e_tmp[w], k_sh[w], f_prev[s, w], F_tmp[w])
        kcw = 0.0 if broken[s, w] else kcw  # a spring that breaks in this step: the step's ends only
        k_hit[s, w] = kcw > 0.0
        k_th[s, w] = th
        for d in range(D):
            k_dfax[s, d, w] = dF * ax_tmp[d, w]
        pf[s, w] = peak(pf[s, w], kcw * actf[w])


@stage
def failure(
    s, n, lo, B, fail_t, fail_c, spring_fail_time, dt_b, e_tmp, e_prev, F_tmp, act, actf, broken, ftmp
):  # pragma: no cover - compiled
    """A breakable spring: past a failure elongation it breaks (force 0 from this step on); ftmp[0] / ftmp[1]
    are the elongation and activity its extremes take (the failure elongation, 0 once broken)."""
    for w in range(B):
        q = lo + w
        was = broken[s, w]
        snaps, limit, t = broken_at(e_tmp[w], e_prev[s, w], fail_t[s, q], fail_c[s, q], n, dt_b[w])
        snaps = snaps and act[w] and not was and n > 0
        ftmp[1, w] = 0.0 if was else actf[w]
        ftmp[0, w] = limit if snaps else e_tmp[w]
        if snaps:
            spring_fail_time[s, q] = t
            broken[s, w] = True
        if broken[s, w]:
            F_tmp[w] = 0.0


@hot_stage
def scatter(
    s,
    i,
    j,
    n,
    fh,
    fr,
    lo,
    D,
    B,
    e0,
    rate0,
    dt_b,
    F_tmp,
    e_tmp,
    ax_tmp,
    actf,
    ftmp,
    f,
    ie,
    ie_tot,
    pf,
    mc,
    me,
    forces,
    elong,
    f_prev,
    e_prev,
):  # pragma: no cover - compiled
    """Spring s's force on its nodes (f[i] += F ax, f[j] -= F ax) and its summaries: absorbed energy
    (:func:`step_laws.energy_increment`; ``fh``: a preloaded spring's first step, F^0 acting for the first
    half step, :func:`step_laws.energy_first_half`), peak force and extremes (:func:`step_laws.spring_extremes`;
    ``fr``: a breakable spring's extremes up to its break, ``ftmp``). One loop per case, the case chosen
    outside the lane loop, as the laws' callers had it before the split."""
    if fr or (n == 1 and fh):  # a breakable spring, or a preloaded spring's first step
        _forces_on_nodes(i, j, D, B, F_tmp, ax_tmp, f)
        for w in range(B):
            F = F_tmp[w]
            e = e_tmp[w]
            af = actf[w]
            if n == 1 and fh and e0[s, lo + w] != 0.0:
                ie[s, w] = energy_first_half(
                    ie[s, w], F, f_prev[s, w], e, e_prev[s, w], dt_b[w], rate0[s, lo + w], af
                )
            elif n > 0:
                ie[s, w] = energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
            ie_tot[w] += ie[s, w]
            em = ftmp[0, w] if fr else e  # extremes while intact
            ai = ftmp[1, w] if fr else af
            pf[s, w], mc[s, w], me[s, w] = spring_extremes(pf[s, w], mc[s, w], me[s, w], F, af, em, ai)
            forces[s, w] = F
            elong[s, w] = e
            f_prev[s, w] = F
            e_prev[s, w] = e
    elif D == 1 and n > 0:  # one pass: scatter and summaries
        for w in range(B):
            F = F_tmp[w]
            e = e_tmp[w]
            af = actf[w]
            fa = F * ax_tmp[0, w]
            f[i, 0, w] += fa
            f[j, 0, w] -= fa
            ie[s, w] = energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
            ie_tot[w] += ie[s, w]
            pf[s, w], mc[s, w], me[s, w] = spring_extremes(pf[s, w], mc[s, w], me[s, w], F, af, e, af)
            forces[s, w] = F
            elong[s, w] = e
            f_prev[s, w] = F
            e_prev[s, w] = e
    else:
        _forces_on_nodes(i, j, D, B, F_tmp, ax_tmp, f)
        for w in range(B):
            F = F_tmp[w]
            e = e_tmp[w]
            af = actf[w]
            if n > 0:
                ie[s, w] = energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
            ie_tot[w] += ie[s, w]
            pf[s, w], mc[s, w], me[s, w] = spring_extremes(pf[s, w], mc[s, w], me[s, w], F, af, e, af)
            forces[s, w] = F
            elong[s, w] = e
            f_prev[s, w] = F
            e_prev[s, w] = e


@hot_stage
def _forces_on_nodes(i, j, D, B, F_tmp, ax_tmp, f):  # pragma: no cover - compiled
    """f[i] += F ax, f[j] -= F ax over the block."""
    for d in range(D):
        for w in range(B):
            fa = F_tmp[w] * ax_tmp[d, w]
            f[i, d, w] += fa
            f[j, d, w] -= fa
