"""The compiled (numba) kernel: the reference step of :mod:`crashstudy.kernel.reference`, with the
loop over variants innermost.

Variants are cut into blocks of at most ``BLOCK`` columns; blocks run in parallel (``prange``) and
each block advances all its variants through time together, so the innermost loops run over
contiguous variant columns and the CPU works on several variants per instruction. Every variant
keeps its own step ``dt``, so its result does not depend on which block it lands in.

What a model does not contain is skipped: no material state without ``general_nonlinear``/``crush``,
no geometry (square roots, directions) in 1-D, no wall, load or prescribed-motion loops when there
are none, no history writes when no history is kept.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from crashstudy.batch import Batch
from crashstudy.compiler import CRUSH, DAMPER, GENERAL, LINEAR, NONLINEAR, PM_ACCELERATION, PM_DISPLACEMENT
from crashstudy.kernel.output import CRUSHED_TO_ZERO, HISTORY_ORDER, INVALID, UNSTABLE, KernelOutput, allocate
from crashstudy.kernel.reference import TINY_LENGTH
from crashstudy.kernel.scalar import curve_at, general_nonlinear, time_curve_at

BLOCK = 256
NSTATE = 8


@nb.njit(parallel=True, cache=True, nogil=True)
def _run(starts, si, sj, material, curve_a, curve_b, off, free, load_node, load_curve, pm_node, pm_dir, pm_kind,
         pm_curve, wall_nodes, mass, inv_mass, x0, v0, length0, sign, kpar, yield_t, yield_c, cx, cy, cds, cs0,
         cs1, gravity, load_force, pm_scale, wall_point, wall_normal, dt, n_steps, out_every, ke_fraction,
         min_time, invalid, rec_mask, h_pos, h_disp, h_vel, h_acc, h_force, h_elong, h_energy, h_wall,
         status, fail_time, fail_item, t_end, peak_force, max_crush, absorbed, peak_acc, peak_wall, energy_error,
         final_energy):  # pragma: no cover - compiled  # fmt: skip
    N = x0.shape[0]
    D = x0.shape[1]
    S = si.shape[0]
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
    nblocks = starts.shape[0] - 1
    for bi in nb.prange(nblocks):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        x = np.empty((N, D, B))
        v = np.empty((N, D, B))
        vnew = np.empty((N, D, B))
        f = np.empty((N, D, B))
        fext = np.zeros((N, D, B))
        fext_prev = np.zeros((N, D, B))
        acc = np.empty((N, D, B))
        state = np.zeros((S if has_state else 0, NSTATE, B))
        forces = np.zeros((S, B))
        elong = np.zeros((S, B))
        f_prev = np.zeros((S, B))
        e_prev = np.zeros((S, B))
        ie = np.zeros((S, B))
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
        err = np.zeros(B)
        wforce = np.zeros((W, B))
        act = np.empty(B, dtype=np.bool_)
        nst = np.empty(B, dtype=np.int64)
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
                    x[n_, d, w] = x0[n_, d, lo + w]
                    v[n_, d, w] = v0[n_, d, lo + w]
                    ke0[w] += 0.5 * mass[n_, lo + w] * v0[n_, d, lo + w] * v0[n_, d, lo + w]

        for n in range(nmax + 1):
            anyact = False
            for w in range(B):
                act[w] = n <= nst[w] and st_ok[w] == 0
                anyact = anyact or act[w]
            if not anyact:
                break
            f[:] = 0.0
            for w in range(B):
                edot_min[w] = np.inf
                crushed[w] = -1
            for s in range(S):
                i = si[s]
                j = sj[s]
                kind = material[s]
                if D == 1:
                    for w in range(B):
                        q = lo + w
                        sg = sign[s, q]
                        e_tmp[w] = sg * ((x[j, 0, w] - x0[j, 0, q]) - (x[i, 0, w] - x0[i, 0, q]))
                        ed_tmp[w] = sg * (v[j, 0, w] - v[i, 0, w])
                        ax_tmp[0, w] = sg
                else:
                    for w in range(B):
                        q = lo + w
                        ln2 = 0.0
                        for d in range(D):
                            dd = x[j, d, w] - x[i, d, w]
                            ax_tmp[d, w] = dd
                            ln2 += dd * dd
                        ln = np.sqrt(ln2)
                        gone = ln <= TINY_LENGTH * length0[s, q]
                        if gone and crushed[w] < 0:
                            crushed[w] = s
                        dn = 1.0 if gone else ln
                        edot = 0.0
                        for d in range(D):
                            ax_tmp[d, w] = ax_tmp[d, w] / dn
                            edot += ax_tmp[d, w] * (v[j, d, w] - v[i, d, w])
                        e_tmp[w] = ln - length0[s, q]
                        ed_tmp[w] = edot
                if kind == LINEAR:
                    for w in range(B):
                        F_tmp[w] = kpar[s, lo + w] * e_tmp[w]
                elif kind == DAMPER:
                    for w in range(B):
                        F_tmp[w] = kpar[s, lo + w] * ed_tmp[w]
                elif kind == NONLINEAR:
                    c = curve_a[s]
                    a0 = off[c]
                    b0 = off[c + 1]
                    for w in range(B):
                        q = lo + w
                        F_tmp[w] = cy[a0, q] + cs0[c, q] * (e_tmp[w] - cx[a0, q])
                    for k in range(a0 + 1, b0 - 1):
                        for w in range(B):
                            q = lo + w
                            F_tmp[w] = F_tmp[w] + cds[k, q] * max(0.0, e_tmp[w] - cx[k, q])
                elif kind == CRUSH:
                    c = curve_a[s]
                    a0 = off[c]
                    b0 = off[c + 1]
                    for w in range(B):
                        q = lo + w
                        F_tmp[w] = cy[a0, q] + cs0[c, q] * (e_tmp[w] - cx[a0, q])
                    for k in range(a0 + 1, b0 - 1):
                        for w in range(B):
                            q = lo + w
                            F_tmp[w] = F_tmp[w] + cds[k, q] * max(0.0, e_tmp[w] - cx[k, q])
                    for w in range(B):
                        e = e_tmp[w]
                        emin = state[s, 0, w]
                        fstar = state[s, 1, w]
                        on = e <= emin
                        f_load = min(0.0, F_tmp[w])
                        f_unl = min(0.0, fstar + kpar[s, lo + w] * (e - emin))
                        F_tmp[w] = f_load if on else f_unl
                        state[s, 0, w] = e if on else emin
                        state[s, 1, w] = f_load if on else fstar
                else:  # GENERAL
                    for w in range(B):
                        F_tmp[w] = general_nonlinear(e_tmp[w], state[s], w, curve_a[s], curve_b[s], yield_t[s, lo + w],
                                                     yield_c[s, lo + w], lo + w, cx, cy, cds, cs0, cs1, off)
                for d in range(D):
                    for w in range(B):
                        fa = F_tmp[w] * ax_tmp[d, w]
                        f[i, d, w] += fa
                        f[j, d, w] -= fa
                for w in range(B):
                    q = lo + w
                    F = F_tmp[w]
                    e = e_tmp[w]
                    forces[s, w] = F
                    elong[s, w] = e
                    edot_min[w] = min(edot_min[w], ed_tmp[w])
                    if act[w]:
                        if n > 0:
                            ie[s, w] += 0.5 * (F + f_prev[s, w]) * (e - e_prev[s, w])
                        peak_force[s, q] = max(peak_force[s, q], abs(F))
                        max_crush[s, q] = max(max_crush[s, q], -e)
                    f_prev[s, w] = F
                    e_prev[s, w] = e

            # external forces and accelerations
            for n_ in range(N):
                for d in range(D):
                    for w in range(B):
                        q = lo + w
                        fe = mass[n_, q] * gravity[d, q] if has_gravity else 0.0
                        fext[n_, d, w] = fe
            for k in range(NL):
                c = load_curve[k]
                p = load_node[k]
                for w in range(B):
                    q = lo + w
                    scale = time_curve_at(c, n * dt[q], q, cx, cy, cds, cs0, off) if c >= 0 else 1.0
                    for d in range(D):
                        fext[p, d, w] += load_force[k, d, q] * scale
            for n_ in range(N):
                for d in range(D):
                    for w in range(B):
                        q = lo + w
                        ftot = f[n_, d, w] + fext[n_, d, w]
                        a = ftot * inv_mass[n_, d, q]
                        acc[n_, d, w] = a
                        dtn = dt[q] if n > 0 else 0.5 * dt[q]
                        vnew[n_, d, w] = v[n_, d, w] + dtn * a
            for k in range(NP):
                p = pm_node[k]
                d = pm_dir[k]
                c = pm_curve[k]
                for w in range(B):
                    q = lo + w
                    t = n * dt[q]
                    dtn = dt[q] if n > 0 else 0.5 * dt[q]
                    if pm_kind[k] == PM_DISPLACEMENT:
                        target = x0[p, d, q] + pm_scale[k, q] * time_curve_at(c, t + dt[q], q, cx, cy, cds, cs0, off)
                        vnew[p, d, w] = (target - x[p, d, w]) / dt[q]
                    elif pm_kind[k] == PM_ACCELERATION:
                        vnew[p, d, w] = v[p, d, w] + dtn * pm_scale[k, q] * time_curve_at(c, t, q, cx, cy, cds, cs0, off)
                    else:
                        vnew[p, d, w] = pm_scale[k, q] * time_curve_at(c, t + 0.5 * dt[q], q, cx, cy, cds, cs0, off)
                    acc[p, d, w] = (vnew[p, d, w] - v[p, d, w]) / dtn
                    ftot = f[p, d, w] + fext[p, d, w]
                    fext[p, d, w] += mass[p, q] * acc[p, d, w] - ftot
            if W > 0:
                wforce[:] = 0.0
            for wl in range(W):
                for n_ in range(N):
                    if wall_nodes[wl, n_] == 0.0:
                        continue
                    for w in range(B):
                        q = lo + w
                        vn = 0.0
                        dist = 0.0
                        vold_n = 0.0
                        for d in range(D):
                            nr = wall_normal[wl, d, q]
                            vn += vnew[n_, d, w] * nr
                            dist += (x[n_, d, w] + dt[q] * vnew[n_, d, w] - wall_point[wl, d, q]) * nr
                            vold_n += v[n_, d, w] * nr
                        if dist < 0.0 and vn < 0.0:
                            for d in range(D):
                                vnew[n_, d, w] = vnew[n_, d, w] - vn * wall_normal[wl, d, q] * free[n_, d]
                            if act[w]:
                                wall_e[w] += 0.5 * mass[n_, q] * vn * vold_n
                            wforce[wl, w] += mass[n_, q] * abs(vn) / dt[q]

            # energies, summaries, failures, histories, termination
            for w in range(B):
                q = lo + w
                if not act[w]:
                    continue
                if n == 0:
                    kw = ke0[w]
                else:
                    kw = 0.0
                    wk = 0.0
                    for n_ in range(N):
                        for d in range(D):
                            kw += 0.5 * mass[n_, q] * v[n_, d, w] * vnew[n_, d, w]
                            wk += 0.5 * (fext[n_, d, w] + fext_prev[n_, d, w]) * v[n_, d, w]
                    work[w] += wk * dt[q]
                ke[w] = kw
                wmax[w] = max(wmax[w], abs(work[w]))
                ie_tot = 0.0
                for s in range(S):
                    ie_tot += ie[s, w]
                bal = abs(kw + ie_tot + wall_e[w] - ke0[w] - work[w])
                err[w] = max(err[w], bal)
                for n_ in range(N):
                    a2 = 0.0
                    for d in range(D):
                        a2 += acc[n_, d, w] * acc[n_, d, w]
                    peak_acc[n_, q] = max(peak_acc[n_, q], np.sqrt(a2))
                for wl in range(W):
                    peak_wall[wl, q] = max(peak_wall[wl, q], wforce[wl, w])
                t = n * dt[q]
                if not np.isfinite(bal):
                    st_ok[w] = UNSTABLE
                    fail_time[q] = t
                    act[w] = False
                    continue
                if crushed[w] >= 0:
                    st_ok[w] = CRUSHED_TO_ZERO
                    fail_item[q] = crushed[w]
                    fail_time[q] = t
                    act[w] = False
                    continue
                if any_hist and n % out_every[q] == 0:
                    r = n // out_every[q]
                    for n_ in range(N):
                        for d in range(D):
                            if rec_mask[0]:
                                h_pos[r, n_, d, q] = x[n_, d, w]
                            if rec_mask[1]:
                                h_disp[r, n_, d, q] = x[n_, d, w] - x0[n_, d, q]
                            if rec_mask[2]:
                                h_vel[r, n_, d, q] = 0.5 * (v[n_, d, w] + vnew[n_, d, w]) if n > 0 else v0[n_, d, q]
                            if rec_mask[3]:
                                h_acc[r, n_, d, q] = acc[n_, d, w]
                    for s in range(S):
                        if rec_mask[4]:
                            h_force[r, s, q] = forces[s, w]
                        if rec_mask[5]:
                            h_elong[r, s, q] = elong[s, w]
                    h_energy[r, 0, q] = kw
                    h_energy[r, 1, q] = ie_tot
                    h_energy[r, 2, q] = work[w]
                    h_energy[r, 3, q] = wall_e[w]
                    for wl in range(W):
                        if rec_mask[10]:
                            h_wall[r, wl, q] = wforce[wl, w]
                t_end[q] = t
                last = n == nst[w]
                if ke_fraction[q] > 0.0 and n > 0 and t >= min_time[q]:
                    fsum = 0.0
                    psum = 0.0
                    for s in range(S):
                        fsum += abs(forces[s, w])
                        psum += peak_force[s, q]
                    small_f = fsum <= ke_fraction[q] * psum
                    small_ke = kw <= ke_fraction[q] * (ke0[w] + wmax[w])
                    opening = edot_min[w] >= 0.0 and no_ext
                    if small_f and (small_ke or opening):
                        nst[w] = n
                        last = True
                if last:
                    final_energy[0, q] = kw
                    final_energy[1, q] = ie_tot
                    final_energy[2, q] = work[w]
                    final_energy[3, q] = wall_e[w]
            for n_ in range(N):
                for d in range(D):
                    for w in range(B):
                        if act[w]:
                            x[n_, d, w] = x[n_, d, w] + dt[lo + w] * vnew[n_, d, w]
                            v[n_, d, w] = vnew[n_, d, w]
                        fext_prev[n_, d, w] = fext[n_, d, w]
        for w in range(B):
            q = lo + w
            status[q] = st_ok[w]
            for s in range(S):
                absorbed[s, q] = ie[s, w]
            energy_error[q] = err[w] / max(ke0[w] + wmax[w], 1e-300)


def run_compiled(b: Batch, histories: tuple[str, ...], n_out: int, block: int = BLOCK) -> KernelOutput:
    """Integrate every variant of ``b`` with the compiled kernel (same results as the reference)."""
    N, D, V = b.x0.shape
    S = len(b.spring_i)
    W = b.wall_nodes.shape[0]
    out = allocate(S, N, D, W, V, histories, n_out)
    energies = ("kinetic_energy", "internal_energy", "external_work", "wall_energy")
    want_energy = any(h in histories for h in energies)
    T = n_out

    def buf(name: str, shape: tuple[int, ...]) -> np.ndarray:
        return out.histories[name] if name in out.histories else np.empty((1,) * len(shape))

    h_energy = np.full((T, 4, V), np.nan) if want_energy else np.empty((1, 4, 1))
    rec_mask = np.array([h in histories for h in HISTORY_ORDER], dtype=np.bool_)
    if want_energy:
        rec_mask[6] = True  # energies are written together
    starts = np.arange(0, V + block, block)
    starts[-1] = V
    starts = np.unique(starts).astype(np.int64)
    _run(starts, b.spring_i, b.spring_j, b.material, b.curve_a, b.curve_b, b.curve_off, b.free, b.load_node,
         b.load_curve, b.pm_node, b.pm_dir, b.pm_kind, b.pm_curve, b.wall_nodes, b.mass, b.inv_mass, b.x0, b.v0,
         b.length0, b.sign, b.kpar, b.yield_t, b.yield_c, b.cx, b.cy, b.cds, b.cs0, b.cs1, b.gravity,
         b.load_force, b.pm_scale, b.wall_point, b.wall_normal, b.dt, b.n_steps, b.out_every, b.ke_fraction,
         b.min_time, b.invalid, rec_mask,
         buf("position", (T, N, D, V)), buf("displacement", (T, N, D, V)), buf("velocity", (T, N, D, V)),
         buf("acceleration", (T, N, D, V)), buf("spring_force", (T, S, V)), buf("spring_elongation", (T, S, V)),
         h_energy, buf("wall_force", (T, W, V)),
         out.status, out.fail_time, out.fail_item, out.t_end, out.peak_force, out.max_crush, out.absorbed_energy,
         out.peak_acceleration, out.peak_wall_force, out.energy_error, out.final_energy)  # fmt: skip
    for k, name in enumerate(energies):
        if name in out.histories:
            out.histories[name][:] = h_energy[:, k, :]
    return out
