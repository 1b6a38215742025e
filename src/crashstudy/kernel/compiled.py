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
from crashstudy.kernel import generic_nodes as gn
from crashstudy.kernel import generic_outputs as go
from crashstudy.kernel import generic_springs as gs
from crashstudy.kernel import laws as lw
from crashstudy.kernel import step_laws as sl
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


@nb.njit(cache=True, nogil=True, inline="always")
def _force(s, kind, lo, B, T, P, K):  # pragma: no cover - compiled
    """Spring s's force over the block (F_tmp) and its new state: the material dispatch (one branch per
    material of :mod:`crashstudy.vocabulary.materials`, each the law of :mod:`crashstudy.kernel.laws`)."""
    off, cx_b, cy_b, ds_b, s0_b, kp_b, yt_b, yc_b = T.curve_off, K.cx_b, K.cy_b, K.ds_b, K.s0_b, K.kp_b, K.yt_b, K.yc_b
    e_tmp, ed_tmp, F_tmp, state, g_arg, g_argt, g_argc = K.e_tmp, K.ed_tmp, K.F_tmp, K.state, K.g_arg, K.g_argt, K.g_argc
    g_L, g_Ut, g_Uc, g_rev = K.g_L, K.g_Ut, K.g_Uc, K.g_rev
    if kind == LINEAR:
        for w in range(B):
            F_tmp[w] = lw.linear_force(kp_b[s, w], e_tmp[w])
    elif kind == DAMPER:
        for w in range(B):
            F_tmp[w] = lw.damper_force(kp_b[s, w], ed_tmp[w])
    elif kind == NONLINEAR:
        gs.ramp(T.curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for w in range(B):
            F_tmp[w] = lw.nonlinear_force(F_tmp[w])
    elif kind == CRUSH:
        gs.ramp(T.curve_a[s], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for w in range(B):
            F_tmp[w], state[s, 0, w], state[s, 1, w] = lw.crush_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], F_tmp[w], kp_b[s, w])
    elif kind == ELASTOPLASTIC:
        for w in range(B):
            F_tmp[w], state[s, 0, w], state[s, 1, w] = lw.elastoplastic_law(
                e_tmp[w], state[s, 0, w], state[s, 1, w], kp_b[s, w], P.ktan[s, lo + w], P.fy[s, lo + w])
    elif kind == NONLINEAR_DAMPER:
        gs.ramp(T.curve_a[s], ed_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
    elif kind == RATE_ELASTIC:  # its first curve, then each neighbouring pair folded in by the rate
        r_a, r_z = T.rate_off[s], T.rate_off[s + 1]
        gs.ramp(T.rate_curve[r_a], e_tmp, F_tmp, off, cx_b, cy_b, ds_b, s0_b, B)
        for k in range(r_a, r_z - 1):
            gs.ramp(T.rate_curve[k], e_tmp, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
            gs.ramp(T.rate_curve[k + 1], e_tmp, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
            for w in range(B):
                F_tmp[w] = lw.rate_segment(
                    F_tmp[w], abs(ed_tmp[w]), P.rate_at[k, lo + w], P.rate_at[k + 1, lo + w], g_L[w], g_Ut[w])
    else:  # GENERAL: rules 1-4 of docs/format.md, branch-free over the block; reversals (rare) per lane
        ca = T.curve_a[s]
        cb = T.curve_b[s]
        for w in range(B):
            g_arg[w] = e_tmp[w] - state[s, 5, w]
            g_argt[w] = e_tmp[w] - state[s, 1, w]
            g_argc[w] = e_tmp[w] - state[s, 3, w]
        gs.ramp(ca, g_arg, g_L, off, cx_b, cy_b, ds_b, s0_b, B)
        gs.ramp(cb, g_argt, g_Ut, off, cx_b, cy_b, ds_b, s0_b, B)
        gs.ramp(cb, g_argc, g_Uc, off, cx_b, cy_b, ds_b, s0_b, B)
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
                        lo + w, P.cx, P.cy, P.cds, P.cs0, P.cs1, off)


@nb.njit(cache=True, nogil=True)
def _run(b_lo, b_hi, starts, n_out, T, P, H, Out):  # pragma: no cover - compiled
    """Blocks ``b_lo:b_hi`` (records of :mod:`crashstudy.kernel.driver`: T topology, P per-variant inputs,
    H histories, Out summaries): the step loop over a block's arrays ``K`` (:data:`generic_block.Block`);
    its stages are :mod:`crashstudy.kernel.generic_springs`, :mod:`crashstudy.kernel.generic_nodes` and
    :mod:`crashstudy.kernel.wall_contact`."""
    si, sj, material, off, e0, rate0 = T.spring_i, T.spring_j, T.material, T.curve_off, P.e0, P.rate0
    N, D, _ = P.x0.shape
    S = si.shape[0]
    W = T.wall_nodes.shape[0]
    NP = T.pm_node.shape[0]
    has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot, pm_disp = gb.flags(T, P, H)
    # 1-D models without walls, prescribed motion or external forces take a fused node update
    fused_1d = D == 1 and W == 0 and NP == 0 and no_ext
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        K, nmax = gb.block_arrays(lo, B, has_state, any_knot, T, P, Out)
        x, v, vnew, f, acc, act, actf, nst, st_ok = K.x, K.v, K.vnew, K.f, K.acc, K.act, K.actf, K.nst, K.st_ok
        ke, ie_tot, work, wall_e, wmax, wforce, bal = K.ke, K.ie_tot, K.work, K.wall_e, K.wmax, K.wforce, K.bal
        e_init, dt_b, crushed, m_b, options = K.e_init, K.dt_b, K.crushed, K.m_b, K.options
        wp, wn, wk, jp, imp = P.wall_point, P.wall_normal, P.wall_stiffness, K.jump_prev, Out.wall_impulse
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
                    rec_now = rec_now or (act[w] and n == K.next_rec[w])
            fused = fused_1d and n > 0 and not rec_now
            h = 1.0 if n > 0 else 0.5
            f[:] = 0.0
            crushed[:] = -1
            K.edot_min[:] = np.inf
            ie_tot[:] = 0.0
            any_hit = False
            for s in range(S):  # springs: elongation, force, failure, knots, scatter and summaries
                i = si[s]
                j = sj[s]
                kind = material[s]
                kn = knotted[s] and n > 0
                gs.geometry(s, i, j, D, B, kind in RATE_MATERIALS or has_term, pm_disp, K)
                if options[PRELOADED, s]:  # e = e0 + ... (initial_elongation)
                    for w in range(B):
                        K.e_tmp[w] = e0[s, lo + w] + K.e_tmp[w]
                nhit = gs.knots_passed(s, kind, B, off, T.curve_a[s], T.knot_check, K) if kn else 0
                _force(s, kind, lo, B, T, P, K)
                fr = options[BREAKABLE, s]
                if fr:
                    gs.failure(s, n, lo, B, P.fail_t, P.fail_c, Out.spring_fail_time, K)
                if kn:
                    K.k_any[s] = nhit > 0
                if nhit > 0:  # rare: peak-force candidate and the deceleration data (see reference)
                    any_hit = True
                    gs.knot_peaks(s, B, D, K)
                # masked by arithmetic: a stopped variant adds 0 and compares against 0 (peaks are >= 0)
                fh = options[PRELOADED, s] and kind not in DAMPER_MATERIALS
                gs.scatter(s, i, j, n, fh, fr, lo, D, B, e0, rate0, K)
                if has_term:
                    for w in range(B):
                        K.edot_min[w] = lw.least(K.edot_min[w], K.ed_tmp[w])

            if any_hit:  # a^{n-1}, for the accelerations at this step's knot crossings
                K.acc_prev[:] = acc
            if W > 0:  # penalty walls' forces (kernel.wall_contact)
                wc.penalty(lo, B, W, N, D, T.wall_nodes, wn, wp, wk, x, f, wforce, wall_e, pen_e, act)
            if fused:  # external forces, accelerations, velocities
                gn.fused_update(h, B, N, movable, K)
            else:
                gn.accelerate(n, h, lo, B, N, D, not no_ext, has_gravity, T, P, K)
            if NP > 0:
                gn.prescribed(n, h, lo, B, T, P, K)
            if W > 0:  # rigid walls (kernel.wall_contact)
                wc.rigid(lo, B, W, N, D, h, T.wall_nodes, wn, wp, wk, T.free, x, v, vnew, acc, m_b, dt_b, jp, wall_e,
                         wforce, imp, act, actf)
            if not fused:  # (fused: kinetic energy summed above; no external work)
                gn.energies(n, lo, B, N, D, not no_ext, P.v0, K)
            nbad = 0
            for w in range(B):
                wmax[w] = max(wmax[w], abs(work[w]))
                b_ = sl.energy_balance(ke[w], ie_tot[w], wall_e[w] if n > 0 else 0.0, e_init[0, w], work[w])
                bal[w] = b_  # t = 0: before impacts
                K.err[w] = lw.peak(K.err[w], b_ * actf[w])
                nbad += act[w] & sl.unstable(b_, sl.unstable_limit(e_init[1, w], wmax[w], P.energy_floor[lo + w]))
            anybad = nbad > 0
            if not fused:
                gn.peak_accelerations(B, N, D, movable, K)
            if any_hit:
                gn.knot_accelerations(B, D, si, sj, movable, K)
            for wl in range(W):
                for w in range(B):
                    K.pwall[wl, w] = lw.peak(K.pwall[wl, w], wforce[wl, w] * actf[w])
            if D > 1:
                for w in range(B):
                    anybad = anybad or (act[w] and crushed[w] >= 0)
            if anybad:  # rare: lanes that fail at this step stop
                gb.fail_lanes(n, lo, B, D, P.energy_floor, Out, K)
            if rec_now:
                go.record(n, lo, B, n_out, P.out_every, H, K)
            if H.step_nodes.shape[0] > 0:  # crash criteria: a^n of the recorded nodes added to their block's row
                go.record_steps(n, lo, B, act, acc, P.rec_block, H.step_nodes, H.steps)
            if has_term and n > 0:
                n_end = gn.stop_tests(n, lo, B, S, no_ext, P, K, n_end)
            if n == n_end:
                go.final_energies(n, lo, B, act, nst, ke, ie_tot, work, wall_e, Out.final_energy)
            if not fused:
                gn.advance_nodes(B, N, D, K)
            if not no_ext:
                K.fext_prev[:] = K.fext
        go.results(lo, B, Out, K)


def run_compiled(b: Batch, histories: tuple[str, ...], n_out: int, block: int = BLOCK,
                 record: tuple[int, ...] = ()) -> KernelOutput:  # fmt: skip
    """Integrate every variant of ``b`` with the compiled kernel (same results as the reference);
    ``record``: nodes whose acceleration is kept at every step (``step_acceleration``)."""
    out, hist, summ = outputs(b, histories, n_out, record)
    topo, var = records(b)
    run_blocks(_run, block_starts(b.x0.shape[2], block), n_out, topo, var, hist, summ)
    return finish(out, hist)
