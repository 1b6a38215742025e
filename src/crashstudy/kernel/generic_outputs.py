"""The generic kernel's outputs of a block: the histories of a sampled step, the per-step record of the
crash criteria, the final energies of the lanes that end and the block's summaries.
"""

from __future__ import annotations

import numpy as np

from crashstudy.kernel.generic_block import stage


@stage
def record(n, lo, B, n_out, out_every, H, K):  # pragma: no cover - compiled
    """The histories of the lanes that sample at step n."""
    act, next_rec, x, x0_b, v, vnew, acc = K.act, K.next_rec, K.x, K.x0_b, K.v, K.vnew, K.acc
    forces, elong, ke, ie_tot, work, wall_e, wforce = (
        K.forces,
        K.elong,
        K.ke,
        K.ie_tot,
        K.work,
        K.wall_e,
        K.wforce,
    )
    rec_mask, h_pos, h_disp, h_vel, h_acc, h_force, h_elong = (
        H.rec,
        H.pos,
        H.disp,
        H.vel,
        H.acc,
        H.force,
        H.elong,
    )
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


@stage
def results(lo, B, Out, K):  # pragma: no cover - compiled
    """Write the block's summaries to its variants' columns."""
    st_ok, err, e_scale, wmax, nst, n_fail, dt_b = (
        K.st_ok,
        K.err,
        K.e_init[1],
        K.wmax,
        K.nst,
        K.n_fail,
        K.dt_b,
    )
    ie, pf, mc, me, pacc, pwall = K.ie, K.pf, K.mc, K.me, K.pacc, K.pwall
    status, t_end, absorbed, peak_force, max_crush = (
        Out.status,
        Out.t_end,
        Out.absorbed,
        Out.peak_force,
        Out.max_crush,
    )
    peak_acc, peak_wall, energy_error, max_elongation = (
        Out.peak_acc,
        Out.peak_wall,
        Out.energy_error,
        Out.max_elongation,
    )
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


@stage
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


@stage
def final_energies(n, lo, B, act, nst, ke, ie_tot, work, wall_e, final_energy):  # pragma: no cover - compiled
    """The energies of the lanes that end at step n."""
    for w in range(B):
        if act[w] and n == nst[w]:
            q = lo + w
            final_energy[0, q] = ke[w]
            final_energy[1, q] = ie_tot[w]
            final_energy[2, q] = work[w]
            final_energy[3, q] = wall_e[w]
