"""The generic kernel's node and bookkeeping stages over a block of variants: external forces,
accelerations and velocities, prescribed motion, rigid walls; energies, peaks, failures, histories,
termination and the position update. Laws from :mod:`crashstudy.kernel.laws`; records as in
:mod:`crashstudy.kernel.generic_springs`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from crashstudy.kernel.codes import (
    CRUSHED_TO_ZERO,
    PM_ACCELERATION,
    PM_DISPLACEMENT,
    UNSTABLE,
    UNSTABLE_ENERGY,
)
from crashstudy.kernel.laws import (
    ext_power,
    knot_accel,
    peak,
    time_curve_at,
    wall_force,
    wall_jump,
    work_increment,
)

_jit = nb.njit(cache=True, nogil=True)


@_jit
def fused_1d(h, B, In, Z):  # pragma: no cover - compiled
    """1-D without walls, prescribed motion or external forces: a = f/m, v^{n+1/2}, kinetic energy, peak
    |a| and x^{n+1} in one pass (the arithmetic of :func:`nodes` and :func:`advance`; x and v advance
    before the failure check, which changes nothing a failed variant reports)."""
    x, v, acc, vnew, dt_b = Z.x, Z.v, Z.acc, Z.vnew, In.dt
    for w in range(B):
        Z.ke[w] = 0.0
    for n_ in range(x.shape[0]):
        mv = Z.movable[n_]
        for w in range(B):
            a = (Z.f[n_, 0, w] + 0.0) * In.im[n_, 0, w]
            acc[n_, 0, w] = a
            vo = v[n_, 0, w]
            vn = vo + (h * dt_b[w]) * a
            vnew[n_, 0, w] = vn
            Z.ke[w] += 0.5 * In.m[n_, w] * vo * vn
            af = Z.actf[w]
            if mv:
                Z.pacc[n_, w] = peak(Z.pacc[n_, w], (a * a) * af)
            x[n_, 0, w] = x[n_, 0, w] + (dt_b[w] * af) * vn
            v[n_, 0, w] = vn * af + vo * (1.0 - af)


@_jit
def nodes(n, h, lo, B, no_ext, has_gravity, T, P, In, Z):  # pragma: no cover - compiled
    """External forces, a^n, v^{n+1/2}, then prescribed motion and rigid walls."""
    x, v, acc, vnew, f, fext, dt_b = Z.x, Z.v, Z.acc, Z.vnew, Z.f, Z.fext, In.dt
    N, D = x.shape[0], x.shape[1]
    off = T.curve_off
    if not no_ext:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    fext[n_, d, w] = In.m[n_, w] * P.gravity[d, lo + w] if has_gravity else 0.0
        for k in range(T.load_node.shape[0]):
            c = T.load_curve[k]
            p = T.load_node[k]
            for w in range(B):
                q = lo + w
                scale = time_curve_at(c, n * dt_b[w], q, P.cx, P.cy, P.cds, P.cs0, off) if c >= 0 else 1.0
                for d in range(D):
                    fext[p, d, w] += P.load_force[k, d, q] * scale
    for n_ in range(N):
        for d in range(D):
            for w in range(B):
                a = (f[n_, d, w] + (fext[n_, d, w] if not no_ext else 0.0)) * In.im[n_, d, w]
                acc[n_, d, w] = a
                vnew[n_, d, w] = v[n_, d, w] + (h * dt_b[w]) * a
    for k in range(T.pm_node.shape[0]):
        p = T.pm_node[k]
        d = T.pm_dir[k]
        c = T.pm_curve[k]
        for w in range(B):
            q = lo + w
            t = n * dt_b[w]
            dtn = h * dt_b[w]
            sc = P.pm_scale[k, q]
            if T.pm_kind[k] == PM_DISPLACEMENT:
                target = In.x0[p, d, w] + sc * time_curve_at(c, t + dt_b[w], q, P.cx, P.cy, P.cds, P.cs0, off)
                vnew[p, d, w] = (target - x[p, d, w]) / dt_b[w]
            elif T.pm_kind[k] == PM_ACCELERATION:
                vnew[p, d, w] = v[p, d, w] + dtn * sc * time_curve_at(c, t, q, P.cx, P.cy, P.cds, P.cs0, off)
            else:
                vnew[p, d, w] = sc * time_curve_at(c, t + 0.5 * dt_b[w], q, P.cx, P.cy, P.cds, P.cs0, off)
            if n != Z.nst[w]:
                Z.pm_acc[k, w] = (vnew[p, d, w] - v[p, d, w]) / dtn
            else:  # the last step's update would look past end_time: continue with the previous acceleration
                vnew[p, d, w] = v[p, d, w] + dtn * Z.pm_acc[k, w]
            acc[p, d, w] = Z.pm_acc[k, w]
            ftot = f[p, d, w] + fext[p, d, w]
            fext[p, d, w] += In.m[p, w] * acc[p, d, w] - ftot
    W = T.wall_nodes.shape[0]
    if W > 0:
        Z.wforce[:] = 0.0
    for wl in range(W):
        for n_ in range(N):
            if T.wall_nodes[wl, n_] == 0.0:
                continue
            for w in range(B):
                q = lo + w
                vn = 0.0
                gap = 0.0
                dist = 0.0
                for d in range(D):
                    nr = P.wall_normal[wl, d, q]
                    vn += vnew[n_, d, w] * nr
                    gap += (x[n_, d, w] - P.wall_point[wl, d, q]) * nr
                    dist += (x[n_, d, w] + dt_b[w] * vnew[n_, d, w] - P.wall_point[wl, d, q]) * nr
                dvn = wall_jump(vn, gap, dist, dt_b[w])
                we = 0.0
                for d in range(D):
                    jmp = dvn * P.wall_normal[wl, d, q] * T.free[n_, d]
                    vnew[n_, d, w] = vnew[n_, d, w] + jmp
                    we += v[n_, d, w] * (jmp + Z.jump_prev[wl, n_, d, w])
                    Z.jump_prev[wl, n_, d, w] = jmp
                if Z.act[w]:
                    Z.wall_e[w] += -0.5 * In.m[n_, w] * we
                Z.wforce[wl, w] += wall_force(In.m[n_, w], dvn, dt_b[w])


@_jit
def energies(n, lo, B, fused, no_ext, P, In, Z):  # pragma: no cover - compiled
    """Kinetic energy and external work (sums over nodes with the variant loop innermost)."""
    v, vnew, ke, bal = Z.v, Z.vnew, Z.ke, Z.bal
    N, D = v.shape[0], v.shape[1]
    if fused:
        return  # kinetic energy summed in fused_1d; no external work
    if n == 0:
        for w in range(B):
            ke[w] = Z.ke0[w]
        return
    for w in range(B):
        ke[w] = 0.0
        bal[w] = 0.0
    for n_ in range(N):
        for d in range(D):
            for w in range(B):
                ke[w] += 0.5 * In.m[n_, w] * v[n_, d, w] * vnew[n_, d, w]
    if not no_ext:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    vb = 0.5 * (P.v0[n_, d, lo + w] + v[n_, d, w]) if n == 1 else v[n_, d, w]
                    bal[w] = ext_power(bal[w], Z.fext[n_, d, w], v[n_, d, w], Z.fext_prev[n_, d, w], vb)
        for w in range(B):
            Z.work[w] = work_increment(Z.work[w], bal[w], In.dt[w], Z.actf[w])


@_jit
def checks(n, lo, B, D, fused, any_hit, T, P, In, Z, Out):  # pragma: no cover - compiled
    """Energy balance, peak |a| (also at this step's knot crossings), peak wall forces, failures."""
    nbad = 0
    for w in range(B):
        Z.wmax[w] = max(Z.wmax[w], abs(Z.work[w]))
        b_ = abs(Z.ke[w] + Z.ie_tot[w] + Z.wall_e[w] - Z.e_init[w] - Z.work[w])
        Z.bal[w] = b_
        Z.err[w] = peak(Z.err[w], b_ * Z.actf[w])
        nbad += Z.act[w] & ~(b_ <= UNSTABLE_ENERGY * (Z.e_init[w] + Z.wmax[w]) + P.energy_floor[lo + w])
    anybad = nbad > 0
    acc = Z.acc
    for n_ in range(acc.shape[0]):  # the square is tracked (sqrt is monotonic: the same peak)
        if fused or not Z.movable[n_]:
            continue
        for w in range(B):
            a2 = 0.0
            for d in range(D):
                a2 += acc[n_, d, w] * acc[n_, d, w]
            Z.pacc[n_, w] = peak(Z.pacc[n_, w], a2 * Z.actf[w])
    if any_hit:  # |a| at the knot crossings of this step (see reference)
        for s in range(T.spring_i.shape[0]):
            if not Z.k_any[s]:
                continue
            for side in range(2):
                p = T.spring_i[s] if side == 0 else T.spring_j[s]
                if not Z.movable[p]:
                    continue
                for w in range(B):
                    a2 = 0.0
                    for d in range(D):
                        ai = knot_accel(Z.acc_prev[p, d, w], acc[p, d, w], Z.k_th[s, w], Z.k_dfax[s, d, w],
                                        In.im[p, d, w], side)  # fmt: skip
                        a2 += ai * ai
                    Z.pacc[p, w] = peak(Z.pacc[p, w], (a2 if Z.k_hit[s, w] else 0.0) * Z.actf[w])
    for wl in range(T.wall_nodes.shape[0]):
        for w in range(B):
            Z.pwall[wl, w] = peak(Z.pwall[wl, w], Z.wforce[wl, w] * Z.actf[w])
    if D > 1:
        for w in range(B):
            anybad = anybad or (Z.act[w] and Z.crushed[w] >= 0)
    if not anybad:
        return
    for w in range(B):
        if not Z.act[w]:
            continue
        if not (Z.bal[w] <= UNSTABLE_ENERGY * (Z.e_init[w] + Z.wmax[w]) + P.energy_floor[lo + w]):
            Z.st_ok[w] = UNSTABLE
        elif D > 1 and Z.crushed[w] >= 0:
            Z.st_ok[w] = CRUSHED_TO_ZERO
            Out.fail_item[lo + w] = Z.crushed[w]
        else:
            continue
        Out.fail_time[lo + w] = n * In.dt[w]
        Z.n_fail[w] = n
        Z.act[w] = False
        Z.actf[w] = 0.0


@_jit
def record(n, lo, B, n_out, P, In, Z, H):  # pragma: no cover - compiled
    """The histories of the lanes that sample at step n (x^n, v^n, a^n, F^n, e^n, energies)."""
    x, v, vnew, acc = Z.x, Z.v, Z.vnew, Z.acc
    N, D = x.shape[0], x.shape[1]
    rec = H.rec
    for w in range(B):
        q = lo + w
        if not (Z.act[w] and n == Z.next_rec[w]):
            continue
        r = n // P.out_every[q]
        Z.next_rec[w] = n + P.out_every[q]
        if r >= n_out:  # the last step may pass the last sample time
            continue
        for n_ in range(N):
            for d in range(D):
                if rec[0]:
                    H.pos[r, n_, d, q] = x[n_, d, w]
                if rec[1]:
                    H.disp[r, n_, d, q] = x[n_, d, w] - In.x0[n_, d, w]
                if rec[2]:
                    H.vel[r, n_, d, q] = 0.5 * (v[n_, d, w] + vnew[n_, d, w]) if n > 0 else v[n_, d, w]
                if rec[3]:
                    H.acc[r, n_, d, q] = acc[n_, d, w]
        for s in range(Z.forces.shape[0]):
            if rec[4]:
                H.force[r, s, q] = Z.forces[s, w]
            if rec[5]:
                H.elong[r, s, q] = Z.elong[s, w]
        if rec[6]:
            H.energy[r, 0, q] = Z.ke[w]
            H.energy[r, 1, q] = Z.ie_tot[w]
            H.energy[r, 2, q] = Z.work[w]
            H.energy[r, 3, q] = Z.wall_e[w]
        for wl in range(Z.wforce.shape[0]):
            if rec[10]:
                H.wall[r, wl, q] = Z.wforce[wl, w]


@_jit
def terminate(n, n_end, lo, B, no_ext, P, In, Z):  # pragma: no cover - compiled
    """Early termination (docs/format.md) of the running lanes; returns the new first end step."""
    for w in range(B):
        q = lo + w
        t = n * In.dt[w]
        if not Z.act[w] or P.ke_fraction[q] <= 0.0 or t < P.min_time[q]:
            continue
        fsum = 0.0
        psum = 0.0
        for s in range(Z.forces.shape[0]):
            fsum += abs(Z.forces[s, w])
            psum += Z.pf[s, w]
        small_f = fsum <= P.ke_fraction[q] * psum
        small_ke = Z.ke[w] <= P.ke_fraction[q] * (Z.e_init[w] + Z.wmax[w])
        opening = Z.edot_min[w] >= 0.0 and no_ext
        if small_f and (small_ke or opening):
            Z.nst[w] = n
            n_end = n
    return n_end


@_jit
def advance(B, fused, no_ext, In, Z):  # pragma: no cover - compiled
    """x^{n+1} = x^n + dt v^{n+1/2} (a stopped variant keeps x and v; vnew is finite for it)."""
    x, v, vnew = Z.x, Z.v, Z.vnew
    N, D = x.shape[0], x.shape[1]
    if not fused:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    af = Z.actf[w]
                    x[n_, d, w] = x[n_, d, w] + (In.dt[w] * af) * vnew[n_, d, w]
                    v[n_, d, w] = vnew[n_, d, w] * af + v[n_, d, w] * (1.0 - af)
    if not no_ext:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    Z.fext_prev[n_, d, w] = Z.fext[n_, d, w]


_ = np
