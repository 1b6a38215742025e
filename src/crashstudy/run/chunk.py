"""One chunk of a study's variants computed: :func:`run_chunk`, a pure function of the plan and a variant range
(any backend gives identical results). Moved here from :mod:`crashstudy.run.runner`, which re-exports it.

(Overlapping the next chunk's set-up with this chunk's kernel on a thread of its own took the 10^6 x 86-step
2-spring study from 3.3 to 2.5 s in process, but a test run deadlocked in ``ThreadPoolExecutor.submit``
on its first chunk; it was taken out, see docs/robustness.md.)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crashstudy import interrupt
from crashstudy.arrays.batch import INVALID_REASONS, build_batch, variant_steps
from crashstudy.kernel import entry
from crashstudy.kernel.output import CRUSHED_TO_ZERO, INVALID, UNSTABLE, KernelOutput
from crashstudy.results.chunk_result import ChunkResult
from crashstudy.results.curve_ends import past_curve_ends
from crashstudy.study.plan import Plan
from crashstudy.study.provenance import variant_hashes
from crashstudy.vocabulary.codes import UNSTABLE_WALLS, KernelName

__all__ = ["run_chunk"]


def run_chunk(
    plan: Plan, lo: int, hi: int, kernel: KernelName = "compiled", repeat: float | None = None
) -> ChunkResult:
    """Compute variants ``lo`` .. ``hi - 1`` of ``plan``. ``repeat``: how many chunks like this one the
    caller will compute (default: those of the plan), for the kernel choice.

    Identical variants are computed once; the rest are ordered by step count so that the kernel's
    blocks hold variants that finish together.
    """
    topo = plan.topology
    V = hi - lo
    # a variant's parameters are a function of its axis values: dedupe on those (few columns)
    axes = plan.axis_values(lo, hi)
    if axes and not plan.variants_distinct:
        _, first, inverse = np.unique(
            np.stack(list(axes.values()), axis=1), axis=0, return_index=True, return_inverse=True
        )
        cols = lo + first
    elif axes:  # every variant differs from every other: nothing to dedupe
        cols, inverse = np.arange(lo, hi), np.arange(V)
    else:
        cols, inverse = np.array([lo]), np.zeros(V, dtype=np.int64)
    uniq, inverse = _step_order(plan, cols, inverse.reshape(-1))
    batch, steps = build_batch(topo, uniq, plan.interval)
    repeat = plan.n_variants / max(V, 1) if repeat is None else repeat
    recorder = None
    if topo.metrics:
        from crashstudy.metrics.record import Recorder

        recorder = Recorder(topo, plan.n_out)
    full, estimate = entry.run_ordered(
        batch,
        topo.histories,
        plan.n_out,
        inverse,
        kernel,
        plan.varying_curves,
        repeat,
        topo.accuracy_check,
        interrupt.check,
        recorder,
    )
    dt, dt_crit = steps.dt[inverse], steps.dt_crit[inverse]
    control = _control_texts(topo, steps.control_node[inverse], steps.control_spring[inverse])
    user_dt = uniq[topo.blocks["time_step"].start][inverse]
    reasons = np.full(V, "", dtype=object)
    for k in np.flatnonzero(full.status):  # texts only for the failed variants
        reasons[k] = _reason(full, int(k), topo, user_dt[k], dt_crit[k], control[k])
    ends = past_curve_ends(batch, full.max_crush, full.max_elongation, inverse)
    return ChunkResult(
        np.arange(lo, hi),
        full,
        dt,
        dt_crit,
        control,
        reasons,
        variant_hashes(plan, lo, hi),
        estimate,
        full.criteria,
        ends,
    )


def _step_order(plan: Plan, cols: np.ndarray, inverse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The parameters of the variants numbered ``cols`` in ascending step count (and ``inverse`` pointing
    at them), so that the batch is built in the order the kernel runs it (``entry.run_ordered`` sorts an
    unsorted batch with a copy of every array: 1 s of 10^6 variants' 4.7 s set-up under load). Only the
    step choice is computed for it; a fixed ``dt`` (equal counts unless ``end_time`` varies) is left as
    it is. The sorted parameters are made anew from the sorted variant numbers (``Plan.params_at``: a
    few rows written per axis), not gathered column by column from the unsorted ones (16x the time)."""
    uniq = plan.params_at(cols)
    if plan.topology.time_step_mode == "dt" or uniq.shape[1] < 2:
        return uniq, inverse
    n = variant_steps(plan.topology, uniq, plan.interval).n_steps
    if np.all(n[1:] >= n[:-1]) or n.max() - n.min() <= entry.SORT_SPREAD * n.max():
        return uniq, inverse  # sorted already, or run unsorted (run_ordered's rule)
    order = np.argsort(n, kind="stable")
    pos = np.empty_like(order)
    pos[order] = np.arange(len(order))
    return plan.params_at(cols[order]), pos[inverse]


def _control_texts(topo: Any, node: np.ndarray, spring: np.ndarray) -> np.ndarray:
    """'node X / spring Y' per variant (object array), each distinct text made once."""
    width = len(topo.spring_ids) + 1
    keys, inv = np.unique((node.astype(np.int64) + 1) * width + spring + 1, return_inverse=True)
    pairs = np.stack([keys // width - 1, keys % width - 1])
    texts = np.array(
        [
            ("none" if n < 0 else f"node {topo.node_ids[n]}")
            + (f" / spring {topo.spring_ids[s]}" if s >= 0 else "")
            for n, s in pairs.T
        ],
        dtype=object,
    )
    return texts[inv.reshape(-1)] if len(node) else np.zeros(0, dtype=object)


def _reason(out: KernelOutput, k: int, topo: Any, user_dt: float, dt_crit: float, control: str) -> str:
    code, t, at = int(out.status[k]), out.fail_time[k], f"(dt_crit={dt_crit:.6g}, {control})"
    if code == UNSTABLE and int(out.fail_item[k]) == UNSTABLE_WALLS:  # the passivity test failed
        w = ", ".join(repr(w) for w in topo.wall_ids)
        w = f"rigid wall {w}" if len(topo.wall_ids) == 1 else f"rigid walls {w} (together)"
        return f"numerical instability: {w} gave back energy (passivity test) at t={t:.6g} {at}: " + (
            "the time step is too large for this contact"
        )
    if code == UNSTABLE:
        return (
            f"numerical instability: energy balance lost (non-finite, or error above 100%) at t={t:.6g} {at}"
        )
    if code == CRUSHED_TO_ZERO:
        return f"spring {topo.spring_ids[int(out.fail_item[k])]!r} crushed to zero length at t={t:.6g}"
    if code == INVALID:
        item = int(out.fail_item[k])
        if item == 1:
            return f"fixed dt={user_dt:.6g} is above the critical step dt_crit={dt_crit:.6g} ({control})"
        return f"invalid input: {INVALID_REASONS.get(item, 'unknown')}"
    return ""
