"""The compiled (numba) kernel: the reference step of :mod:`crashstudy.kernel.reference`, with the
loop over variants innermost.

Variants are cut into blocks of at most ``BLOCK`` columns; blocks run in parallel on a thread pool
(the compiled function releases the GIL; a ``parallel=True`` kernel took minutes to compile) and
each block advances all its variants through time together, so the innermost loops run over
contiguous variant columns and the CPU works on several variants per instruction. Every variant
keeps its own step ``dt``, so its result does not depend on which block it lands in.

What a model does not contain is skipped: no material state without ``general_nonlinear``/``crush``,
no geometry (square roots, directions) in 1-D, no wall, load or prescribed-motion loops when there
are none, no history writes when no history is kept.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from crashstudy.kernel.codes import (
    CRUSH,
    CRUSHED_TO_ZERO,
    DAMPER,
    GENERAL,
    INVALID,
    LINEAR,
    NONLINEAR,
    NSTATE,
    PM_ACCELERATION,
    PM_DISPLACEMENT,
    UNSTABLE,
    UNSTABLE_ENERGY,
)
from crashstudy.kernel.driver import (
    block_starts,
    finish,
    get_threads,
    outputs,
    records,
    run_blocks,
    set_threads,
)
from crashstudy.kernel.laws import (
    collapsed,
    crush_knot_force,
    crush_law,
    crush_window,
    damper_force,
    elongation_1d,
    elongation_2d,
    end_rate,
    energy_increment,
    ext_power,
    general_law,
    general_reverse,
    general_window,
    knot_accel,
    knot_crossing,
    knot_inside,
    knot_step,
    least,
    linear_force,
    nonlinear_force,
    nonlinear_window,
    peak,
    time_curve_at,
    wall_force,
    wall_jump,
    work_increment,
)
from crashstudy.kernel.output import KernelOutput

if TYPE_CHECKING:
    from crashstudy.batch import Batch

BLOCK = 256
__all__ = ["BLOCK", "get_threads", "run_compiled", "set_threads"]


@nb.njit(cache=True, nogil=True, inline="always")
def _ramp(c, arg, out, off, cx_b, cy_b, ds_b, s0_b, B):  # pragma: no cover - compiled
    """out = curve c at arg, over the block (ramp sum; see batch.py)."""
    a0 = off[c]
    b0 = off[c + 1]
    for w in range(B):
        out[w] = cy_b[a0, w] + s0_b[c, w] * (arg[w] - cx_b[a0, w])
    for k in range(a0 + 1, b0 - 1):
        for w in range(B):
            out[w] = out[w] + ds_b[k, w] * max(0.0, arg[w] - cx_b[k, w])


@nb.njit(cache=True, nogil=True)
def _run(b_lo, b_hi, starts, n_out, T, P, H, Out):  # pragma: no cover - compiled
    """Blocks ``b_lo:b_hi`` (records of :mod:`crashstudy.kernel.driver`: T topology, P per-variant inputs,
    H histories, Out summaries); every per-variant formula is a law of :mod:`crashstudy.kernel.laws`."""
    si, sj, material, curve_a, curve_b, off, free = T.spring_i, T.spring_j, T.material, T.curve_a, T.curve_b, T.curve_off, T.free
    load_node, load_curve, pm_node, pm_dir, pm_kind, pm_curve = T.load_node, T.load_curve, T.pm_node, T.pm_dir, T.pm_kind, T.pm_curve
    wall_nodes, knot_check = T.wall_nodes, T.knot_check
    mass, inv_mass, x0, v0, length0, sign, kpar = P.mass, P.inv_mass, P.x0, P.v0, P.length0, P.sign, P.kpar
    yield_t, yield_c, cx, cy, cds, cs0, cs1 = P.yield_t, P.yield_c, P.cx, P.cy, P.cds, P.cs0, P.cs1
    gravity, load_force, pm_scale, wall_point, wall_normal = P.gravity, P.load_force, P.pm_scale, P.wall_point, P.wall_normal
    dt, n_steps, out_every, ke_fraction, min_time = P.dt, P.n_steps, P.out_every, P.ke_fraction, P.min_time
    invalid, e_floor, knot_y = P.invalid, P.energy_floor, P.knot_y
    rec_mask, h_pos, h_disp, h_vel, h_acc, h_force, h_elong = H.rec, H.pos, H.disp, H.vel, H.acc, H.force, H.elong
    h_energy, h_wall = H.energy, H.wall
    status, fail_time, fail_item, t_end, peak_force, max_crush = Out.status, Out.fail_time, Out.fail_item, Out.t_end, Out.peak_force, Out.max_crush
    absorbed, peak_acc, peak_wall, energy_error, final_energy = Out.absorbed, Out.peak_acc, Out.peak_wall, Out.energy_error, Out.final_energy
    N = x0.shape[0]
    D = x0.shape[1]
    S = si.shape[0]
    K = cx.shape[0]
    C = cs0.shape[0]
    W = wall_nodes.shape[0]
    NL = load_node.shape[0]
    NP = pm_node.shape[0]
    has_state = False
    for s in range(S):
        if material[s] == GENERAL or material[s] == CRUSH:
            has_state = True
    has_gravity = False
    for d in range(D):
        for q in range(gravity.shape[1]):
            if gravity[d, q] != 0.0:
                has_gravity = True
    no_ext = NL == 0 and NP == 0 and not has_gravity
    any_hist = False
    for h in range(rec_mask.shape[0]):
        any_hist = any_hist or rec_mask[h]
    has_term = False
    for q in range(ke_fraction.shape[0]):
        if ke_fraction[q] > 0.0:
            has_term = True
    movable = np.zeros(N, dtype=np.bool_)
    for n_ in range(N):
        for d in range(D):
            if free[n_, d] > 0.0:
                movable[n_] = True
    for k in range(NP):
        movable[pm_node[k]] = True
    # springs whose curve has a knot that can be a local maximum of |force| (Batch.knot_check)
    knotted = np.zeros(S, dtype=np.bool_)
    any_knot = False
    for s in range(S):
        ca = curve_a[s]
        if (material[s] == NONLINEAR or material[s] == CRUSH or material[s] == GENERAL) and ca >= 0:
            for k in range(off[ca] + 1, off[ca + 1] - 1):
                if knot_check[k]:
                    knotted[s] = True
                    any_knot = True
    # 1-D models without walls, prescribed motion or external forces take a fused node update
    fused_1d = D == 1 and W == 0 and NP == 0 and no_ext
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        # block-local copies of the per-variant inputs (contiguous, cache-resident)
        m_b = np.empty((N, B))
        im_b = np.empty((N, D, B))
        x0_b = np.empty((N, D, B))
        sg_b = np.empty((S, B))
        l0_b = np.empty((S, B))
        kp_b = np.empty((S, B))
        cx_b = np.empty((K, B))
        cy_b = np.empty((K, B))
        ds_b = np.empty((K, B))
        ky_b = np.empty((K, B))
        s0_b = np.empty((C, B))
        yt_b = np.empty((S, B))
        yc_b = np.empty((S, B))
        g_arg = np.empty(B)
        g_argt = np.empty(B)
        g_argc = np.empty(B)
        g_L = np.empty(B)
        g_Ut = np.empty(B)
        g_Uc = np.empty(B)
        g_rev = np.zeros(B, dtype=np.bool_)
        dt_b = np.empty(B)
        for w in range(B):
            dt_b[w] = dt[lo + w]
        for n_ in range(N):
            for w in range(B):
                m_b[n_, w] = mass[n_, lo + w]
            for d in range(D):
                for w in range(B):
                    im_b[n_, d, w] = inv_mass[n_, d, lo + w]
                    x0_b[n_, d, w] = x0[n_, d, lo + w]
        for s in range(S):
            for w in range(B):
                sg_b[s, w] = sign[s, lo + w]
                yt_b[s, w] = yield_t[s, lo + w]
                yc_b[s, w] = yield_c[s, lo + w]
                l0_b[s, w] = length0[s, lo + w]
                kp_b[s, w] = kpar[s, lo + w]
        for k in range(K):
            for w in range(B):
                cx_b[k, w] = cx[k, lo + w]
                cy_b[k, w] = cy[k, lo + w]
                ds_b[k, w] = cds[k, lo + w]
                ky_b[k, w] = knot_y[k, lo + w]
        for c in range(C):
            for w in range(B):
                s0_b[c, w] = cs0[c, lo + w]
        # state
        x = np.empty((N, D, B))
        v = np.empty((N, D, B))
        vnew = np.empty((N, D, B))
        f = np.empty((N, D, B))
        fext = np.zeros((N, D, B))
        fext_prev = np.zeros((N, D, B))
        acc = np.zeros((N, D, B))  # a^{n-1} at the start of step n (dampers' velocity estimate)
        acc_prev = np.zeros((N, D, B) if any_knot else (0, D, B))  # a^{n-1} during step n (knot crossings)
        k_sh = np.empty(B)  # knot test: shift of the curve's abscissa (general_nonlinear)
        k_c = np.empty(B)  # candidate |force|, and the abscissa and force of the knot that gave it
        k_x = np.empty(B)
        k_y = np.empty(B)
        k_any = np.zeros(S, dtype=np.bool_)  # some lane of the block passed over a knot of spring s this step
        k_hit = np.zeros((S if any_knot else 0, B), dtype=np.bool_)  # this lane did
        k_th = np.zeros((S if any_knot else 0, B))  # crossing fraction of the step at that knot
        k_dfax = np.zeros((S if any_knot else 0, D, B))  # (knot force - interpolated force) * axis
        jump_prev = np.zeros((W, N, D, B))
        pm_acc = np.zeros((NP, B))  # kinematic acceleration of each prescribed dof
        axis_prev = np.zeros((S if D > 1 else 0, D, B))  # 2-D: previous spring direction (un-normalised)
        if D > 1:
            for s in range(S):
                for d in range(D):
                    for w in range(B):
                        axis_prev[s, d, w] = x0_b[sj[s], d, w] - x0_b[si[s], d, w]
        state = np.zeros((S if has_state else 0, NSTATE, B))
        forces = np.zeros((S, B))
        elong = np.zeros((S, B))
        f_prev = np.zeros((S, B))
        e_prev = np.zeros((S, B))
        ie = np.zeros((S, B))
        pf = np.zeros((S, B))
        mc = np.zeros((S, B))
        pacc = np.zeros((N, B))
        pwall = np.zeros((W, B))
        e_tmp = np.empty(B)
        ed_tmp = np.empty(B)
        F_tmp = np.empty(B)
        ax_tmp = np.empty((D, B))
        edot_min = np.empty(B)
        crushed = np.empty(B, dtype=np.int64)
        work = np.zeros(B)
        wall_e = np.zeros(B)
        wmax = np.zeros(B)
        ke0 = np.zeros(B)
        ke = np.zeros(B)
        ie_tot = np.zeros(B)
        err = np.zeros(B)
        bal = np.zeros(B)
        wforce = np.zeros((W, B))
        act = np.empty(B, dtype=np.bool_)
        actf = np.empty(B)  # 1.0 while the variant runs, else 0.0 (arithmetic masks vectorise)
        n_fail = np.full(B, -1, dtype=np.int64)
        nst = np.empty(B, dtype=np.int64)
        next_rec = np.zeros(B, dtype=np.int64)
        st_ok = np.zeros(B, dtype=np.int64)
        nmax = -1
        for w in range(B):
            q = lo + w
            nst[w] = n_steps[q]
            if invalid[q] > 0:
                st_ok[w] = INVALID
                fail_item[q] = invalid[q]
                fail_time[q] = 0.0
            elif nst[w] > nmax:
                nmax = nst[w]
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    x[n_, d, w] = x0_b[n_, d, w]
                    v[n_, d, w] = v0[n_, d, lo + w]
                    ke0[w] += 0.5 * m_b[n_, w] * v[n_, d, w] * v[n_, d, w]

        for n in range(nmax + 1):
            nact = 0
            n_end = nmax + 1  # the first step at which an active variant ends
            for w in range(B):
                a_ = (n <= nst[w]) & (st_ok[w] == 0)
                act[w] = a_
                actf[w] = 1.0 if a_ else 0.0
                nact += a_
                n_end = min(n_end, nst[w] if a_ else nmax + 1)
            if nact == 0:
                break
            rec_now = False
            if any_hist:
                for w in range(B):
                    rec_now = rec_now or (act[w] and n == next_rec[w])
            fused = fused_1d and n > 0 and not rec_now
            h = 1.0 if n > 0 else 0.5
            f[:] = 0.0
            if D > 1:
                for w in range(B):
                    crushed[w] = -1
            if has_term:
                for w in range(B):
                    edot_min[w] = np.inf
            for w in range(B):
                ie_tot[w] = 0.0
            any_hit = False
            for s in range(S):
                i = si[s]
                j = sj[s]
                kind = material[s]
                kn = knotted[s] and n > 0
                if D == 1:
                    for w in range(B):
                        sg = sg_b[s, w]
                        e_tmp[w] = elongation_1d(sg, x[j, 0, w] - x0_b[j, 0, w], x[i, 0, w] - x0_b[i, 0, w])
                        ax_tmp[0, w] = sg
                    if kind == DAMPER or has_term:
                        for w in range(B):
                            vpj = end_rate(v[j, 0, w], acc[j, 0, w], dt_b[w])
                            vpi = end_rate(v[i, 0, w], acc[i, 0, w], dt_b[w])
                            ed_tmp[w] = sg_b[s, w] * (vpj - vpi)
                else:
                    for w in range(B):
                        ln2 = 0.0
                        for d in range(D):
                            dd = x[j, d, w] - x[i, d, w]
                            ax_tmp[d, w] = dd
                            ln2 += dd * dd
                        ln = np.sqrt(ln2)
                        turn = 0.0
                        for d in range(D):
                            turn += ax_tmp[d, w] * axis_prev[s, d, w]
                            axis_prev[s, d, w] = ax_tmp[d, w]
                        gone = collapsed(ln, l0_b[s, w], turn)
                        if gone and crushed[w] < 0:
                            crushed[w] = s
                        dn = 1.0 if gone else ln
                        edot = 0.0
                        for d in range(D):
                            ax_tmp[d, w] = ax_tmp[d, w] / dn
                            vpj = end_rate(v[j, d, w], acc[j, d, w], dt_b[w])
                            vpi = end_rate(v[i, d, w], acc[i, d, w], dt_b[w])
                            edot += ax_tmp[d, w] * (vpj - vpi)
                        e_tmp[w] = elongation_2d(ln, l0_b[s, w])
                        ed_tmp[w] = edot
                nhit = 0
                if kn:  # did any lane pass over a flagged knot since the previous step? (cheap: no stores)
                    ca = curve_a[s]
                    for k in range(off[ca] + 1, off[ca + 1] - 1):
                        if not knot_check[k]:
                            continue
                        if kind == CRUSH:
                            for w in range(B):
                                lo_, hi_, _ = crush_window(e_tmp[w], state[s, 0, w])
                                nhit += knot_inside(cx_b[k, w], lo_, hi_)
                        elif kind == GENERAL:
                            for w in range(B):
                                lo_, hi_, _ = general_window(e_prev[s, w], e_tmp[w], state[s, 0, w], state[s, 1, w],
                                                             state[s, 3, w], state[s, 5, w])  # fmt: skip
                                nhit += knot_inside(cx_b[k, w], lo_, hi_)
                        else:
                            for w in range(B):
                                lo_, hi_, _ = nonlinear_window(e_prev[s, w], e_tmp[w])
                                nhit += knot_inside(cx_b[k, w], lo_, hi_)
                if nhit > 0:  # rare: the knots passed over, lane by lane (the state is still the one before the step)
                    nhit = 0
                    ca = curve_a[s]
                    first = True
                    for k in range(off[ca] + 1, off[ca + 1] - 1):
                        if not knot_check[k]:
                            continue
                        if kind == CRUSH:  # (e, e_min): crushing further
                            for w in range(B):
                                lo_, hi_, sh = crush_window(e_tmp[w], state[s, 0, w])
                                c0 = 0.0 if first else k_c[w]
                                c1, k_x[w], k_y[w] = knot_step(c0, (e_prev[s, w] - sh) if first else k_x[w],
                                                               0.0 if first else k_y[w], lo_, hi_, cx_b[k, w],
                                                               crush_knot_force(ky_b[k, w]))  # fmt: skip
                                k_c[w] = c1
                                k_sh[w] = sh
                                nhit += c1 > c0
                        elif kind == GENERAL:  # on the loading curve, in its own (shifted) abscissa
                            for w in range(B):
                                lo_, hi_, sh = general_window(e_prev[s, w], e_tmp[w], state[s, 0, w], state[s, 1, w],
                                                              state[s, 3, w], state[s, 5, w])  # fmt: skip
                                c0 = 0.0 if first else k_c[w]
                                c1, k_x[w], k_y[w] = knot_step(c0, (e_prev[s, w] - sh) if first else k_x[w],
                                                               0.0 if first else k_y[w], lo_, hi_, cx_b[k, w], ky_b[k, w])
                                k_c[w] = c1
                                k_sh[w] = sh
                                nhit += c1 > c0
                        else:  # nonlinear_elastic: the whole path
                            for w in range(B):
                                lo_, hi_, sh = nonlinear_window(e_prev[s, w], e_tmp[w])
                                c0 = 0.0 if first else k_c[w]
                                c1, k_x[w], k_y[w] = knot_step(c0, (e_prev[s, w] - sh) if first else k_x[w],
                                                               0.0 if first else k_y[w], lo_, hi_, cx_b[k, w], ky_b[k, w])
                                k_c[w] = c1
                                k_sh[w] = sh
                                nhit += c1 > c0
                        first = False
                if kind == LINEAR:
                    for w in range(B):
                        F_tmp[w] = linear_force(kp_b[s, w], e_tmp[w])
                elif kind == DAMPER:
                    for w in range(B):
                        F_tmp[w] = damper_force(kp_b[s, w], ed_tmp[w])
                elif kind == NONLINEAR:
                    _ramp(curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
                    for w in range(B):
                        F_tmp[w] = nonlinear_force(F_tmp[w])
                elif kind == CRUSH:
                    _ramp(curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
                    for w in range(B):
                        F_tmp[w], state[s, 0, w], state[s, 1, w] = crush_law(e_tmp[w], state[s, 0, w], state[s, 1, w],
                                                                             F_tmp[w], kp_b[s, w])  # fmt: skip
                else:  # GENERAL: rules 1-4 of docs/format.md, branch-free over the block; reversals (rare) per lane
                    ca = curve_a[s]
                    cb = curve_b[s]
                    for w in range(B):
                        g_arg[w] = e_tmp[w] - state[s, 5, w]
                        g_argt[w] = e_tmp[w] - state[s, 1, w]
                        g_argc[w] = e_tmp[w] - state[s, 3, w]
                    _ramp(ca, g_arg, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
                    _ramp(cb, g_argt, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
                    _ramp(cb, g_argc, g_Uc, off, cx_b, cy_b, ds_b, s0_b, B)
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
                                    lo + w, cx, cy, cds, cs0, cs1, off)
                if kn:
                    k_any[s] = nhit > 0
                if nhit > 0:  # rare: peak-force candidate and the deceleration data (see reference)
                    any_hit = True
                    for w in range(B):
                        kcw = k_c[w]
                        th, dF = knot_crossing(kcw, k_x[w], k_y[w], e_prev[s, w], e_tmp[w], k_sh[w], f_prev[s, w],
                                               F_tmp[w])  # fmt: skip
                        k_hit[s, w] = kcw > 0.0
                        k_th[s, w] = th
                        for d in range(D):
                            k_dfax[s, d, w] = dF * ax_tmp[d, w]
                        pf[s, w] = peak(pf[s, w], kcw * actf[w])
                # masked by arithmetic: a stopped variant adds 0 and compares against 0 (peaks are >= 0)
                if D == 1 and n > 0:  # one pass: scatter and summaries
                    for w in range(B):
                        F = F_tmp[w]
                        e = e_tmp[w]
                        af = actf[w]
                        fa = F * ax_tmp[0, w]
                        f[i, 0, w] += fa
                        f[j, 0, w] -= fa
                        ie[s, w] = energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
                        ie_tot[w] += ie[s, w]
                        pf[s, w] = peak(pf[s, w], abs(F) * af)
                        mc[s, w] = peak(mc[s, w], -e * af)
                        forces[s, w] = F
                        elong[s, w] = e
                        f_prev[s, w] = F
                        e_prev[s, w] = e
                else:
                    for d in range(D):
                        for w in range(B):
                            fa = F_tmp[w] * ax_tmp[d, w]
                            f[i, d, w] += fa
                            f[j, d, w] -= fa
                    for w in range(B):
                        F = F_tmp[w]
                        e = e_tmp[w]
                        af = actf[w]
                        if n > 0:
                            ie[s, w] = energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
                        ie_tot[w] += ie[s, w]
                        pf[s, w] = peak(pf[s, w], abs(F) * af)
                        mc[s, w] = peak(mc[s, w], -e * af)
                        forces[s, w] = F
                        elong[s, w] = e
                        f_prev[s, w] = F
                        e_prev[s, w] = e
                if has_term:
                    for w in range(B):
                        edot_min[w] = least(edot_min[w], ed_tmp[w])

            if any_hit:  # a^{n-1}, for the accelerations at this step's knot crossings
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            acc_prev[n_, d, w] = acc[n_, d, w]
            # external forces, accelerations, velocities
            if fused:
                # a = f/m, v^{n+1/2}, kinetic energy, peak |a| and x^{n+1} in one pass (the same
                # arithmetic as the general path below; x and v advance before the failure check,
                # which changes nothing a failed variant reports)
                for w in range(B):
                    ke[w] = 0.0
                for n_ in range(N):
                    mv = movable[n_]
                    for w in range(B):
                        a = (f[n_, 0, w] + 0.0) * im_b[n_, 0, w]
                        acc[n_, 0, w] = a
                        vo = v[n_, 0, w]
                        vn = vo + (h * dt_b[w]) * a
                        vnew[n_, 0, w] = vn
                        ke[w] += 0.5 * m_b[n_, w] * vo * vn
                        af = actf[w]
                        if mv:
                            pacc[n_, w] = peak(pacc[n_, w], (a * a) * af)
                        x[n_, 0, w] = x[n_, 0, w] + (dt_b[w] * af) * vn
                        v[n_, 0, w] = vn * af + vo * (1.0 - af)
            elif not no_ext:
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            fext[n_, d, w] = m_b[n_, w] * gravity[d, lo + w] if has_gravity else 0.0
                for k in range(NL):
                    c = load_curve[k]
                    p = load_node[k]
                    for w in range(B):
                        q = lo + w
                        scale = time_curve_at(c, n * dt_b[w], q, cx, cy, cds, cs0, off) if c >= 0 else 1.0
                        for d in range(D):
                            fext[p, d, w] += load_force[k, d, q] * scale
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            a = (f[n_, d, w] + fext[n_, d, w]) * im_b[n_, d, w]
                            acc[n_, d, w] = a
                            vnew[n_, d, w] = v[n_, d, w] + (h * dt_b[w]) * a
            else:
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            a = (f[n_, d, w] + 0.0) * im_b[n_, d, w]
                            acc[n_, d, w] = a
                            vnew[n_, d, w] = v[n_, d, w] + (h * dt_b[w]) * a
            for k in range(NP):
                p = pm_node[k]
                d = pm_dir[k]
                c = pm_curve[k]
                for w in range(B):
                    q = lo + w
                    t = n * dt_b[w]
                    dtn = h * dt_b[w]
                    if pm_kind[k] == PM_DISPLACEMENT:
                        target = x0_b[p, d, w] + pm_scale[k, q] * time_curve_at(c, t + dt_b[w], q, cx, cy, cds, cs0, off)
                        vnew[p, d, w] = (target - x[p, d, w]) / dt_b[w]
                    elif pm_kind[k] == PM_ACCELERATION:
                        vnew[p, d, w] = v[p, d, w] + dtn * pm_scale[k, q] * time_curve_at(c, t, q, cx, cy, cds, cs0, off)
                    else:
                        vnew[p, d, w] = pm_scale[k, q] * time_curve_at(c, t + 0.5 * dt_b[w], q, cx, cy, cds, cs0, off)
                    if n != nst[w]:
                        pm_acc[k, w] = (vnew[p, d, w] - v[p, d, w]) / dtn
                    else:  # the last step's update would look past end_time: continue with the previous acceleration
                        vnew[p, d, w] = v[p, d, w] + dtn * pm_acc[k, w]
                    acc[p, d, w] = pm_acc[k, w]
                    ftot = f[p, d, w] + fext[p, d, w]
                    fext[p, d, w] += m_b[p, w] * acc[p, d, w] - ftot
            if W > 0:
                wforce[:] = 0.0
            for wl in range(W):
                for n_ in range(N):
                    if wall_nodes[wl, n_] == 0.0:
                        continue
                    for w in range(B):
                        q = lo + w
                        vn = 0.0
                        gap = 0.0
                        dist = 0.0
                        for d in range(D):
                            nr = wall_normal[wl, d, q]
                            vn += vnew[n_, d, w] * nr
                            gap += (x[n_, d, w] - wall_point[wl, d, q]) * nr
                            dist += (x[n_, d, w] + dt_b[w] * vnew[n_, d, w] - wall_point[wl, d, q]) * nr
                        dvn = wall_jump(vn, gap, dist, dt_b[w])
                        we = 0.0
                        for d in range(D):
                            jmp = dvn * wall_normal[wl, d, q] * free[n_, d]
                            vnew[n_, d, w] = vnew[n_, d, w] + jmp
                            we += v[n_, d, w] * (jmp + jump_prev[wl, n_, d, w])
                            jump_prev[wl, n_, d, w] = jmp
                        if act[w]:
                            wall_e[w] += -0.5 * m_b[n_, w] * we
                        wforce[wl, w] += wall_force(m_b[n_, w], dvn, dt_b[w])

            # energies (sums over nodes/springs with the variant loop innermost)
            if fused:
                pass  # kinetic energy summed above; no external work
            elif n == 0:
                for w in range(B):
                    ke[w] = ke0[w]
            else:
                for w in range(B):
                    ke[w] = 0.0
                    bal[w] = 0.0
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            ke[w] += 0.5 * m_b[n_, w] * v[n_, d, w] * vnew[n_, d, w]
                if not no_ext:
                    for n_ in range(N):
                        for d in range(D):
                            for w in range(B):
                                vb = 0.5 * (v0[n_, d, lo + w] + v[n_, d, w]) if n == 1 else v[n_, d, w]
                                bal[w] = ext_power(bal[w], fext[n_, d, w], v[n_, d, w], fext_prev[n_, d, w], vb)
                    for w in range(B):
                        work[w] = work_increment(work[w], bal[w], dt_b[w], actf[w])
            nbad = 0
            for w in range(B):
                wmax[w] = max(wmax[w], abs(work[w]))
                b_ = abs(ke[w] + ie_tot[w] + wall_e[w] - ke0[w] - work[w])
                bal[w] = b_
                err[w] = peak(err[w], b_ * actf[w])
                nbad += act[w] & ~(b_ <= UNSTABLE_ENERGY * (ke0[w] + wmax[w]) + e_floor[lo + w])
            anybad = nbad > 0
            # peak |a|: the square is tracked (sqrt is monotonic, so the peak is the same number)
            for n_ in range(N):
                if fused or not movable[n_]:
                    continue
                for w in range(B):
                    a2 = 0.0
                    for d in range(D):
                        a2 += acc[n_, d, w] * acc[n_, d, w]
                    pacc[n_, w] = peak(pacc[n_, w], a2 * actf[w])
            if any_hit:  # |a| at the knot crossings of this step (see reference)
                for s in range(S):
                    if not k_any[s]:
                        continue
                    for side in range(2):
                        p = si[s] if side == 0 else sj[s]
                        if not movable[p]:
                            continue
                        for w in range(B):
                            th = k_th[s, w]
                            a2 = 0.0
                            for d in range(D):
                                ai = knot_accel(acc_prev[p, d, w], acc[p, d, w], th, k_dfax[s, d, w], im_b[p, d, w], side)
                                a2 += ai * ai
                            pacc[p, w] = peak(pacc[p, w], (a2 if k_hit[s, w] else 0.0) * actf[w])
            for wl in range(W):
                for w in range(B):
                    pwall[wl, w] = peak(pwall[wl, w], wforce[wl, w] * actf[w])
            if D > 1:
                for w in range(B):
                    anybad = anybad or (act[w] and crushed[w] >= 0)
            if anybad:
                for w in range(B):
                    if not act[w]:
                        continue
                    if not (bal[w] <= UNSTABLE_ENERGY * (ke0[w] + wmax[w]) + e_floor[lo + w]):
                        st_ok[w] = UNSTABLE
                        fail_time[lo + w] = n * dt_b[w]
                        n_fail[w] = n
                        act[w] = False
                        actf[w] = 0.0
                    elif D > 1 and crushed[w] >= 0:
                        st_ok[w] = CRUSHED_TO_ZERO
                        fail_item[lo + w] = crushed[w]
                        fail_time[lo + w] = n * dt_b[w]
                        n_fail[w] = n
                        act[w] = False
                        actf[w] = 0.0
            if any_hist:
                for w in range(B):
                    q = lo + w
                    if not (act[w] and n == next_rec[w]):
                        continue
                    r = n // out_every[q]
                    next_rec[w] = n + out_every[q]
                    if r >= n_out:  # the last step may pass the last sample time
                        continue
                    for n_ in range(N):
                        for d in range(D):
                            if rec_mask[0]:
                                h_pos[r, n_, d, q] = x[n_, d, w]
                            if rec_mask[1]:
                                h_disp[r, n_, d, q] = x[n_, d, w] - x0_b[n_, d, w]
                            if rec_mask[2]:
                                h_vel[r, n_, d, q] = 0.5 * (v[n_, d, w] + vnew[n_, d, w]) if n > 0 else v[n_, d, w]
                            if rec_mask[3]:
                                h_acc[r, n_, d, q] = acc[n_, d, w]
                    for s in range(S):
                        if rec_mask[4]:
                            h_force[r, s, q] = forces[s, w]
                        if rec_mask[5]:
                            h_elong[r, s, q] = elong[s, w]
                    if rec_mask[6]:
                        h_energy[r, 0, q] = ke[w]
                        h_energy[r, 1, q] = ie_tot[w]
                        h_energy[r, 2, q] = work[w]
                        h_energy[r, 3, q] = wall_e[w]
                    for wl in range(W):
                        if rec_mask[10]:
                            h_wall[r, wl, q] = wforce[wl, w]
            if has_term and n > 0:
                for w in range(B):
                    q = lo + w
                    t = n * dt_b[w]
                    if not act[w] or ke_fraction[q] <= 0.0 or t < min_time[q]:
                        continue
                    fsum = 0.0
                    psum = 0.0
                    for s in range(S):
                        fsum += abs(forces[s, w])
                        psum += pf[s, w]
                    small_f = fsum <= ke_fraction[q] * psum
                    small_ke = ke[w] <= ke_fraction[q] * (ke0[w] + wmax[w])
                    opening = edot_min[w] >= 0.0 and no_ext
                    if small_f and (small_ke or opening):
                        nst[w] = n
                        n_end = n
            for w in range(B):
                if n != n_end:
                    break
                if act[w] and n == nst[w]:
                    q = lo + w
                    final_energy[0, q] = ke[w]
                    final_energy[1, q] = ie_tot[w]
                    final_energy[2, q] = work[w]
                    final_energy[3, q] = wall_e[w]
            for n_ in range(N):
                if fused:
                    break
                for d in range(D):
                    for w in range(B):
                        af = actf[w]  # a stopped variant keeps x and v (vnew is finite for it)
                        x[n_, d, w] = x[n_, d, w] + (dt_b[w] * af) * vnew[n_, d, w]
                        v[n_, d, w] = vnew[n_, d, w] * af + v[n_, d, w] * (1.0 - af)
            if not no_ext:
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            fext_prev[n_, d, w] = fext[n_, d, w]
        for w in range(B):
            q = lo + w
            status[q] = st_ok[w]
            energy_error[q] = err[w] / max(ke0[w] + wmax[w], 1e-300)
            if st_ok[w] == 0:
                t_end[q] = nst[w] * dt_b[w]
            elif n_fail[w] > 0:
                t_end[q] = (n_fail[w] - 1) * dt_b[w]
        for s in range(S):
            for w in range(B):
                absorbed[s, lo + w] = ie[s, w]
                peak_force[s, lo + w] = pf[s, w]
                max_crush[s, lo + w] = mc[s, w]
        for n_ in range(N):
            for w in range(B):
                peak_acc[n_, lo + w] = np.sqrt(pacc[n_, w])
        for wl in range(W):
            for w in range(B):
                peak_wall[wl, lo + w] = pwall[wl, w]


def run_compiled(b: Batch, histories: tuple[str, ...], n_out: int, block: int = BLOCK) -> KernelOutput:
    """Integrate every variant of ``b`` with the compiled kernel (same results as the reference)."""
    out, hist, summ = outputs(b, histories, n_out)
    topo, var = records(b)
    run_blocks(_run, block_starts(b.x0.shape[2], block), n_out, topo, var, hist, summ)
    return finish(out, hist)
