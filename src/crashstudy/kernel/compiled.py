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
from crashstudy.kernel import generic_force as gf
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
from crashstudy.vocabulary.codes import GENERAL
from crashstudy.vocabulary.materials import DAMPER_MATERIALS, RATE_MATERIALS

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

BLOCK = 256
__all__ = ["BLOCK", "get_threads", "run_compiled", "set_threads"]


@nb.njit(cache=True, nogil=True)
def _run(b_lo, b_hi, starts, n_out, T, P, H, Out):  # pragma: no cover - compiled
    """Blocks ``b_lo:b_hi`` (records of :mod:`crashstudy.kernel.driver`: T topology, P per-variant inputs,
    H histories, Out summaries): the step loop over a block's arrays ``K`` (:data:`generic_block.Block`);
    its stages are :mod:`crashstudy.kernel.generic_springs`, :mod:`crashstudy.kernel.generic_nodes` and
    :mod:`crashstudy.kernel.wall_contact`."""
    # the records' arrays as locals, once per call: the stages take arrays, never a record. Read through
    # aliases used in this block only: numba keeps a variable used in several blocks (T, P, K) in a stack
    # slot and reloads the WHOLE record at each attribute read; LLVM's SROA then splits every such load
    # (18 s of the cold compile; benchmarks/results/generic_compile.md)
    t, p = T, P
    si, sj, material, off, e0, rate0 = t.spring_i, t.spring_j, t.material, t.curve_off, p.e0, p.rate0
    curve_a, curve_b, knot_check, rate_off = t.curve_a, t.curve_b, t.knot_check, t.rate_off
    rate_curve, load_node, load_curve, pm_node = t.rate_curve, t.load_node, t.load_curve, t.pm_node
    pm_dir, pm_curve, pm_kind, ktan, fy, rate_at = t.pm_dir, t.pm_curve, t.pm_kind, p.ktan, p.fy, p.rate_at
    cx, cy, cds, cs0, cs1, gravity, load_force = p.cx, p.cy, p.cds, p.cs0, p.cs1, p.gravity, p.load_force
    pm_scale, fail_t, fail_c, v0 = p.pm_scale, p.fail_t, p.fail_c, p.v0
    ke_fraction, min_time, e_floor, rec_block = p.ke_fraction, p.min_time, p.energy_floor, p.rec_block
    wall_nodes, free, step_nodes, steps = t.wall_nodes, t.free, H.step_nodes, H.steps
    wp, wn, wk, out_every, x0 = p.wall_point, p.wall_normal, p.wall_stiffness, p.out_every, p.x0
    imp, sft, final_energy = Out.wall_impulse, Out.spring_fail_time, Out.final_energy
    N, D, _ = x0.shape
    S = si.shape[0]
    W = wall_nodes.shape[0]
    NP = pm_node.shape[0]
    flags = gb.flags(T, P, H)
    has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot, pm_disp = flags
    # 1-D models without walls, prescribed motion or external forces take a fused node update
    fused_1d = D == 1 and W == 0 and NP == 0 and no_ext
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        K, nmax = gb.block_arrays(lo, B, has_state, any_knot, T, P, Out)
        k = K  # (an alias used in this block only: one read of the record, as t and p above)
        # the block's arrays as locals, once per block: the stages take only the arrays they use
        m_b, im_b, x0_b, sg_b, l0_b, kp_b, cx_b = k.m_b, k.im_b, k.x0_b, k.sg_b, k.l0_b, k.kp_b, k.cx_b
        cy_b, ds_b, ky_b, s0_b, yt_b, yc_b, g_arg = k.cy_b, k.ds_b, k.ky_b, k.s0_b, k.yt_b, k.yc_b, k.g_arg
        g_argt, g_argc, g_L, g_Ut, g_Uc, g_rev = k.g_argt, k.g_argc, k.g_L, k.g_Ut, k.g_Uc, k.g_rev
        dt_b, x, v, vnew, f, fext, fext_prev, acc = k.dt_b, k.x, k.v, k.vnew, k.f, k.fext, k.fext_prev, k.acc
        acc_prev, k_sh, k_c, k_x, k_y, k_any = k.acc_prev, k.k_sh, k.k_c, k.k_x, k.k_y, k.k_any
        k_hit, k_th, k_dfax, jump_prev, pm_acc = k.k_hit, k.k_th, k.k_dfax, k.jump_prev, k.pm_acc
        axis_prev, state, forces, elong, f_prev = k.axis_prev, k.state, k.forces, k.elong, k.f_prev
        e_prev, ie, pf, mc, pacc, pwall, e_tmp = k.e_prev, k.ie, k.pf, k.mc, k.pacc, k.pwall, k.e_tmp
        ed_tmp, F_tmp, ax_tmp, edot_min, crushed = k.ed_tmp, k.F_tmp, k.ax_tmp, k.edot_min, k.crushed
        work, wall_e, wmax, ke0, ke, ie_tot, err = k.work, k.wall_e, k.wmax, k.ke0, k.ke, k.ie_tot, k.err
        bal, wforce, act, actf, nst = k.bal, k.wforce, k.act, k.actf, k.nst
        next_rec, st_ok, me, broken, options, ftmp = k.next_rec, k.st_ok, k.me, k.broken, k.options, k.ftmp
        e_init = k.e_init
        jp = jump_prev
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
                crushed[:] = -1
            if has_term:
                edot_min[:] = np.inf
            ie_tot[:] = 0.0
            any_hit = False
            for s in range(S):  # springs: elongation, force, failure, knots, scatter and summaries
                i = si[s]
                j = sj[s]
                kind = material[s]
                kn = knotted[s] and n > 0
                gs.geometry(
                    s,
                    i,
                    j,
                    D,
                    B,
                    kind in RATE_MATERIALS or has_term,
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
                )
                if options[PRELOADED, s]:  # e = e0 + ... (initial_elongation)
                    for w in range(B):
                        e_tmp[w] = e0[s, lo + w] + e_tmp[w]
                nhit = (
                    gs.knots_passed(
                        s,
                        kind,
                        B,
                        off,
                        curve_a[s],
                        knot_check,
                        cx_b,
                        ky_b,
                        e_tmp,
                        e_prev,
                        state,
                        k_c,
                        k_x,
                        k_y,
                        k_sh,
                    )
                    if kn
                    else 0
                )
                if kind == GENERAL:  # the material dispatch (kernel.generic_force)
                    gf.general(
                        s,
                        lo,
                        B,
                        curve_a[s],
                        curve_b[s],
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
                    )
                else:
                    gf.force(
                        s,
                        kind,
                        lo,
                        B,
                        curve_a[s],
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
                    )
                fr = options[BREAKABLE, s]
                if fr:
                    gs.failure(
                        s, n, lo, B, fail_t, fail_c, sft, dt_b, e_tmp, e_prev, F_tmp, act, actf, broken, ftmp
                    )
                if kn:
                    k_any[s] = nhit > 0
                if nhit > 0:  # rare: peak-force candidate and the deceleration data (see reference)
                    any_hit = True
                    gs.knot_peaks(
                        s,
                        B,
                        D,
                        k_c,
                        k_x,
                        k_y,
                        k_sh,
                        e_prev,
                        e_tmp,
                        f_prev,
                        F_tmp,
                        ax_tmp,
                        broken,
                        actf,
                        k_hit,
                        k_th,
                        k_dfax,
                        pf,
                    )
                # masked by arithmetic: a stopped variant adds 0 and compares against 0 (peaks are >= 0)
                fh = options[PRELOADED, s] and kind not in DAMPER_MATERIALS
                gs.scatter(
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
                )
                if has_term:
                    for w in range(B):
                        edot_min[w] = lw.least(edot_min[w], ed_tmp[w])

            if any_hit:  # a^{n-1}, for the accelerations at this step's knot crossings
                gn.keep(acc_prev, acc)
            if W > 0:  # penalty walls' forces (kernel.wall_contact)
                wc.penalty(lo, B, W, N, D, wall_nodes, wn, wp, wk, x, f, wforce, wall_e, pen_e, act)
            if fused:  # external forces, accelerations, velocities
                gn.fused_update(h, B, N, movable, f, im_b, m_b, x, v, vnew, acc, dt_b, actf, ke, pacc)
            else:
                gn.accelerate(
                    n,
                    h,
                    lo,
                    B,
                    N,
                    D,
                    not no_ext,
                    has_gravity,
                    load_node,
                    load_curve,
                    gravity,
                    load_force,
                    cx,
                    cy,
                    cds,
                    cs0,
                    off,
                    m_b,
                    im_b,
                    f,
                    fext,
                    v,
                    vnew,
                    acc,
                    dt_b,
                )
            if NP > 0:
                gn.prescribed(
                    n,
                    h,
                    lo,
                    B,
                    pm_node,
                    pm_dir,
                    pm_curve,
                    pm_kind,
                    pm_scale,
                    cx,
                    cy,
                    cds,
                    cs0,
                    off,
                    x0_b,
                    m_b,
                    x,
                    v,
                    vnew,
                    acc,
                    pm_acc,
                    f,
                    fext,
                    nst,
                    dt_b,
                )
            if W > 0:  # rigid walls (kernel.wall_contact)
                wc.rigid(
                    lo,
                    B,
                    W,
                    N,
                    D,
                    h,
                    wall_nodes,
                    wn,
                    wp,
                    wk,
                    free,
                    x,
                    v,
                    vnew,
                    acc,
                    m_b,
                    dt_b,
                    jp,
                    wall_e,
                    wforce,
                    imp,
                    act,
                    actf,
                )
            if not fused:  # (fused: kinetic energy summed above; no external work)
                gn.energies(
                    n,
                    lo,
                    B,
                    N,
                    D,
                    not no_ext,
                    v0,
                    m_b,
                    v,
                    vnew,
                    fext,
                    fext_prev,
                    dt_b,
                    actf,
                    ke,
                    ke0,
                    bal,
                    work,
                )
            nbad = 0
            for w in range(B):
                wmax[w] = max(wmax[w], abs(work[w]))
                wall_now = wall_e[w] if n > 0 else 0.0  # t = 0: before impacts
                b_ = sl.energy_balance(ke[w], ie_tot[w], wall_now, e_init[0, w], work[w])
                bal[w] = b_
                err[w] = lw.peak(err[w], b_ * actf[w])
                lim = sl.unstable_limit(e_init[1, w], wmax[w], e_floor[lo + w])
                nbad += act[w] & (sl.unstable(b_, lim) or sl.wall_gives(wall_now, lim))
            anybad = nbad > 0
            if not fused:
                gn.peak_accelerations(B, N, D, movable, acc, actf, pacc)
            if any_hit:
                gn.knot_accelerations(
                    B, D, si, sj, movable, k_any, k_hit, k_th, k_dfax, acc_prev, acc, im_b, actf, pacc
                )
            for wl in range(W):
                for w in range(B):
                    pwall[wl, w] = lw.peak(pwall[wl, w], wforce[wl, w] * actf[w])
            if D > 1:
                for w in range(B):
                    anybad = anybad or (act[w] and crushed[w] >= 0)
            # rare: lanes that fail at this step stop (fail_item says which test: codes.UNSTABLE_WALLS)
            if anybad:
                gb.fail_lanes(n, lo, B, D, e_floor, Out, K)
            if rec_now:
                go.record(n, lo, B, n_out, out_every, H, K)
            if (
                step_nodes.shape[0] > 0
            ):  # crash criteria: a^n of the recorded nodes added to their block's row
                go.record_steps(n, lo, B, act, acc, rec_block, step_nodes, steps)
            if has_term and n > 0:
                n_end = gn.stop_tests(
                    n,
                    lo,
                    B,
                    S,
                    no_ext,
                    ke_fraction,
                    min_time,
                    act,
                    dt_b,
                    forces,
                    pf,
                    edot_min,
                    ke,
                    wmax,
                    nst,
                    e_init,
                    n_end,
                )
            if n == n_end:
                go.final_energies(n, lo, B, act, nst, ke, ie_tot, work, wall_e, final_energy)
            if not fused:
                gn.advance_nodes(B, N, D, x, v, vnew, dt_b, actf)
            if not no_ext:
                gn.keep(fext_prev, fext)
        go.results(lo, B, Out, K)


def run_compiled(
    b: Batch, histories: tuple[str, ...], n_out: int, block: int = BLOCK, record: tuple[int, ...] = ()
) -> KernelOutput:
    """Integrate every variant of ``b`` with the compiled kernel (same results as the reference);
    ``record``: nodes whose acceleration is kept at every step (``step_acceleration``)."""
    out, hist, summ = outputs(b, histories, n_out, record)
    topo, var = records(b)
    run_blocks(_run, block_starts(b.x0.shape[2], block), n_out, topo, var, hist, summ)
    return finish(out, hist)
