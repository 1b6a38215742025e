"""The generic kernel's cold parts, called once per block or on rare steps (so a call's cost, numba
increfs every array argument, does not matter): which features the model has, the block's arrays,
the knot search after a crossing, the histories of a sampled step and the block's results.
The step itself stays one compiled loop in :mod:`crashstudy.kernel.compiled`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from crashstudy.kernel.laws import (
    broken_at,
    crush_knot_force,
    crush_window,
    energy_first_half,
    energy_increment,
    general_window,
    knot_step,
    nonlinear_window,
    peak,
    unstable,
    unstable_limit,
)
from crashstudy.vocabulary.codes import (
    CRUSH,
    CRUSHED_TO_ZERO,
    GENERAL,
    INVALID,
    NONLINEAR,
    NSTATE,
    PM_DISPLACEMENT,
    UNSTABLE,
)
from crashstudy.vocabulary.materials import KNOT_MATERIALS, STATE_MATERIALS

_jit = nb.njit(cache=True, nogil=True)


#: rows of the per-spring options array of a block: preloaded (initial_elongation), breakable (failure)
PRELOADED, BREAKABLE = 0, 1

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
def flags(T, P, H):  # pragma: no cover - compiled
    """What the model contains: (has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot,
    pm_disp: (N, D) the dofs driven by a displacement curve, whose rate is v^{n-1/2} (see the reference))."""
    material, gravity, rec_mask, ke_fraction, free = T.material, P.gravity, H.rec, P.ke_fraction, T.free
    pm_node, curve_a, off, knot_check = T.pm_node, T.curve_a, T.curve_off, T.knot_check
    N, D, _ = P.x0.shape
    S = T.spring_i.shape[0]
    NL = T.load_node.shape[0]
    NP = pm_node.shape[0]
    has_state = False
    for s in range(S):
        if material[s] in STATE_MATERIALS:
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
        if material[s] in KNOT_MATERIALS and ca >= 0:
            for k in range(off[ca] + 1, off[ca + 1] - 1):
                if knot_check[k]:
                    knotted[s] = True
                    any_knot = True
    pm_disp = np.zeros((N, D), dtype=np.bool_)
    for k in range(NP):
        if T.pm_kind[k] == PM_DISPLACEMENT:
            pm_disp[pm_node[k], T.pm_dir[k]] = True
    return has_state, has_gravity, no_ext, any_hist, has_term, movable, knotted, any_knot, pm_disp


@_jit
def block_arrays(lo, B, has_state, any_knot, T, P, Out):  # pragma: no cover - compiled
    """The block's copies of its variants' inputs and its state, zeroed or set to the initial state;
    invalid variants are marked; preloaded springs (``initial_elongation``) start from the batch's state and
    IE0, and ``e_init`` holds KE0 + IE0 (row 0) and the error's scale KE0 + |IE0| (row 1). Returns the arrays and the largest step count (see the unpacking in
    :func:`crashstudy.kernel.compiled._run` for the order)."""
    si, sj, pm_node = T.spring_i, T.spring_j, T.pm_node
    mass, inv_mass, x0, v0, length0, sign, kpar = P.mass, P.inv_mass, P.x0, P.v0, P.length0, P.sign, P.kpar
    yield_t, yield_c, cx, cy, cds, cs0, knot_y = P.yield_t, P.yield_c, P.cx, P.cy, P.cds, P.cs0, P.knot_y
    dt, n_steps, invalid, fail_item, fail_time = P.dt, P.n_steps, P.invalid, Out.fail_item, Out.fail_time
    N, D, _ = x0.shape
    S = si.shape[0]
    K = cx.shape[0]
    C = cs0.shape[0]
    W = T.wall_nodes.shape[0]
    NP = pm_node.shape[0]
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
    # spring options: max elongation, broken springs, (preloaded, breakable) per spring, the
    # elongation / activity the extremes of a breakable spring take in this step, KE0 + IE0
    me = np.zeros((S, B))
    broken = np.zeros((S, B), dtype=np.bool_)
    options = np.zeros((2, S), dtype=np.bool_)  # rows PRELOADED, BREAKABLE
    ftmp = np.empty((2, B))
    e_init = np.zeros((2, B))  # KE0 + IE0 (the energy at t = 0), KE0 + |IE0| (the error's and stop tests' scale)
    for s in range(S):
        for w in range(B):
            q = lo + w
            ie[s, w] = P.ie0[s, q]
            options[PRELOADED, s] = options[PRELOADED, s] or P.e0[s, q] != 0.0
            options[BREAKABLE, s] = options[BREAKABLE, s] or P.fail_t[s, q] < np.inf or P.fail_c[s, q] > -np.inf
    if has_state and P.state0.shape[0] > 0:
        for s in range(S):
            for k in range(NSTATE):
                for w in range(B):
                    state[s, k, w] = P.state0[s, k, lo + w]
    for w in range(B):
        ie0 = 0.0
        for s in range(S):
            ie0 = ie0 + P.ie0[s, lo + w]
        e_init[0, w] = ke0[w] + ie0
        e_init[1, w] = ke0[w] + abs(ie0)

    return (m_b, im_b, x0_b, sg_b, l0_b, kp_b, cx_b, cy_b, ds_b, ky_b, s0_b, yt_b, yc_b, g_arg, g_argt, g_argc, g_L, g_Ut, g_Uc, g_rev, dt_b, x, v, vnew, f, fext, fext_prev, acc, acc_prev, k_sh, k_c, k_x, k_y, k_any, k_hit, k_th, k_dfax, jump_prev, pm_acc, axis_prev, state, forces, elong, f_prev, e_prev, ie, pf, mc, pacc, pwall, e_tmp, ed_tmp, F_tmp, ax_tmp, edot_min, crushed, work, wall_e, wmax, ke0, ke, ie_tot, err, bal, wforce, act, actf, n_fail, nst, next_rec, st_ok, me, broken, options, ftmp, e_init, nmax)


@_jit
def knot_search(s, kind, B, off, ca, knot_check, cx_b, ky_b, e_tmp, e_prev, state, k_c, k_x, k_y, k_sh):  # pragma: no cover
    """The knots of spring s's curve that its lanes passed over this step (rare): each lane's winning
    knot (k_c, k_x, k_y, k_sh; the state is still the one before the step). Returns how many lanes
    passed one."""
    nhit = 0
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
    return nhit


@_jit
def record(n, lo, B, n_out, act, next_rec, out_every, x, x0_b, v, vnew, acc, forces, elong, ke, ie_tot, work, wall_e,
           wforce, H):  # pragma: no cover - compiled  # fmt: skip
    """The histories of the lanes that sample at step n."""
    rec_mask, h_pos, h_disp, h_vel, h_acc, h_force, h_elong = H.rec, H.pos, H.disp, H.vel, H.acc, H.force, H.elong
    h_energy, h_wall = H.energy, H.wall
    N, D, _ = x.shape
    S = forces.shape[0]
    W = wforce.shape[0]
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
            h_energy[r, 3, q] = wall_e[w] if n > 0 else 0.0  # t = 0: before any impact (see the reference)
        for wl in range(W):
            if rec_mask[10]:
                h_wall[r, wl, q] = wforce[wl, w]


@_jit
def results(lo, B, st_ok, err, e_scale, wmax, nst, n_fail, dt_b, ie, pf, mc, me, pacc, pwall, Out):  # pragma: no cover
    """Write the block's summaries to its variants' columns."""
    status, t_end, absorbed, peak_force, max_crush = Out.status, Out.t_end, Out.absorbed, Out.peak_force, Out.max_crush
    peak_acc, peak_wall, energy_error, max_elongation = Out.peak_acc, Out.peak_wall, Out.energy_error, Out.max_elongation
    S, N, W = ie.shape[0], pacc.shape[0], pwall.shape[0]
    for w in range(B):
        q = lo + w
        status[q] = st_ok[w]
        energy_error[q] = err[w] / max(e_scale[w] + wmax[w], 1e-300)
        if st_ok[w] == 0:
            t_end[q] = nst[w] * dt_b[w]
        elif n_fail[w] > 0:
            t_end[q] = (n_fail[w] - 1) * dt_b[w]
    for s in range(S):
        for w in range(B):
            absorbed[s, lo + w] = ie[s, w]
            peak_force[s, lo + w] = pf[s, w]
            max_crush[s, lo + w] = mc[s, w]
            max_elongation[s, lo + w] = me[s, w]
    for n_ in range(N):
        for w in range(B):
            peak_acc[n_, lo + w] = np.sqrt(pacc[n_, w])
    for wl in range(W):
        for w in range(B):
            peak_wall[wl, lo + w] = pwall[wl, w]


@_jit
def record_steps(n, lo, B, act, acc, rec_block, step_nodes, steps):  # pragma: no cover - compiled
    """a^n of the recorded nodes (crash criteria) for the lanes still running after this step's checks,
    added to row ``(n + (k - 1) // 2) // k`` of the block record (``k = rec_block`` of the variant)."""
    k_w = 0
    r = 0
    for w in range(B):
        if act[w]:
            k = rec_block[lo + w]
            if k != k_w:  # divided once per run of lanes with equal k
                k_w = k
                r = (n + (k - 1) // 2) // k
            for m in range(step_nodes.shape[0]):
                p = step_nodes[m]
                for d in range(acc.shape[1]):
                    steps[r, m, d, lo + w] += acc[p, d, w]
@_jit
def fail_lanes(n, lo, B, D, act, actf, bal, e_scale, wmax, e_floor, crushed, st_ok, n_fail, dt_b, Out):  # pragma: no cover
    """A step where some lane failed (rare): unstable (energy balance) or, in 2-D, a spring crushed to zero
    length; those lanes stop."""
    for w in range(B):
        if not act[w]:
            continue
        if unstable(bal[w], unstable_limit(e_scale[w], wmax[w], e_floor[lo + w])):
            st_ok[w] = UNSTABLE
        elif D > 1 and crushed[w] >= 0:
            st_ok[w] = CRUSHED_TO_ZERO
            Out.fail_item[lo + w] = crushed[w]
        else:
            continue
        Out.fail_time[lo + w] = n * dt_b[w]
        n_fail[w] = n
        act[w] = False
        actf[w] = 0.0


@_jit
def final_energies(n, lo, B, act, nst, ke, ie_tot, work, wall_e, final_energy):  # pragma: no cover - compiled
    """The energies of the lanes that end at step n."""
    for w in range(B):
        if act[w] and n == nst[w]:
            q = lo + w
            final_energy[0, q] = ke[w]
            final_energy[1, q] = ie_tot[w]
            final_energy[2, q] = work[w]
            final_energy[3, q] = wall_e[w]


# ---- spring options (failure, initial_elongation) in the step (inlined: no call, no increfs) ----


@nb.njit(cache=True, nogil=True, inline="always")
def failure(s, n, lo, B, fail_t, fail_c, dt_b, e_tmp, e_prev, F_tmp, act, actf, broken, ftmp,
            spring_fail_time):  # pragma: no cover - compiled  # fmt: skip
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


@nb.njit(cache=True, nogil=True, inline="always")
def option_scatter(s, i, j, n, fh, lo, D, B, e0, rate0, dt_b, F_tmp, e_tmp, ax_tmp, actf, ftmp, fr, f, ie, ie_tot, pf,
               mc, me, forces, elong, f_prev, e_prev):  # pragma: no cover - compiled  # fmt: skip
    """Nodal forces and summaries of a breakable spring (``fr``: extremes up to the break) or of a preloaded
    spring's first step (``fh``: F^0 acts for the first half step, :func:`laws.energy_first_half`)."""
    for d in range(D):
        for w in range(B):
            fa = F_tmp[w] * ax_tmp[d, w]
            f[i, d, w] += fa
            f[j, d, w] -= fa
    for w in range(B):
        F = F_tmp[w]
        e = e_tmp[w]
        af = actf[w]
        if n == 1 and fh and e0[s, lo + w] != 0.0:
            ie[s, w] = energy_first_half(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], dt_b[w], rate0[s, lo + w], af)
        elif n > 0:
            ie[s, w] = energy_increment(ie[s, w], F, f_prev[s, w], e, e_prev[s, w], af)
        ie_tot[w] += ie[s, w]
        pf[s, w] = peak(pf[s, w], abs(F) * af)
        em = ftmp[0, w] if fr else e  # extremes while intact
        ai = ftmp[1, w] if fr else af
        mc[s, w] = peak(mc[s, w], -em * ai)
        me[s, w] = peak(me[s, w], em * ai)
        forces[s, w] = F
        elong[s, w] = e
        f_prev[s, w] = F
        e_prev[s, w] = e


_ = (CRUSH, GENERAL, INVALID, NONLINEAR, NSTATE, KNOT_MATERIALS, STATE_MATERIALS, np)
