"""The compiled (numba) kernel: the reference step of :mod:`crashstudy.kernel.reference`, with the
loop over variants innermost.

Blocks of at most ``BLOCK`` variants run in parallel on a thread pool (the function releases the GIL;
``parallel=True`` took minutes to compile); each advances all its variants together, innermost loops
over contiguous variant columns (SIMD). Every variant keeps its own ``dt``: its result does not
depend on its block. What a model does not contain is skipped: no material state without
``general_nonlinear``/``crush``, no geometry in 1-D, no wall, load, motion or history loops when none.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from crashstudy.kernel import generic_block as gb
from crashstudy.kernel import laws as lw
from crashstudy.kernel import wall_contact as wc
from crashstudy.kernel.driver import (
    block_starts,
    finish,
    get_threads,
    outputs,
    records,
    run_blocks,
    set_threads,
)
from crashstudy.kernel.generic_block import BREAKABLE, PRELOADED
from crashstudy.kernel.output import KernelOutput
from crashstudy.vocabulary.codes import (
    CRUSH,
    DAMPER,
    ELASTOPLASTIC,
    GENERAL,
    LINEAR,
    NONLINEAR,
    NONLINEAR_DAMPER,
    RATE_ELASTIC,
)
from crashstudy.vocabulary.materials import DAMPER_MATERIALS, RATE_MATERIALS

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

BLOCK = 256
__all__ = ["BLOCK", "get_threads", "run_compiled", "set_threads"]


@nb.njit(cache=True, nogil=True)
def _run(b_lo, b_hi, starts, n_out, T, P, H, Out):  # pragma: no cover - compiled
    """Blocks ``b_lo:b_hi`` (records of :mod:`crashstudy.kernel.driver`: T topology, P per-variant inputs,
    H histories, Out summaries); every per-variant formula is a law of :mod:`crashstudy.kernel.laws`."""
    si, sj, material, curve_a, curve_b, off = T.spring_i, T.spring_j, T.material, T.curve_a, T.curve_b, T.curve_off
    free, load_node, load_curve, pm_node, pm_dir, pm_kind = T.free, T.load_node, T.load_curve, T.pm_node, T.pm_dir, T.pm_kind
    pm_curve, wall_nodes, knot_check, x0, v0, cx = T.pm_curve, T.wall_nodes, T.knot_check, P.x0, P.v0, P.cx
    cy, cds, cs0, cs1, gravity, load_force = P.cy, P.cds, P.cs0, P.cs1, P.gravity, P.load_force
    pm_scale, wall_point, wall_normal, out_every, ke_fraction, min_time = P.pm_scale, P.wall_point, P.wall_normal, P.out_every, P.ke_fraction, P.min_time
    e_floor, final_energy, e0, rate0, sft = P.energy_floor, Out.final_energy, P.e0, P.rate0, Out.spring_fail_time
    N = x0.shape[0]
    D = x0.shape[1]
    S = si.shape[0]
    W = wall_nodes.shape[0]
    NL = load_node.shape[0]
    NP = pm_node.shape[0]
    has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot, pm_disp = gb.flags(T, P, H)
    # 1-D models without walls, prescribed motion or external forces take a fused node update
    fused_1d = D == 1 and W == 0 and NP == 0 and no_ext
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        (m_b, im_b, x0_b, sg_b, l0_b, kp_b, cx_b, cy_b, ds_b, ky_b, s0_b, yt_b, yc_b, g_arg, g_argt, g_argc, g_L,
         g_Ut, g_Uc, g_rev, dt_b, x, v, vnew, f, fext, fext_prev, acc, acc_prev, k_sh, k_c, k_x, k_y, k_any, k_hit,
         k_th, k_dfax, jump_prev, pm_acc, axis_prev, state, forces, elong, f_prev, e_prev, ie, pf, mc, pacc, pwall,
         e_tmp, ed_tmp, F_tmp, ax_tmp, edot_min, crushed, work, wall_e, wmax, ke0, ke, ie_tot, err, bal, wforce, act,
         actf, n_fail, nst, next_rec, st_ok, me, broken, options, ftmp, e_init, nmax) = gb.block_arrays(
            lo, B, has_state, any_knot, T, P, Out)
        pen_e = np.zeros((W, N, B))  # stored energy of each node at each penalty wall
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
                        e_tmp[w] = lw.elongation_1d(sg, x[j, 0, w] - x0_b[j, 0, w], x[i, 0, w] - x0_b[i, 0, w])
                        ax_tmp[0, w] = sg
                    if kind in RATE_MATERIALS or has_term:
                        for w in range(B):
                            vpj = lw.end_rate(v[j, 0, w], 0.0 if pm_disp[j, 0] else acc[j, 0, w], dt_b[w])
                            vpi = lw.end_rate(v[i, 0, w], 0.0 if pm_disp[i, 0] else acc[i, 0, w], dt_b[w])
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
                        gone = lw.collapsed(ln, l0_b[s, w], turn)
                        if gone and crushed[w] < 0 and not broken[s, w]:  # a broken spring may collapse
                            crushed[w] = s
                        dn = 1.0 if gone else ln
                        edot = 0.0
                        for d in range(D):
                            ax_tmp[d, w] = ax_tmp[d, w] / dn
                            vpj = lw.end_rate(v[j, d, w], 0.0 if pm_disp[j, d] else acc[j, d, w], dt_b[w])
                            vpi = lw.end_rate(v[i, d, w], 0.0 if pm_disp[i, d] else acc[i, d, w], dt_b[w])
                            edot += ax_tmp[d, w] * (vpj - vpi)
                        e_tmp[w] = lw.elongation_2d(ln, l0_b[s, w])
                        ed_tmp[w] = edot
                if options[PRELOADED, s]:  # e = e0 + ... (initial_elongation)
                    for w in range(B):
                        e_tmp[w] = e0[s, lo + w] + e_tmp[w]
                nhit = 0
                if kn:  # did any lane pass over a flagged knot since the previous step? (cheap: no stores)
                    ca = curve_a[s]
                    for k in range(off[ca] + 1, off[ca + 1] - 1):
                        if not knot_check[k]:
                            continue
                        if kind == CRUSH:
                            for w in range(B):
                                lo_, hi_, _ = lw.crush_window(e_tmp[w], state[s, 0, w])
                                nhit += lw.knot_inside(cx_b[k, w], lo_, hi_)
                        elif kind == GENERAL:
                            for w in range(B):
                                lo_, hi_, _ = lw.general_window(e_prev[s, w], e_tmp[w], state[s, 0, w], state[s, 1, w],
                                                             state[s, 3, w], state[s, 5, w])  # fmt: skip
                                nhit += lw.knot_inside(cx_b[k, w], lo_, hi_)
                        else:
                            for w in range(B):
                                lo_, hi_, _ = lw.nonlinear_window(e_prev[s, w], e_tmp[w])
                                nhit += lw.knot_inside(cx_b[k, w], lo_, hi_)
                if nhit > 0:  # rare: the knots passed over, lane by lane (the state is still the one before the step)
                    nhit = gb.knot_search(s, kind, B, off, curve_a[s], knot_check, cx_b, ky_b, e_tmp, e_prev, state,
                                          k_c, k_x, k_y, k_sh)  # fmt: skip
                if kind == LINEAR:
                    for w in range(B):
                        F_tmp[w] = lw.linear_force(kp_b[s, w], e_tmp[w])
                elif kind == DAMPER:
                    for w in range(B):
                        F_tmp[w] = lw.damper_force(kp_b[s, w], ed_tmp[w])
                elif kind == NONLINEAR:
                    gb.ramp(curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
                    for w in range(B):
                        F_tmp[w] = lw.nonlinear_force(F_tmp[w])
                elif kind == CRUSH:
                    gb.ramp(curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
                    for w in range(B):
                        F_tmp[w], state[s, 0, w], state[s, 1, w] = lw.crush_law(e_tmp[w], state[s, 0, w], state[s, 1, w],
                                                                             F_tmp[w], kp_b[s, w])  # fmt: skip
                elif kind == ELASTOPLASTIC:
                    for w in range(B):
                        F_tmp[w], state[s, 0, w], state[s, 1, w] = lw.elastoplastic_law(
                            e_tmp[w], state[s, 0, w], state[s, 1, w], kp_b[s, w], P.ktan[s, lo + w], P.fy[s, lo + w])
                elif kind == NONLINEAR_DAMPER:
                    gb.ramp(curve_a[s], ed_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
                elif kind == RATE_ELASTIC:  # its first curve, then each neighbouring pair folded in by the rate
                    r_a, r_z = T.rate_off[s], T.rate_off[s + 1]
                    gb.ramp(T.rate_curve[r_a], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
                    for k in range(r_a, r_z - 1):
                        gb.ramp(T.rate_curve[k], e_tmp, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
                        gb.ramp(T.rate_curve[k + 1], e_tmp, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
                        for w in range(B):
                            F_tmp[w] = lw.rate_segment(F_tmp[w], abs(ed_tmp[w]), P.rate_at[k, lo + w],
                                                       P.rate_at[k + 1, lo + w], g_L[w], g_Ut[w])  # fmt: skip
                else:  # GENERAL: rules 1-4 of docs/format.md, branch-free over the block; reversals (rare) per lane
                    ca = curve_a[s]
                    cb = curve_b[s]
                    for w in range(B):
                        g_arg[w] = e_tmp[w] - state[s, 5, w]
                        g_argt[w] = e_tmp[w] - state[s, 1, w]
                        g_argc[w] = e_tmp[w] - state[s, 3, w]
                    gb.ramp(ca, g_arg, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
                    gb.ramp(cb, g_argt, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
                    gb.ramp(cb, g_argc, g_Uc, off, cx_b, cy_b, ds_b, s0_b, B)
                    nrev = 0
                    for w in range(B):
                        (F_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w], state[s, 4, w],
                         state[s, 6, w], state[s, 7, w], rev) = lw.general_law(
                            e_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w], state[s, 4, w],
                            state[s, 6, w], state[s, 7, w], g_L[w], g_Ut[w], g_Uc[w], yt_b[s, w], yc_b[s, w])
                        g_rev[w] = rev
                        nrev += rev
                    if nrev > 0:
                        for w in range(B):
                            if g_rev[w]:
                                (F_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w], state[s, 4, w],
                                 state[s, 5, w], state[s, 6, w], state[s, 7, w]) = lw.general_reverse(
                                    e_tmp[w], state[s, 0, w], state[s, 1, w], state[s, 2, w], state[s, 3, w],
                                    state[s, 4, w], state[s, 6, w], state[s, 7, w], yt_b[s, w], yc_b[s, w], ca, cb,
                                    lo + w, cx, cy, cds, cs0, cs1, off)
                if options[BREAKABLE, s]:
                    gb.failure(s, n, lo, B, P.fail_t, P.fail_c, dt_b, e_tmp, e_prev, F_tmp, act, actf, broken, ftmp, sft)
                if kn:
                    k_any[s] = nhit > 0
                if nhit > 0:  # rare: peak-force candidate and the deceleration data (see reference)
                    any_hit = True
                    for w in range(B):
                        kcw = k_c[w]
                        th, dF = lw.knot_crossing(kcw, k_x[w], k_y[w], e_prev[s, w], e_tmp[w], k_sh[w], f_prev[s, w],
                                               F_tmp[w])  # fmt: skip
                        kcw = 0.0 if broken[s, w] else kcw  # a spring that breaks in this step: the step's ends only
                        k_hit[s, w] = kcw > 0.0
                        k_th[s, w] = th
                        for d in range(D):
                            k_dfax[s, d, w] = dF * ax_tmp[d, w]
                        pf[s, w] = lw.peak(pf[s, w], kcw * actf[w])
                # masked by arithmetic: a stopped variant adds 0 and compares against 0 (peaks are >= 0)
                fh = options[PRELOADED, s] and kind not in DAMPER_MATERIALS
                if options[BREAKABLE, s] or (n == 1 and fh):  # a breakable spring, or a preloaded spring's first step
                    gb.option_scatter(s, i, j, n, fh, lo, D, B, e0, rate0, dt_b, F_tmp, e_tmp, ax_tmp, actf, ftmp,
                                      options[BREAKABLE, s], f, ie, ie_tot, pf, mc, me, forces, elong, f_prev,
                                      e_prev)  # fmt: skip
                elif D == 1 and n > 0:  # one pass: scatter and summaries
                    for w in range(B):
                        F = F_tmp[w]
                        e = e_tmp[w]
                        af = actf[w]
                        fa = F * ax_tmp[0, w]
                        f[i, 0, w] += fa
                        f[j, 0, w] -= fa
                        ie[s, w] = lw.energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
                        ie_tot[w] += ie[s, w]
                        pf[s, w] = lw.peak(pf[s, w], abs(F) * af)
                        mc[s, w] = lw.peak(mc[s, w], -e * af)
                        me[s, w] = lw.peak(me[s, w], e * af)
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
                            ie[s, w] = lw.energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
                        ie_tot[w] += ie[s, w]
                        pf[s, w] = lw.peak(pf[s, w], abs(F) * af)
                        mc[s, w] = lw.peak(mc[s, w], -e * af)
                        me[s, w] = lw.peak(me[s, w], e * af)
                        forces[s, w] = F
                        elong[s, w] = e
                        f_prev[s, w] = F
                        e_prev[s, w] = e
                if has_term:
                    for w in range(B):
                        edot_min[w] = lw.least(edot_min[w], ed_tmp[w])

            if any_hit:  # a^{n-1}, for the accelerations at this step's knot crossings
                for n_ in range(N):
                    for d in range(D):
                        for w in range(B):
                            acc_prev[n_, d, w] = acc[n_, d, w]
            if W > 0:  # penalty walls' forces (kernel.wall_contact)
                wc.penalty(lo, B, W, N, D, wall_nodes, wall_normal, wall_point, P.wall_stiffness, x, f, wforce, wall_e,
                           pen_e, act)  # fmt: skip
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
                            pacc[n_, w] = lw.peak(pacc[n_, w], (a * a) * af)
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
                        scale = lw.time_curve_at(c, n * dt_b[w], q, cx, cy, cds, cs0, off) if c >= 0 else 1.0
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
                    kind = pm_kind[k]
                    tc = lw.time_curve_at(c, lw.prescribed_time(kind, t, dt_b[w]), q, cx, cy, cds, cs0, off)
                    vn = lw.prescribed_velocity(kind, x0_b[p, d, w], pm_scale[k, q], tc, x[p, d, w], v[p, d, w], dt_b[w],
                                                dtn)  # fmt: skip
                    vnew[p, d, w], pm_acc[k, w] = lw.prescribed_step(n == nst[w], vn, v[p, d, w], pm_acc[k, w], dtn)
                    acc[p, d, w] = pm_acc[k, w]
                    ftot = f[p, d, w] + fext[p, d, w]
                    fext[p, d, w] += m_b[p, w] * acc[p, d, w] - ftot
            if W > 0:  # rigid walls (kernel.wall_contact)
                wc.rigid(lo, B, W, N, D, h, wall_nodes, wall_normal, wall_point, P.wall_stiffness, free, x, v, vnew,
                         acc, m_b, dt_b, jump_prev, wall_e, wforce, Out.wall_impulse, act, actf)  # fmt: skip

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
                                bal[w] = lw.ext_power(bal[w], fext[n_, d, w], v[n_, d, w], fext_prev[n_, d, w], vb)
                    for w in range(B):
                        work[w] = lw.work_increment(work[w], bal[w], dt_b[w], actf[w])
            nbad = 0
            for w in range(B):
                wmax[w] = max(wmax[w], abs(work[w]))
                b_ = lw.energy_balance(ke[w], ie_tot[w], wall_e[w] if n > 0 else 0.0, e_init[0, w], work[w])  # t = 0: before impacts
                bal[w] = b_
                err[w] = lw.peak(err[w], b_ * actf[w])
                nbad += act[w] & lw.unstable(b_, lw.unstable_limit(e_init[1, w], wmax[w], e_floor[lo + w]))
            anybad = nbad > 0
            # peak |a|: the square is tracked (sqrt is monotonic, so the peak is the same number)
            for n_ in range(N):
                if fused or not movable[n_]:
                    continue
                for w in range(B):
                    a2 = 0.0
                    for d in range(D):
                        a2 += acc[n_, d, w] * acc[n_, d, w]
                    pacc[n_, w] = lw.peak(pacc[n_, w], a2 * actf[w])
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
                                ai = lw.knot_accel(acc_prev[p, d, w], acc[p, d, w], th, k_dfax[s, d, w], im_b[p, d, w], side)
                                a2 += ai * ai
                            pacc[p, w] = lw.peak(pacc[p, w], (a2 if k_hit[s, w] else 0.0) * actf[w])
            for wl in range(W):
                for w in range(B):
                    pwall[wl, w] = lw.peak(pwall[wl, w], wforce[wl, w] * actf[w])
            if D > 1:
                for w in range(B):
                    anybad = anybad or (act[w] and crushed[w] >= 0)
            if anybad:  # rare: lanes that fail at this step stop
                gb.fail_lanes(n, lo, B, D, act, actf, bal, e_init[1], wmax, e_floor, crushed, st_ok, n_fail, dt_b, Out)
            if any_hist:
                gb.record(n, lo, B, n_out, act, next_rec, out_every, x, x0_b, v, vnew, acc, forces, elong, ke, ie_tot,
                          work, wall_e, wforce, H)  # fmt: skip
            if H.step_nodes.shape[0] > 0:  # crash criteria: a^n of the recorded nodes added to their block's row
                gb.record_steps(n, lo, B, act, acc, P.rec_block, H.step_nodes, H.steps)
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
                    opening = edot_min[w] >= 0.0 and no_ext
                    if lw.stop_test(ke_fraction[q], fsum, psum, ke[w], e_init[1, w], wmax[w], opening):
                        nst[w] = n
                        n_end = n
            if n == n_end:
                gb.final_energies(n, lo, B, act, nst, ke, ie_tot, work, wall_e, final_energy)
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
        gb.results(lo, B, st_ok, err, e_init[1], wmax, nst, n_fail, dt_b, ie, pf, mc, me, pacc, pwall, Out)


def run_compiled(b: Batch, histories: tuple[str, ...], n_out: int, block: int = BLOCK,
                 record: tuple[int, ...] = ()) -> KernelOutput:  # fmt: skip
    """Integrate every variant of ``b`` with the compiled kernel (same results as the reference);
    ``record``: nodes whose acceleration is kept at every step (``step_acceleration``)."""
    out, hist, summ = outputs(b, histories, n_out, record)
    topo, var = records(b)
    run_blocks(_run, block_starts(b.x0.shape[2], block), n_out, topo, var, hist, summ)
    return finish(out, hist)
