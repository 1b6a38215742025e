"""The generic compiled (numba) kernel: the reference step of :mod:`crashstudy.kernel.reference`, with
the loop over variants innermost, topology read from arrays at run time.

Variants are cut into blocks of at most ``BLOCK`` columns (:mod:`crashstudy.kernel.driver` runs the
blocks on a thread pool; the compiled function releases the GIL) and each block advances all its
variants through time together, so the innermost loops run over contiguous variant columns and the
CPU works on several variants per instruction. Every variant keeps its own step ``dt``, so its
result does not depend on which block it lands in.

The step is in stages: springs (:mod:`crashstudy.kernel.generic_springs`), then nodes, energies,
checks, histories, termination and the position update (:mod:`crashstudy.kernel.generic_nodes`);
every formula is a law of :mod:`crashstudy.kernel.laws`. What a model does not contain is skipped:
no material state without ``general_nonlinear``/``crush``, no geometry in 1-D, no wall, load or
prescribed-motion loops when there are none, no history writes when no history is kept.
"""

from __future__ import annotations

from collections import namedtuple
from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from crashstudy.kernel import generic_nodes as gn
from crashstudy.kernel.codes import CURVE_MATERIALS, INVALID, NSTATE, STATE_MATERIALS
from crashstudy.kernel.driver import (
    block_starts,
    finish,
    get_threads,
    outputs,
    records,
    run_blocks,
    set_threads,
)
from crashstudy.kernel.generic_springs import springs
from crashstudy.kernel.output import KernelOutput

if TYPE_CHECKING:
    from crashstudy.batch import Batch

BLOCK = 256
__all__ = ["BLOCK", "get_threads", "run_compiled", "set_threads"]

# block-local copies of the per-variant inputs (contiguous, cache-resident)
BlockIn = namedtuple("BlockIn", ("m", "im", "x0", "sg", "l0", "kp", "cx", "cy", "ds", "ky", "s0", "yt", "yc", "dt"))
# the block's state: kinematics, spring state and summaries, knot-crossing data, per-lane scratch
BlockState = namedtuple("BlockState", (
    "x", "v", "vnew", "f", "fext", "fext_prev", "acc", "acc_prev", "axis_prev", "state", "forces", "elong", "f_prev",
    "e_prev", "ie", "pf", "mc", "pacc", "pwall", "wforce", "jump_prev", "pm_acc", "k_sh", "k_c", "k_x", "k_y",
    "k_any", "k_hit", "k_th", "k_dfax", "g_arg", "g_argt", "g_argc", "g_L", "g_Ut", "g_Uc", "g_rev", "e_tmp",
    "ed_tmp", "F_tmp", "ax_tmp", "edot_min", "crushed", "work", "wall_e", "wmax", "ke0", "ke", "ie_tot", "err",
    "bal", "act", "actf", "n_fail", "nst", "next_rec", "st_ok", "movable", "knotted",
    # v2 spring features: max elongation, broken springs, KE0 + IE0, (preloaded, breakable) per spring, and
    # the elongation / activity the extremes of a breakable spring take in this step
    "me", "broken", "e_init", "v2", "ftmp"))  # fmt: skip


@nb.njit(cache=True, nogil=True)
def _block_inputs(lo, B, T, P):  # pragma: no cover - compiled
    N, D, _ = P.x0.shape
    S = T.spring_i.shape[0]
    K = P.cx.shape[0]
    C = P.cs0.shape[0]
    In = BlockIn(np.empty((N, B)), np.empty((N, D, B)), np.empty((N, D, B)), np.empty((S, B)), np.empty((S, B)),
                np.empty((S, B)), np.empty((K, B)), np.empty((K, B)), np.empty((K, B)), np.empty((K, B)),
                np.empty((C, B)), np.empty((S, B)), np.empty((S, B)), np.empty(B))  # fmt: skip
    for w in range(B):
        In.dt[w] = P.dt[lo + w]
    for n_ in range(N):
        for w in range(B):
            In.m[n_, w] = P.mass[n_, lo + w]
        for d in range(D):
            for w in range(B):
                In.im[n_, d, w] = P.inv_mass[n_, d, lo + w]
                In.x0[n_, d, w] = P.x0[n_, d, lo + w]
    for s in range(S):
        for w in range(B):
            In.sg[s, w] = P.sign[s, lo + w]
            In.yt[s, w] = P.yield_t[s, lo + w]
            In.yc[s, w] = P.yield_c[s, lo + w]
            In.l0[s, w] = P.length0[s, lo + w]
            In.kp[s, w] = P.kpar[s, lo + w]
    for k in range(K):
        for w in range(B):
            In.cx[k, w] = P.cx[k, lo + w]
            In.cy[k, w] = P.cy[k, lo + w]
            In.ds[k, w] = P.cds[k, lo + w]
            In.ky[k, w] = P.knot_y[k, lo + w]
    for c in range(C):
        for w in range(B):
            In.s0[c, w] = P.cs0[c, lo + w]
    return In


@nb.njit(cache=True, nogil=True)
def _block_state(lo, B, T, P, In):  # pragma: no cover - compiled
    N, D, _ = P.x0.shape
    S = T.spring_i.shape[0]
    W = T.wall_nodes.shape[0]
    NP = T.pm_node.shape[0]
    off = T.curve_off
    has_state = False
    movable = np.zeros(N, dtype=np.bool_)
    for n_ in range(N):
        for d in range(D):
            if T.free[n_, d] > 0.0:
                movable[n_] = True
    for k in range(NP):
        movable[T.pm_node[k]] = True
    # springs whose curve has a knot that can be a local maximum of |force| (Batch.knot_check)
    knotted = np.zeros(S, dtype=np.bool_)
    any_knot = False
    for s in range(S):
        has_state = has_state or T.material[s] in STATE_MATERIALS
        ca = T.curve_a[s]
        if T.material[s] in CURVE_MATERIALS and ca >= 0:
            for k in range(off[ca] + 1, off[ca + 1] - 1):
                if T.knot_check[k]:
                    knotted[s] = True
                    any_knot = True
    SK = S if any_knot else 0
    NK = N if any_knot else 0
    SS = S if has_state else 0
    axis_prev = np.zeros((S if D > 1 else 0, D, B))  # 2-D: previous spring direction (un-normalised)
    if D > 1:
        for s in range(S):
            for d in range(D):
                for w in range(B):
                    axis_prev[s, d, w] = In.x0[T.spring_j[s], d, w] - In.x0[T.spring_i[s], d, w]
    Z = BlockState(
        np.empty((N, D, B)), np.empty((N, D, B)), np.empty((N, D, B)), np.empty((N, D, B)), np.zeros((N, D, B)),
        np.zeros((N, D, B)), np.zeros((N, D, B)), np.zeros((NK, D, B)), axis_prev,
        np.zeros((SS, NSTATE, B)), np.zeros((S, B)), np.zeros((S, B)), np.zeros((S, B)),
        np.zeros((S, B)), np.zeros((S, B)), np.zeros((S, B)), np.zeros((S, B)), np.zeros((N, B)), np.zeros((W, B)),
        np.zeros((W, B)), np.zeros((W, N, D, B)), np.zeros((NP, B)), np.empty(B), np.empty(B), np.empty(B),
        np.empty(B), np.zeros(S, dtype=np.bool_), np.zeros((SK, B), dtype=np.bool_), np.zeros((SK, B)),
        np.zeros((SK, D, B)), np.empty(B), np.empty(B), np.empty(B), np.empty(B), np.empty(B), np.empty(B),
        np.zeros(B, dtype=np.bool_), np.empty(B), np.empty(B), np.empty(B), np.empty((D, B)), np.empty(B),
        np.empty(B, dtype=np.int64), np.zeros(B), np.zeros(B), np.zeros(B), np.zeros(B), np.zeros(B), np.zeros(B),
        np.zeros(B), np.zeros(B), np.empty(B, dtype=np.bool_), np.empty(B), np.full(B, -1, dtype=np.int64),
        np.empty(B, dtype=np.int64), np.zeros(B, dtype=np.int64), np.zeros(B, dtype=np.int64), movable, knotted,
        np.zeros((S, B)), np.zeros((S, B), dtype=np.bool_), np.zeros(B), np.zeros((2, S), dtype=np.bool_),
        np.empty((2, B)),
    )  # fmt: skip
    for n_ in range(N):
        for d in range(D):
            for w in range(B):
                Z.x[n_, d, w] = In.x0[n_, d, w]
                Z.v[n_, d, w] = P.v0[n_, d, lo + w]
                Z.ke0[w] += 0.5 * In.m[n_, w] * Z.v[n_, d, w] * Z.v[n_, d, w]
    _preload(lo, B, S, SS, P, Z)
    return Z


@nb.njit(cache=True, nogil=True)
def _preload(lo, B, S, SS, P, Z):  # pragma: no cover - compiled
    """Initial elongations and failures (docs/format.md): the material state and IE0 of the batch
    (kernel.preload), KE0 + IE0, and which springs are preloaded or can break in this block."""
    for s in range(S):
        for w in range(B):
            q = lo + w
            Z.ie[s, w] = P.ie0[s, q]
            Z.v2[0, s] = Z.v2[0, s] or P.e0[s, q] != 0.0
            Z.v2[1, s] = Z.v2[1, s] or P.fail_t[s, q] < np.inf or P.fail_c[s, q] > -np.inf
    if SS > 0 and P.state0.shape[0] > 0:
        for s in range(S):
            for k in range(NSTATE):
                for w in range(B):
                    Z.state[s, k, w] = P.state0[s, k, lo + w]
    for w in range(B):
        ie0 = 0.0
        for s in range(S):
            ie0 = ie0 + P.ie0[s, lo + w]
        Z.e_init[w] = Z.ke0[w] + ie0


@nb.njit(cache=True, nogil=True)
def _run(b_lo, b_hi, starts, n_out, T, P, H, Out):  # pragma: no cover - compiled
    """Blocks ``b_lo:b_hi``: records of :mod:`crashstudy.kernel.driver` (T topology, P per-variant
    inputs, H histories, Out summaries)."""
    N, D, _ = P.x0.shape
    has_gravity = False
    for d in range(D):
        for q in range(P.gravity.shape[1]):
            has_gravity = has_gravity or P.gravity[d, q] != 0.0
    no_ext = T.load_node.shape[0] == 0 and T.pm_node.shape[0] == 0 and not has_gravity
    any_hist = False
    for h in range(H.rec.shape[0]):
        any_hist = any_hist or H.rec[h]
    has_term = False
    for q in range(P.ke_fraction.shape[0]):
        has_term = has_term or P.ke_fraction[q] > 0.0
    # 1-D models without walls, prescribed motion or external forces take a fused node update
    fused_1d = D == 1 and T.wall_nodes.shape[0] == 0 and no_ext
    for bi in range(b_lo, b_hi):
        lo = starts[bi]
        B = starts[bi + 1] - lo
        In = _block_inputs(lo, B, T, P)
        Z = _block_state(lo, B, T, P, In)
        nmax = -1
        for w in range(B):
            q = lo + w
            Z.nst[w] = P.n_steps[q]
            if P.invalid[q] > 0:
                Z.st_ok[w] = INVALID
                Out.fail_item[q] = P.invalid[q]
                Out.fail_time[q] = 0.0
            elif Z.nst[w] > nmax:
                nmax = Z.nst[w]
        for n in range(nmax + 1):
            nact = 0
            n_end = nmax + 1  # the first step at which an active variant ends
            for w in range(B):
                a_ = (n <= Z.nst[w]) & (Z.st_ok[w] == 0)
                Z.act[w] = a_
                Z.actf[w] = 1.0 if a_ else 0.0  # arithmetic masks vectorise
                nact += a_
                n_end = min(n_end, Z.nst[w] if a_ else nmax + 1)
            if nact == 0:
                break
            rec_now = False
            if any_hist:
                for w in range(B):
                    rec_now = rec_now or (Z.act[w] and n == Z.next_rec[w])
            fused = fused_1d and n > 0 and not rec_now
            h = 1.0 if n > 0 else 0.5
            Z.f[:] = 0.0
            Z.crushed[:] = -1
            Z.edot_min[:] = np.inf
            Z.ie_tot[:] = 0.0
            any_hit = springs(n, lo, B, D, has_term, T, P, In, Z, Out)
            if any_hit:  # a^{n-1}, for the accelerations at this step's knot crossings
                Z.acc_prev[:] = Z.acc
            if fused:
                gn.fused_1d(h, B, In, Z)
            else:
                gn.nodes(n, h, lo, B, no_ext, has_gravity, T, P, In, Z)
            gn.energies(n, lo, B, fused, no_ext, P, In, Z)
            gn.checks(n, lo, B, D, fused, any_hit, T, P, In, Z, Out)
            if any_hist:
                gn.record(n, lo, B, n_out, P, In, Z, H)
            if has_term and n > 0:
                n_end = gn.terminate(n, n_end, lo, B, no_ext, P, In, Z)
            for w in range(B):
                if n != n_end:
                    break
                if Z.act[w] and n == Z.nst[w]:
                    q = lo + w
                    Out.final_energy[0, q] = Z.ke[w]
                    Out.final_energy[1, q] = Z.ie_tot[w]
                    Out.final_energy[2, q] = Z.work[w]
                    Out.final_energy[3, q] = Z.wall_e[w]
            gn.advance(B, fused, no_ext, In, Z)
        _results(lo, B, In, Z, Out)


@nb.njit(cache=True, nogil=True)
def _results(lo, B, In, Z, Out):  # pragma: no cover - compiled
    for w in range(B):
        q = lo + w
        Out.status[q] = Z.st_ok[w]
        Out.energy_error[q] = Z.err[w] / max(Z.e_init[w] + Z.wmax[w], 1e-300)
        if Z.st_ok[w] == 0:
            Out.t_end[q] = Z.nst[w] * In.dt[w]
        elif Z.n_fail[w] > 0:
            Out.t_end[q] = (Z.n_fail[w] - 1) * In.dt[w]
    for s in range(Z.ie.shape[0]):
        for w in range(B):
            Out.absorbed[s, lo + w] = Z.ie[s, w]
            Out.peak_force[s, lo + w] = Z.pf[s, w]
            Out.max_crush[s, lo + w] = Z.mc[s, w]
            Out.max_elongation[s, lo + w] = Z.me[s, w]
    for n_ in range(Z.pacc.shape[0]):
        for w in range(B):
            Out.peak_acc[n_, lo + w] = np.sqrt(Z.pacc[n_, w])
    for wl in range(Z.pwall.shape[0]):
        for w in range(B):
            Out.peak_wall[wl, lo + w] = Z.pwall[wl, w]


def run_compiled(b: Batch, histories: tuple[str, ...], n_out: int, block: int = BLOCK) -> KernelOutput:
    """Integrate every variant of ``b`` with the compiled kernel (same results as the reference)."""
    out, hist, summ = outputs(b, histories, n_out)
    topo, var = records(b)
    run_blocks(_run, block_starts(b.x0.shape[2], block), n_out, topo, var, hist, summ)
    return finish(out, hist)
