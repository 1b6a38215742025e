"""Hand-specialised reference loop for ``studies/models/frontal-9mass.yaml`` (benchmarks only).

What the hardware gives for this one model: the topology is hard-coded (which nodes each spring
joins, which material it has), the curves' shapes are compile-time constants (the crush springs' curve
scale and x_scale and the flange's stiffness come per variant: a study's curve axes), and one fused loop over the
variants of a block (innermost, contiguous, ``BLOCK`` columns) does every spring, every node update
and every summary of a time step, with branch-free curves and material laws (selects, ``min``/``max``)
so that LLVM can put several variants in one SIMD instruction. It computes the same physics as the
generic kernel (central difference, docs/format.md and docs/solver.md; summaries as
:mod:`crashstudy.kernel.compiled`) and takes the same per-variant steps, so element-steps are equal;
``check_against_generic`` compares peak forces.

Nodes (1-D, all springs drawn left to right so ``e = u_j - u_i``):
0 barrier (fixed), 1 bumper, 2 radiator, 3 engine, 4 engine_mount, 5 front_wheel, 6 transmission,
7 aft_frame, 8 survival_room.
Springs: 0 crash-box (0-1, crush), 1 front-rail (1-5, crush), 2 rear-rail (5-7, crush),
3 occupant-cell (7-8, general_nonlinear), 4 radiator-support (1-2, crush), 5 engine-stackup (2-3,
crush), 6 engine-mount (3-4, general_nonlinear), 7 gearbox-flange (3-6, linear).

The two general_nonlinear springs have monotone loading curves and straight unloading lines through
the origin, so the curve inverses of rules 3-4 are ramp sums too (no search, no branch).

Modules: this one (the block loop and the entry :func:`run_specialised`, :func:`set_threads`),
frontal_step.py (one time step), frontal_laws.py (the branch-free curves, material laws, summaries and
node update) and frontal_constants.py (the model's topology and constants, the work array's rows)."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba as nb
import numpy as np

from crashstudy.kernel.output import KernelOutput, allocate
from frontal_constants import (
    BLOCK,
    CRUSH_SPRINGS,
    N_NODES,
    N_ROWS,
    N_SPRINGS,
    R_AH,
    R_DT,
    R_EH,
    R_ERR,
    R_FH,
    R_IE,
    R_IEEND,
    R_IEH,
    R_IM,
    R_IX,
    R_KE0,
    R_KEEND,
    R_KEH,
    R_KF,
    R_M,
    R_MC,
    R_NST,
    R_PA,
    R_PF,
    R_UH,
    R_V,
    R_VH,
    R_YS,
    ROW,
    SPRING_NODES,
)
from frontal_laws import _max
from frontal_step import _step


@nb.njit(nogil=True, error_model="numpy", cache=True)
def _run_blocks(
    b_lo,
    b_hi,
    starts,
    record,
    mass,
    inv_mass,
    x0,
    v0,
    dt,
    n_steps,
    out_every,
    n_out,
    ys,
    ixs,
    kf,
    h_pos,
    h_disp,
    h_vel,
    h_acc,
    h_force,
    h_elong,
    h_energy,
    peak_force,
    max_crush,
    absorbed,
    peak_acc,
    energy_error,
    final_energy,
    t_end,
):  # pragma: no cover
    N = 9
    S = 8
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        Z = np.zeros(N_ROWS * ROW)  # row r of the block: Z[r * ROW : r * ROW + BLOCK]
        next_rec = np.zeros(B, dtype=np.int64)
        for n_ in range(N):
            for w in range(B):
                Z[(R_M + n_) * ROW + w] = mass[n_, lo + w]
                Z[(R_IM + n_) * ROW + w] = inv_mass[n_, 0, lo + w]
                Z[(R_V + n_) * ROW + w] = v0[n_, 0, lo + w]
        for k in range(5):
            for w in range(B):
                Z[(R_YS + k) * ROW + w] = ys[k, lo + w]
                Z[(R_IX + k) * ROW + w] = ixs[k, lo + w]
        nmax = 0
        for w in range(B):
            Z[R_KF * ROW + w] = kf[lo + w]
            Z[R_DT * ROW + w] = dt[lo + w]
            Z[R_NST * ROW + w] = n_steps[lo + w]
            nmax = max(nmax, n_steps[lo + w])
        for n_ in range(N):
            for w in range(B):
                Z[R_KE0 * ROW + w] += (
                    0.5 * Z[(R_M + n_) * ROW + w] * Z[(R_V + n_) * ROW + w] * Z[(R_V + n_) * ROW + w]
                )
        for n in range(nmax + 1):
            rec_now = False
            if record:
                for w in range(B):
                    rec_now = rec_now or (n == next_rec[w] and n <= n_steps[lo + w])
            if not rec_now:
                _step(Z, B, n, False)
                continue
            _step(Z, B, n, True)
            for w in range(B):
                q = lo + w
                if n != next_rec[w] or n > n_steps[q]:
                    continue
                r = n // out_every[q]
                next_rec[w] = n + out_every[q]
                if r >= n_out:
                    continue
                for n_ in range(N):
                    h_pos[r, n_, 0, q] = x0[n_, 0, q] + Z[(R_UH + n_) * ROW + w]
                    h_disp[r, n_, 0, q] = Z[(R_UH + n_) * ROW + w]
                    h_vel[r, n_, 0, q] = Z[(R_VH + n_) * ROW + w]
                    h_acc[r, n_, 0, q] = Z[(R_AH + n_) * ROW + w]
                for s in range(S):
                    h_force[r, s, q] = Z[(R_FH + s) * ROW + w]
                    h_elong[r, s, q] = Z[(R_EH + s) * ROW + w]
                h_energy[r, 0, q] = Z[R_KEH * ROW + w]
                h_energy[r, 1, q] = Z[R_IEH * ROW + w]
                h_energy[r, 2, q] = 0.0
                h_energy[r, 3, q] = 0.0
        for w in range(B):
            q = lo + w
            energy_error[q] = Z[R_ERR * ROW + w] / _max(Z[R_KE0 * ROW + w], 1e-300)
            t_end[q] = n_steps[q] * Z[R_DT * ROW + w]
            final_energy[0, q] = Z[R_KEEND * ROW + w]
            final_energy[1, q] = Z[R_IEEND * ROW + w]
            for s in range(S):
                peak_force[s, q] = Z[(R_PF + s) * ROW + w]
                max_crush[s, q] = Z[(R_MC + s) * ROW + w]
                absorbed[s, q] = Z[(R_IE + s) * ROW + w]
            for n_ in range(N):
                peak_acc[n_, q] = np.sqrt(Z[(R_PA + n_) * ROW + w])


_THREADS = [os.cpu_count() or 1]


def set_threads(n: int) -> None:
    """Threads the specialised loop uses (blocks spread over a thread pool, as the generic kernel)."""
    _THREADS[0] = max(1, int(n))


def run_specialised(b: Any, histories: tuple[str, ...], n_out: int, block: int = BLOCK) -> KernelOutput:
    """Run the frontal model's variants of batch ``b`` (a :class:`crashstudy.arrays.batch.Batch` built from
    frontal-9mass.yaml) with the specialised loop; histories all or none."""
    N, D, V = b.x0.shape
    assert (N, D, len(b.spring_i)) == (N_NODES, 1, N_SPRINGS), "not the frontal model"
    assert np.array_equal(np.stack([b.spring_i, b.spring_j], axis=1), np.array(SPRING_NODES)), (
        "not the frontal model"
    )
    assert np.all(b.sign == 1.0) and np.all(b.invalid == 0)
    record = len(histories) > 0
    out = allocate(N_SPRINGS, N_NODES, 1, 0, V, histories, n_out)
    h_energy = np.full((n_out, 4, V), np.nan) if record else np.empty((1, 4, 1))

    def buf(name: str, nd: int) -> np.ndarray:
        return out.histories[name] if name in out.histories else np.empty((1,) * nd)

    starts = np.unique(np.minimum(np.arange(0, V + block, block), V)).astype(np.int64)
    curves = b.curve_a[list(CRUSH_SPRINGS)]
    others = [c for c in range(b.cfac.shape[1]) if c not in set(curves.tolist())]
    assert np.all(b.cfac[:2, others] == 1.0), "the loop scales the crush springs' curves only"
    ys, ixs = np.ascontiguousarray(b.cfac[0, curves]), np.ascontiguousarray(1.0 / b.cfac[1, curves])
    args = (
        starts,
        record,
        b.mass,
        b.inv_mass,
        b.x0,
        b.v0,
        b.dt,
        b.n_steps,
        b.out_every,
        n_out,
        ys,
        ixs,
        np.ascontiguousarray(b.kpar[7]),
        buf("position", 4),
        buf("displacement", 4),
        buf("velocity", 4),
        buf("acceleration", 4),
        buf("spring_force", 3),
        buf("spring_elongation", 3),
        h_energy,
        out.peak_force,
        out.max_crush,
        out.absorbed_energy,
        out.peak_acceleration,
        out.energy_error,
        out.final_energy,
        out.t_end,
    )
    nblocks = len(starts) - 1
    threads = min(_THREADS[0], nblocks)
    if threads <= 1:
        _run_blocks(0, nblocks, *args)
    else:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda bi: _run_blocks(bi, bi + 1, *args), range(nblocks)))
    for k, name in enumerate(("kinetic_energy", "internal_energy", "external_work", "wall_energy")):
        if name in out.histories:
            out.histories[name][:] = h_energy[:, k, :]
    return out
