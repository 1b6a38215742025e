"""The generic kernel's node stage over a block: external forces, accelerations and the central-difference
update, prescribed motion, kinetic energy and external work, peak accelerations and the stop test.

Every function is compiled once and called by :func:`crashstudy.kernel.compiled._run` (no numba IR
inlining, no CPython or C wrapper: see :mod:`crashstudy.kernel.generic_springs`); every per-lane formula is a law of
:mod:`crashstudy.kernel.step_laws` / :mod:`crashstudy.kernel.laws`.
"""

from __future__ import annotations

from crashstudy.kernel.generic_block import stage
from crashstudy.kernel.laws import knot_accel, peak, time_curve_at
from crashstudy.kernel.step_laws import (
    advance,
    ext_power,
    half_step,
    kinetic,
    prescribed_step,
    prescribed_time,
    prescribed_velocity,
    stop_test,
    work_increment,
)


@stage
def fused_update(
    h, B, N, movable, f, im_b, m_b, x, v, vnew, acc, dt_b, actf, ke, pacc
):  # pragma: no cover - compiled
    """1-D without walls, prescribed motion or external forces: a = f/m, v^{n+1/2}, kinetic energy, peak |a|
    and x^{n+1} in one pass (the arithmetic of the general path; x and v advance before the failure check,
    which changes nothing a failed variant reports)."""
    for w in range(B):
        ke[w] = 0.0
    for n_ in range(N):
        mv = movable[n_]
        for w in range(B):
            a = (f[n_, 0, w] + 0.0) * im_b[n_, 0, w]
            acc[n_, 0, w] = a
            vo = v[n_, 0, w]
            vn = half_step(vo, a, h * dt_b[w])
            vnew[n_, 0, w] = vn
            ke[w] = kinetic(ke[w], m_b[n_, w], vo, vn)
            af = actf[w]
            if mv:
                pacc[n_, w] = peak(pacc[n_, w], (a * a) * af)
            x[n_, 0, w], v[n_, 0, w] = advance(x[n_, 0, w], vo, vn, dt_b[w], af)


@stage
def accelerate(
    n,
    h,
    lo,
    B,
    N,
    D,
    ext,
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
):  # pragma: no cover - compiled
    """External forces (gravity, then the loads in order, scaled by their time curves), a^n = (f + f_ext)/m
    and v^{n+1/2}. Every stage here takes the arrays of the topology and input records, not the records
    (a record passed per step costs an incref per array)."""
    if ext:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    fext[n_, d, w] = m_b[n_, w] * gravity[d, lo + w] if has_gravity else 0.0
        for k in range(load_node.shape[0]):
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
                    vnew[n_, d, w] = half_step(v[n_, d, w], a, h * dt_b[w])
    else:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    a = (f[n_, d, w] + 0.0) * im_b[n_, d, w]
                    acc[n_, d, w] = a
                    vnew[n_, d, w] = half_step(v[n_, d, w], a, h * dt_b[w])


@stage
def prescribed(
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
):  # pragma: no cover - compiled
    """Prescribed motion of its dofs: v^{n+1/2} and a^n from the curve; f_ext takes the force it needs."""
    for k in range(pm_node.shape[0]):
        p = pm_node[k]
        d = pm_dir[k]
        c = pm_curve[k]
        kind = pm_kind[k]
        for w in range(B):
            q = lo + w
            t = n * dt_b[w]
            dtn = h * dt_b[w]
            tc = time_curve_at(c, prescribed_time(kind, t, dt_b[w]), q, cx, cy, cds, cs0, off)
            vn = prescribed_velocity(
                kind, x0_b[p, d, w], pm_scale[k, q], tc, x[p, d, w], v[p, d, w], dt_b[w], dtn
            )
            vnew[p, d, w], pm_acc[k, w] = prescribed_step(n == nst[w], vn, v[p, d, w], pm_acc[k, w], dtn)
            acc[p, d, w] = pm_acc[k, w]
            ftot = f[p, d, w] + fext[p, d, w]
            fext[p, d, w] += m_b[p, w] * acc[p, d, w] - ftot


@stage
def energies(
    n, lo, B, N, D, ext, v0, m_b, v, vnew, fext, fext_prev, dt_b, actf, ke, ke0, bal, work
):  # pragma: no cover - compiled
    """Kinetic energy at t^n and the external work (trapezoid; over the first half step f^0 acts on the
    mean velocity (v0 + v^{1/2}) / 2)."""
    if n == 0:
        for w in range(B):
            ke[w] = ke0[w]
        return
    for w in range(B):
        ke[w] = 0.0
        bal[w] = 0.0
    for n_ in range(N):
        for d in range(D):
            for w in range(B):
                ke[w] = kinetic(ke[w], m_b[n_, w], v[n_, d, w], vnew[n_, d, w])
    if ext:
        for n_ in range(N):
            for d in range(D):
                for w in range(B):
                    vb = 0.5 * (v0[n_, d, lo + w] + v[n_, d, w]) if n == 1 else v[n_, d, w]
                    bal[w] = ext_power(bal[w], fext[n_, d, w], v[n_, d, w], fext_prev[n_, d, w], vb)
        for w in range(B):
            work[w] = work_increment(work[w], bal[w], dt_b[w], actf[w])


@stage
def peak_accelerations(B, N, D, movable, acc, actf, pacc):  # pragma: no cover - compiled
    """Peak |a| of the movable nodes: the square is tracked (sqrt is monotonic, the peak is the same)."""
    for n_ in range(N):
        if not movable[n_]:
            continue
        for w in range(B):
            a2 = 0.0
            for d in range(D):
                a2 += acc[n_, d, w] * acc[n_, d, w]
            pacc[n_, w] = peak(pacc[n_, w], a2 * actf[w])


@stage
def knot_accelerations(
    B, D, si, sj, movable, k_any, k_hit, k_th, k_dfax, acc_prev, acc, im_b, actf, pacc
):  # pragma: no cover - compiled
    """|a| at the knot crossings of this step (see the reference)."""
    for s in range(si.shape[0]):
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


@stage
def stop_tests(
    n,
    lo,
    B,
    S,
    opening_ok,
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
):  # pragma: no cover - compiled
    """Early termination (docs/format.md) of the running lanes; returns the step at which the first ends."""
    e_scale = e_init[1]
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
        opening = edot_min[w] >= 0.0 and opening_ok
        if stop_test(ke_fraction[q], fsum, psum, ke[w], e_scale[w], wmax[w], opening):
            nst[w] = n
            n_end = n
    return n_end


@stage
def advance_nodes(B, N, D, x, v, vnew, dt_b, actf):  # pragma: no cover - compiled
    """x^{n+1} and v^{n+1/2} kept; a stopped variant keeps x and v (vnew is finite for it)."""
    for n_ in range(N):
        for d in range(D):
            for w in range(B):
                x[n_, d, w], v[n_, d, w] = advance(x[n_, d, w], v[n_, d, w], vnew[n_, d, w], dt_b[w], actf[w])


@stage
def keep(dst, src):  # pragma: no cover - compiled
    """``dst[...] = src`` for the (N, D, B) node arrays kept for the next step, as a loop: numba compiles
    a slice copy's shape-mismatch message (string formatting, ~5 CPU s of the cold compile)."""
    for n_ in range(min(dst.shape[0], src.shape[0])):  # acc_prev has no rows in a model without knots
        for d in range(src.shape[1]):
            for w in range(src.shape[2]):
                dst[n_, d, w] = src[n_, d, w]
