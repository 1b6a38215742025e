"""Walls in the generic compiled kernel (:mod:`crashstudy.kernel.compiled`): the penalty walls' forces
before the accelerations, the rigid walls' velocity jumps after them (docs/solver.md, "Rigid walls").

The NumPy reference (:mod:`crashstudy.kernel.reference`) is the twin; every formula is a law of
:mod:`crashstudy.kernel.laws`. A wall's ``wall_stiffness`` is per variant: 0 a rigid wall (the
penalty law gives an exact 0), > 0 a penalty wall (the rigid jump is 0).
"""

from __future__ import annotations

from crashstudy.kernel import step_laws as sl
from crashstudy.kernel.generic_block import stage


@stage
def gap_of(x, wall_point, wall_normal, wl, n_, w, q, D):  # pragma: no cover - compiled
    """Distance of node ``n_`` (lane ``w``, variant ``q``) from wall ``wl``'s plane, along its normal."""
    gap = 0.0
    for d in range(D):
        gap += (x[n_, d, w] - wall_point[wl, d, q]) * wall_normal[wl, d, q]
    return gap


@stage
def penalty(
    lo, B, W, N, D, wall_nodes, wall_normal, wall_point, wall_k, x, f, wforce, wall_e, pen_e, act
):  # pragma: no cover
    """Penalty walls: the contact force ``k pen`` of x^n joins the nodal forces ``f``; the wall force
    (``wforce``, zeroed here) sums it; ``wall_e`` takes the change of the stored energy ``k pen^2 / 2``."""
    for wl in range(W):
        for w in range(B):
            wforce[wl, w] = 0.0
    for wl in range(W):
        for n_ in range(N):
            if wall_nodes[wl, n_] == 0.0:
                continue
            for w in range(B):
                fp, ep = sl.wall_penalty(
                    wall_k[wl, lo + w], gap_of(x, wall_point, wall_normal, wl, n_, w, lo + w, D)
                )
                q = lo + w
                for d in range(D):
                    f[n_, d, w] += fp * wall_normal[wl, d, q]
                wforce[wl, w] += fp
                if act[w]:
                    wall_e[w] += ep - pen_e[wl, n_, w]
                pen_e[wl, n_, w] = ep


@stage
def rigid(
    lo,
    B,
    W,
    N,
    D,
    h,
    wall_nodes,
    wall_normal,
    wall_point,
    wall_k,
    free,
    x,
    v,
    vnew,
    acc,
    m_b,
    dt_b,
    jump_prev,
    wall_e,
    wforce,
    wall_impulse,
    act,
    actf,
):  # pragma: no cover
    """Rigid walls: land a node crossing the plane on it; the held part of the jump is the contact force
    (added to ``wforce`` and to the node's acceleration), the rest the impact impulse."""
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
                    vn, gap, dist = sl.wall_plane(
                        vn,
                        gap,
                        dist,
                        vnew[n_, d, w],
                        x[n_, d, w],
                        wall_point[wl, d, q],
                        wall_normal[wl, d, q],
                        dt_b[w],
                    )
                dvn = sl.wall_jump(vn, gap, dist, dt_b[w], wall_k[wl, q])
                an = 0.0
                for d in range(D):
                    an += acc[n_, d, w] * wall_normal[wl, d, q]
                c = sl.wall_hold(dvn, an, h * dt_b[w])
                we = 0.0
                for d in range(D):
                    vnew[n_, d, w], acc[n_, d, w], we, jump_prev[wl, n_, d, w] = sl.wall_dof(
                        dvn,
                        c,
                        wall_normal[wl, d, q],
                        free[n_, d],
                        vnew[n_, d, w],
                        acc[n_, d, w],
                        v[n_, d, w],
                        jump_prev[wl, n_, d, w],
                        we,
                    )
                if act[w]:
                    wall_e[w] += sl.wall_work(m_b[n_, w], we)
                wforce[wl, w] += sl.wall_force(m_b[n_, w], c)
                wall_impulse[wl, q] += sl.wall_impulse(m_b[n_, w], dvn, c, h * dt_b[w]) * actf[w]
