"""Plain NumPy twin of the compiled kernel: the executable definition of the time integration.

Explicit central difference (docs/solver.md), vectorised over variants, one Python iteration per
time step. It is slow and only meant for tests (the compiled kernel must agree with it) and for
readers: every formula of the compiled kernel appears here once, in the same order.

Per step ``n`` (time ``t = n dt``; ``v`` holds ``v^{n-1/2}``, ``v0`` at ``n = 0``):

1. spring elongations and forces from ``x^n`` (dampers from the second-order estimate
   ``v^n ~ v^{n-1/2} + dt/2 a^{n-1}``); material state update;
2. external forces (loads, gravity) and accelerations ``a^n = f^n / m`` on free dofs;
3. ``v^{n+1/2} = v^{n-1/2} + dt a^n`` (half a step at ``n = 0``), then prescribed motion and
   rigid walls (a node that would cross a wall gets the normal velocity that lands it exactly on
   the plane, and none into it afterwards: a perfectly plastic stonewall impact). The part of that
   jump the node's own forces pushed into the wall (``step_laws.wall_hold``) is the wall's contact force
   and joins the node's acceleration (a held node has a = 0); the rest is the impact impulse. A
   penalty wall (``wall_stiffness`` > 0) has no jump: its force ``k pen`` of ``x^n`` joins the nodal
   forces in step 2 and its stored energy ``k pen^2 / 2`` the wall energy;
4. energies: internal and external work by the trapezoidal rule, kinetic energy as
   ``1/2 m v^{n-1/2} . v^{n+1/2}`` (exactly conserved with the trapezoidal internal energy for a
   linear system), wall energy ``-1/2 v^{n-1/2} . (J^n + J^{n-1})`` for the wall impulses ``J``
   (the discrete work of an impulse, so the balance holds at every step);
5. summaries (every step), histories (every ``out_every`` steps), failure and termination checks;
6. ``x^{n+1} = x^n + dt v^{n+1/2}``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from crashstudy.arrays import material_laws as mat
from crashstudy.kernel.reference_knots import knot_crossing_np, spring_knotted
from crashstudy.kernel.step_twins import (
    energy_balance_np,
    half_step_np,
    prescribed_step_np,
    prescribed_time_np,
    prescribed_velocity_np,
    stop_test_np,
    unstable_limit_np,
    unstable_np,
    wall_gives_np,
    wall_hold_np,
    wall_penalty_np,
)
from crashstudy.vocabulary.codes import (
    CRUSH,
    DAMPER,
    ELASTOPLASTIC,
    GENERAL,
    LINEAR,
    NONLINEAR,
    NONLINEAR_DAMPER,
    PM_DISPLACEMENT,
    RATE_ELASTIC,
    TINY_LENGTH,
    UNSTABLE_ENERGY,
    UNSTABLE_WALLS,
)
from crashstudy.vocabulary.materials import DAMPER_MATERIALS

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

from crashstudy.kernel.output import CRUSHED_TO_ZERO, INVALID, UNSTABLE, KernelOutput, allocate, block_rows

STOP_EVERY = 256  # steps between calls of run_reference's ``check``
__all__ = ["TINY_LENGTH", "UNSTABLE_ENERGY", "run_reference"]


def run_reference(
    b: Batch,
    histories: tuple[str, ...],
    n_out: int,
    check: Callable[[], None] | None = None,
    record: tuple[int, ...] = (),
) -> KernelOutput:
    """Integrate every variant of ``b``; see the module docstring for the step. ``check`` is called
    every ``STOP_EVERY`` steps; it raises to abandon the batch (Ctrl-C). ``record``: nodes whose
    acceleration is kept at every step (``KernelOutput.step_acceleration``, for the crash criteria)."""
    N, D, V = b.x0.shape
    S = len(b.spring_i)
    W = b.wall_nodes.shape[0]
    out = allocate(S, N, D, W, V, histories, n_out)
    rec_nodes = np.asarray(record, dtype=np.int64)
    rk = b.rec_block
    if len(record):
        out.step_acceleration = np.zeros((int(block_rows(b.n_steps, rk).max(initial=0)), len(record), D, V))
    out.status[:] = np.where(b.invalid > 0, INVALID, 0)
    out.fail_item[:] = np.where(b.invalid > 0, b.invalid, -1)
    out.fail_time[:] = np.where(b.invalid > 0, 0.0, np.nan)
    nst = b.n_steps.copy()
    dt = b.dt
    x = b.x0.copy()
    v = b.v0.copy()
    m = b.mass
    state = (
        b.state0.copy() if len(b.state0) else np.zeros((S, mat.NSTATE, V))
    )  # preloaded springs: arrays.preload
    f_prev = np.zeros((S, V))
    e_prev = np.zeros((S, V))
    fext_prev = np.zeros((N, D, V))
    a_prev = np.zeros((N, D, V))  # a^{n-1}: dampers use the second-order velocity v^{n-1/2} + dt/2 a^{n-1}
    jump_prev = np.zeros((W, N, D, V))  # velocity jump of each node at each wall in the previous step
    pen_e = np.zeros((W, N, V))  # energy stored by each node at each penalty wall
    # 2-D: the previous direction of each spring; a reversal means the nodes passed through each other
    axis_prev = (b.x0[b.spring_j] - b.x0[b.spring_i]) if D > 1 else np.zeros((0, D, V))
    ie = b.ie0.copy()  # IE includes the energy stored at t = 0 (initial_elongation)
    ie0 = np.zeros(V)
    for s in range(S):
        ie0 = ie0 + b.ie0[s]
    # preloaded springs (F^0 != 0 only with an initial elongation: every material curve passes the origin)
    first_half = (b.e0 != 0.0) & ~np.isin(b.material, DAMPER_MATERIALS)[:, None]
    broken = np.zeros(
        (S, V), dtype=bool
    )  # springs past a failure elongation: no force for the rest of the run
    work = np.zeros(V)
    wall_e = np.zeros(V)
    wmax = np.zeros(V)
    ke0 = 0.5 * np.sum(m[:, None, :] * b.v0 * b.v0, axis=(0, 1))
    e_init = ke0 + ie0  # the energy at t = 0: KE0 + IE0
    # the scale of the error and the stop tests: KE0 + |IE0| (a preload against a curve that pushes the
    # wrong way stores IE0 < 0; KE0 + IE0 <= 0 would make every step "unstable")
    e_scale = ke0 + np.abs(ie0)
    err = np.zeros(V)
    no_ext = len(b.load_node) == 0 and len(b.pm_node) == 0 and not np.any(b.gravity)
    cargs = (b.cx, b.cy, b.cds, b.cs0, b.curve_off)
    knotted = spring_knotted(b)
    knot_hit = np.zeros((S, V), dtype=bool)  # the spring passed over a knot in this step
    knot_th = np.zeros((S, V))  # crossing fraction of the step at the knot that gave a spring's candidate
    knot_dfax = np.zeros((S, D, V))  # that knot's force minus the force interpolated in time, times the axis
    movable = ~np.all(b.free == 0.0, axis=1)
    movable[b.pm_node] = True
    # a dof driven by a displacement curve: its rate at t^n is v^{n-1/2}, the slope of the segment it is
    # on (no extrapolation by a^{n-1}, which is a velocity jump / dt at a kink of the curve)
    pm_disp = np.zeros((N, D, 1), dtype=bool)
    for k in range(len(b.pm_node)):
        pm_disp[b.pm_node[k], b.pm_dir[k]] = b.pm_kind[k] == PM_DISPLACEMENT

    for n in range(int(nst.max(initial=-1)) + 1):
        if check is not None and n % STOP_EVERY == 0:
            check()
        act = (n <= nst) & (out.status == 0)
        if not act.any():
            break
        t = n * dt
        dtn = dt if n > 0 else 0.5 * dt
        f = np.zeros((N, D, V))
        forces = np.zeros((S, V))
        elong = np.zeros((S, V))
        edot_min = np.full(V, np.inf)
        crushed = np.full(V, -1)
        a_rate = np.where(pm_disp, 0.0, a_prev)
        for s in range(S):
            i, j = b.spring_i[s], b.spring_j[s]
            vpj = v[j] + 0.5 * dt * a_rate[j]
            vpi = v[i] + 0.5 * dt * a_rate[i]
            if D == 1:
                e = b.e0[s] + b.sign[s] * ((x[j, 0] - b.x0[j, 0]) - (x[i, 0] - b.x0[i, 0]))
                edot = b.sign[s] * (vpj[0] - vpi[0])
                axis = b.sign[s][None, :]
            else:
                d = x[j] - x[i]
                length = np.sqrt(np.sum(d * d, axis=0))
                gone = (length <= TINY_LENGTH * b.length0[s]) | (np.sum(d * axis_prev[s], axis=0) <= 0.0)
                crushed = np.where(
                    gone & ~broken[s] & (crushed < 0), s, crushed
                )  # a broken spring may collapse
                axis = d / np.where(gone, 1.0, length)
                axis_prev[s] = d
                e = b.e0[s] + (length - b.length0[s])
                edot = np.sum(axis * (vpj - vpi), axis=0)
            st_before = state[s].copy() if knotted[s] and n > 0 else None
            F = _force(b, s, e, edot, state[s], cargs)
            # failure (docs/format.md): past either elongation the spring breaks, at the interpolated crossing
            snaps = act & ~broken[s] & ((e > b.fail_t[s]) | (e < b.fail_c[s])) & (n > 0)
            limit = np.where(e > b.fail_t[s], b.fail_t[s], b.fail_c[s])
            frac = (limit - e_prev[s]) / np.where(snaps, e - e_prev[s], 1.0)
            out.spring_fail_time[s] = np.where(snaps, (n - 1 + frac) * dt, out.spring_fail_time[s])
            intact = act & ~broken[s]
            broken[s] |= snaps
            F = np.where(broken[s], 0.0, F)
            f[i] += F * axis
            f[j] -= F * axis
            forces[s], elong[s] = F, e
            edot_min = np.minimum(edot_min, edot)
            if n > 0:
                de = e - e_prev[s]
                step_ie = 0.5 * (F + f_prev[s]) * de
                if n == 1 and first_half[s].any():
                    # over the first (half) step F^0 acts on the mean rate (edot^0 + edot^{1/2}) / 2 for dt/2, as
                    # in the external work: exact for a preload released from rest (docs/solver.md, "Energies")
                    half = (0.5 * F + 0.25 * f_prev[s]) * de + 0.25 * dt * f_prev[s] * b.rate0[s]
                    step_ie = np.where(first_half[s], half, step_ie)
                ie[s] += np.where(act, step_ie, 0.0)
            out.peak_force[s] = np.where(act, np.maximum(out.peak_force[s], np.abs(F)), out.peak_force[s])
            if st_before is not None:  # knots passed over since the previous step (docs/solver.md, "Peaks")
                cand, th, dF = knot_crossing_np(b, s, e, e_prev[s], F, f_prev[s], st_before)
                cand = np.where(
                    broken[s], 0.0, cand
                )  # a spring that breaks in this step: the step's ends only
                out.peak_force[s] = np.where(act, np.maximum(out.peak_force[s], cand), out.peak_force[s])
                knot_hit[s], knot_th[s], knot_dfax[s] = cand > 0.0, th, dF * axis
            # extremes while intact; a spring that breaks in this step reached its failure elongation
            e_max = np.where(snaps, limit, e)
            # laws.peak's running maximum (np.maximum(0.0, -0.0) is -0.0: a spring only ever in tension
            # reported a max_crush of -0.0)
            out.max_crush[s] = np.where(intact & (-e_max > out.max_crush[s]), -e_max, out.max_crush[s])
            out.max_elongation[s] = np.where(
                intact & (e_max > out.max_elongation[s]), e_max, out.max_elongation[s]
            )
        f_prev, e_prev = forces, elong

        fext = m[:, None, :] * b.gravity[None, :, :] * np.ones((N, D, 1))
        for k in range(len(b.load_node)):
            c = b.load_curve[k]
            scale = mat.time_curve_eval(c, t, *cargs) if c >= 0 else 1.0
            fext[b.load_node[k]] += b.load_force[k] * scale
        wall_force = np.zeros((W, V))
        for w in range(W):  # penalty walls (wall_stiffness > 0; 0: the law gives an exact 0)
            for k in range(N):
                if b.wall_nodes[w, k] == 0.0:
                    continue
                gap = np.sum((x[k] - b.wall_point[w]) * b.wall_normal[w], axis=0)
                fp, ep = wall_penalty_np(b.wall_stiffness[w], gap)
                f[k] += fp * b.wall_normal[w]
                wall_force[w] += fp
                wall_e += np.where(act, ep - pen_e[w, k], 0.0)
                pen_e[w, k] = ep
        ftot = f + fext
        a = ftot * b.inv_mass
        vnew = half_step_np(v, a, dtn)

        for k in range(len(b.pm_node)):
            p, d, c = b.pm_node[k], b.pm_dir[k], b.pm_curve[k]
            tc = mat.time_curve_eval(c, prescribed_time_np(b.pm_kind[k], t, dt), *cargs)
            vn = prescribed_velocity_np(
                b.pm_kind[k], b.x0[p, d], b.pm_scale[k], tc, x[p, d], v[p, d], dt, dtn
            )
            vnew[p, d], a[p, d] = prescribed_step_np(n == nst, vn, v[p, d], a_prev[p, d], dtn)
            fext[p, d] += m[p] * a[p, d] - ftot[p, d]

        for w in range(W):
            for k in range(N):
                if b.wall_nodes[w, k] == 0.0:
                    continue
                nrm = b.wall_normal[w]
                vn = np.sum(vnew[k] * nrm, axis=0)
                gap = np.sum((x[k] - b.wall_point[w]) * nrm, axis=0)
                dist = np.sum((x[k] + dt * vnew[k] - b.wall_point[w]) * nrm, axis=0)
                hit = (dist < 0.0) & (vn < 0.0) & (b.wall_stiffness[w] == 0.0)
                dvn = np.where(hit, -gap / dt - vn, 0.0)  # lands the node exactly on the plane
                c = wall_hold_np(dvn, np.sum(a[k] * nrm, axis=0), dtn)
                jump = dvn * nrm * b.free[k][:, None]
                vnew[k] = vnew[k] + jump
                a[k] = a[k] + c * nrm * b.free[k][:, None]  # the contact force's part: a held node has a = 0
                # wall work of the impulses of this and the previous step, at v^{n-1/2}
                wall_e += np.where(act, -0.5 * m[k] * np.sum(v[k] * (jump + jump_prev[w, k]), axis=0), 0.0)
                wall_force[w] += m[k] * c
                imp = dvn - c * dtn
                out.wall_impulse[w] += np.where(act, m[k] * np.where(imp > 0.0, imp, 0.0), 0.0)
                jump_prev[w, k] = jump

        if n == 0:
            ke = ke0.copy()
        else:
            ke = 0.5 * np.sum(m[:, None, :] * v * vnew, axis=(0, 1))
            # trapezoid; over the first (half) step f^0 acts on the mean velocity (v0 + v^{1/2}) / 2 for dt/2
            vbar = 0.5 * (b.v0 + v) if n == 1 else v
            work += np.where(act, 0.5 * np.sum(fext * v + fext_prev * vbar, axis=(0, 1)) * dt, 0.0)
        wmax = np.maximum(wmax, np.abs(work))
        ie_tot = np.sum(ie, axis=0)
        # the t = 0 balance is the state before any impact: an impulse of the first step is counted from
        # step 1 on, where v^{1/2} after it is in the kinetic energy (wall_e itself keeps the reference's sum)
        wall_now = wall_e if n > 0 else np.zeros_like(wall_e)
        bal = energy_balance_np(ke, ie_tot, wall_now, e_init, work)
        err = np.where(act, np.maximum(err, bal), err)
        amag = np.sqrt(np.sum(a * a, axis=1))
        out.peak_acceleration[:] = np.where(
            act, np.maximum(out.peak_acceleration, amag), out.peak_acceleration
        )
        for s in range(S if n > 0 else 0):
            if not knotted[s]:
                continue
            # the node acceleration at the knot crossing: linear in time between the steps, plus the jump
            # of the kinked spring's force from its own linear interpolation (second order)
            th = knot_th[s]
            for p, sgn in ((b.spring_i[s], 1.0), (b.spring_j[s], -1.0)):
                if not movable[p]:
                    continue
                corr = knot_dfax[s] * b.inv_mass[p]
                ai = (1.0 - th) * a_prev[p] + th * a[p]
                ai = ai + corr if sgn > 0 else ai - corr
                amag = np.sqrt(np.sum(ai * ai, axis=0))
                out.peak_acceleration[p] = np.where(
                    act & knot_hit[s], np.maximum(out.peak_acceleration[p], amag), out.peak_acceleration[p]
                )
        out.peak_wall_force[:] = np.where(
            act, np.maximum(out.peak_wall_force, wall_force), out.peak_wall_force
        )

        limit = unstable_limit_np(e_scale, wmax, b.energy_floor)
        lost = act & unstable_np(bal, limit)
        gives = act & ~lost & wall_gives_np(wall_now, limit)  # the balance held (fail_item names the test)
        bad = lost | gives
        out.status[:] = np.where(bad, UNSTABLE, out.status)
        out.fail_item[:] = np.where(gives, UNSTABLE_WALLS, out.fail_item)
        gone = act & ~bad & (crushed >= 0)
        out.status[:] = np.where(gone, CRUSHED_TO_ZERO, out.status)
        out.fail_item[:] = np.where(gone, crushed, out.fail_item)
        out.fail_time[:] = np.where(bad | gone, t, out.fail_time)
        ok = act & ~bad & ~gone
        if out.step_acceleration is not None:  # block sums, added in step order (as the fast kernels)
            q = np.flatnonzero(ok)
            out.step_acceleration[(n + (rk[q] - 1) // 2) // rk[q], :, :, q] += a[rec_nodes][
                :, :, q
            ].transpose(2, 0, 1)

        rec = (
            ok & (n % b.out_every == 0) & (n // b.out_every < n_out)
        )  # the last step may pass the last sample
        if rec.any() and histories:
            _record(
                out,
                rec,
                n // b.out_every,
                x,
                b.x0,
                0.5 * (v + vnew) if n > 0 else b.v0,
                a,
                forces,
                elong,
                ke,
                ie_tot,
                work,
                wall_now,
                wall_force,
            )
        out.t_end[:] = np.where(ok, t, out.t_end)
        last = ok & (n == nst)
        if b.ke_fraction.any():
            opening = (edot_min >= 0.0) & no_ext
            small = stop_test_np(
                b.ke_fraction,
                np.sum(np.abs(forces), axis=0),
                np.sum(out.peak_force, axis=0),
                ke,
                e_scale,
                wmax,
                opening,
            )
            stop = ok & (b.ke_fraction > 0) & (t >= b.min_time) & small & (n > 0)
            nst = np.where(stop, n, nst)
            last |= stop
        out.final_energy[:, last] = np.stack([ke, ie_tot, work, wall_e])[:, last]

        x = np.where(ok, x + dt * vnew, x)
        v = np.where(ok, vnew, v)
        a_prev = a
        fext_prev = fext

    out.absorbed_energy[:] = ie
    out.energy_error[:] = err / np.maximum(e_scale + wmax, 1e-300)
    return out


def _force(b: Batch, s: int, e: np.ndarray, edot: np.ndarray, st: np.ndarray, cargs: tuple) -> np.ndarray:
    kind = b.material[s]
    if kind == LINEAR:
        return b.kpar[s] * e
    if kind == DAMPER:
        return b.kpar[s] * edot
    if kind == NONLINEAR:
        return mat.curve_eval(int(b.curve_a[s]), e, *cargs)
    if kind == CRUSH:
        return mat.crush(e, st, int(b.curve_a[s]), b.kpar[s], *cargs)
    if kind == ELASTOPLASTIC:
        return mat.elastoplastic(e, st, b.kpar[s], b.ktan[s], b.fy[s])
    if kind == NONLINEAR_DAMPER:
        return mat.curve_eval(int(b.curve_a[s]), edot, *cargs)
    if kind == RATE_ELASTIC:
        a, z = int(b.rate_off[s]), int(b.rate_off[s + 1])
        return mat.rate_elastic(e, edot, b.rate_curve[a:z], b.rate_at[a:z], *cargs)
    if kind == GENERAL:
        cx, cy, cds, cs0, off = cargs
        return mat.general_nonlinear(
            e,
            st,
            int(b.curve_a[s]),
            int(b.curve_b[s]),
            b.yield_t[s],
            b.yield_c[s],
            cx,
            cy,
            cds,
            cs0,
            b.cs1,
            off,
        )
    raise ValueError(f"unknown material code {kind}")


def _record(
    out: KernelOutput,
    rec: np.ndarray,
    k: np.ndarray,
    x,
    x0,
    vel,
    a,
    forces,
    elong,
    ke,
    ie,
    work,
    wall_e,
    wall_force,
) -> None:
    cols = np.nonzero(rec)[0]
    rows = k[cols]
    values = {
        "position": x,
        "displacement": x - x0,
        "velocity": vel,
        "acceleration": a,
        "spring_force": forces,
        "spring_elongation": elong,
        "kinetic_energy": ke,
        "internal_energy": ie,
        "external_work": work,
        "wall_energy": wall_e,
        "wall_force": wall_force,
    }
    for name, arr in out.histories.items():
        src = values[name]
        arr[rows, ..., cols] = np.moveaxis(src[..., cols], -1, 0)
