"""The ``metrics:`` block through the pipeline: per-step record -> crash criteria -> result variables.

A model (or a study's ``set``) lists nodes to judge (docs/format.md, "metrics"). The kernel adds the
acceleration of those nodes at *every* time step into blocks of ``k`` steps (``k`` odd, per variant,
:func:`record_blocks`: a record rate of at least ``max(RECORD_RATE, RECORD_PER_CFC x CFC)``; never the
sampled histories): row ``r`` is the mean of ``a^n`` over steps ``r k - h .. r k + h`` (``h = (k-1)/2``),
the sample at ``t = r k dt`` (docs/criteria.md, "Record rate"). After each batch :func:`run_recorded`
turns the sums into means and hands them to :func:`crashstudy.metrics.criteria.compute` (the SAE J211 filter and
the criteria, batched over variants) and drops them, so a chunk holds at most :data:`RECORD_BUDGET`
bytes of record: a chunk whose record would be larger is run in several batches.

Units: the criteria are computed in SI (acceleration in m/s^2, time in s, as the standards define
them); the results are given back in the model's units (``delta_v`` in its velocity unit, the HIC
window ``t1``/``t2`` in its time unit) or in g. ``direction`` is the direction of travel: deceleration
is positive against it. Without one, the node's initial velocity direction of each variant (x when the
node starts at rest).

``filtered_acceleration`` (a history, variant x time x node, in g): the filtered resultant of each metric
node (the class of its first ``metrics`` entry), sampled like the other histories from the filtered
block-mean signal (linear between its samples where a history sample falls between two). ``criteria_note`` (a text per variant, "" when every criterion is trusted): what
:func:`crashstudy.metrics.criteria.compute` says about a criterion whose value depends on the step, prefixed by
the node.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from crashstudy.kernel.output import KernelOutput, concatenate
from crashstudy.units import UNIT_SYSTEMS

RECORD_BUDGET = 256 * 2**20  # bytes of the per-step acceleration record per kernel call
# the record keeps block means of the acceleration at a rate of at least max(RECORD_RATE, RECORD_PER_CFC x the
# highest CFC asked) (docs/criteria.md, "Record rate": the criteria within 1 % of their converged values)
RECORD_RATE = 2500.0  # [Hz]
RECORD_PER_CFC = 10.0
G_SI = 9.80665  # standard gravity [m/s^2]
METRE = {"m": 1.0, "mm": 1e-3}  # length unit -> metres
SECOND = {"s": 1.0, "ms": 1e-3}  # time unit -> seconds

METRIC_META = {  # name: (unit kind, long name); the standard each follows: crashstudy.metrics.criteria.STANDARDS
    "peak_g": ("g", "peak of the filtered resultant acceleration"),
    "hic15": ("1", "head injury criterion, window up to 15 ms"),
    "hic15_t1": ("time", "start of the hic15 window"),
    "hic15_t2": ("time", "end of the hic15 window"),
    "hic36": ("1", "head injury criterion, window up to 36 ms"),
    "hic36_t1": ("time", "start of the hic36 window"),
    "hic36_t2": ("time", "end of the hic36 window"),
    "clip3ms": ("g", "highest level the filtered resultant stays at or above for a continuous 3 ms"),
    "clip3ms_cumulative": ("g", "highest level the filtered resultant exceeds for a cumulative 3 ms"),
    "olc": ("g", "occupant load criterion (65 mm free flight, 235 mm restrained)"),
    "dri": ("1", "dynamic response index (omega 52.9 rad/s, zeta 0.224) of the unfiltered deceleration"),
    "delta_v": ("velocity", "largest change of velocity along the direction from the initial value"),
}
NOTE_TEXT = "criteria_note"
NOTE_LONG = "why a crash criterion of the variant is not trusted (empty if every one is)"


def result_names(topo: Any) -> tuple[str, ...]:
    """The criterion variables of a topology's metrics (with the HIC windows), in METRIC_META order."""
    from crashstudy.metrics.criteria import EXTRA

    asked = {c for mt in topo.metrics for c in mt.criteria}
    asked |= {e for c in list(asked) for e in EXTRA.get(c, ())}
    return tuple(n for n in METRIC_META if n in asked)


def standard(name: str) -> str:
    """The standard a criterion variable follows (a HIC window: its criterion's)."""
    from crashstudy.metrics.criteria import EXTRA, STANDARDS

    return STANDARDS[next((c for c, extra in EXTRA.items() if name in extra), name)]


def asked_nodes(topo: Any, name: str) -> list[str]:
    """Ids of the nodes whose metrics entries ask for criterion ``name`` (or its HIC window's criterion)."""
    from crashstudy.metrics.criteria import EXTRA

    owner = next((c for c, extra in EXTRA.items() if name in extra), name)
    return list(dict.fromkeys(topo.node_ids[mt.node] for mt in topo.metrics if owner in mt.criteria))


@dataclass
class ChunkCriteria:
    """Criteria of a batch's variants: ``values`` name -> (V, N) (NaN where a node does not ask for it
    or the variant failed), ``notes`` (V,) texts."""

    values: dict[str, np.ndarray]
    notes: np.ndarray

    def take(self, idx: np.ndarray) -> ChunkCriteria:
        return ChunkCriteria({k: v[idx] for k, v in self.values.items()}, self.notes[idx])


def record_blocks(topo: Any, dt: np.ndarray) -> np.ndarray:
    """(V,) steps per block of the record (odd, >= 1): the largest whose rate ``1 / (k dt)`` is at least
    ``max(RECORD_RATE, RECORD_PER_CFC x the highest CFC of topo.metrics)``; 1 when dt is that coarse already."""
    second = SECOND[UNIT_SYSTEMS[topo.units].time]
    rate = max([RECORD_RATE] + [RECORD_PER_CFC * mt.cfc for mt in topo.metrics])
    k = np.floor(1.0 / (rate * np.asarray(dt, dtype=np.float64) * second) * (1.0 + 1e-12)).astype(np.int64)
    k = np.maximum(k - (k + 1) % 2, 1)  # odd: a block centred on its sample
    return k


def batch_groups(n_steps: np.ndarray, width: int, budget: int = RECORD_BUDGET) -> list[slice]:
    """Contiguous groups of variants (sorted by step count) whose record, ``(max n_steps + 1) x width``
    doubles a variant, stays within ``budget`` bytes (a group has one variant at least); ``n_steps`` here
    is the last row of each variant's record (the last step when every step is kept)."""
    out: list[slice] = []
    lo = 0
    V = len(n_steps)
    while lo < V:  # a group's bytes grow with its length: the longest group within budget, by bisection
        peak = np.maximum.accumulate(np.asarray(n_steps[lo:], dtype=np.float64))
        size = 8.0 * (peak + 1.0) * width * np.arange(1, V - lo + 1)
        hi = lo + max(1, int(np.searchsorted(size, budget, side="right")))
        out.append(slice(lo, hi))
        lo = hi
    return out


@dataclass
class Recorder:
    """What :func:`crashstudy.kernel.entry.run_ordered` calls to run a batch of a topology with metrics:
    the kernel records ``nodes``; the output comes back with ``criteria`` and ``filtered_acceleration``."""

    topo: Any
    n_out: int

    @property
    def nodes(self) -> tuple[int, ...]:
        return tuple(self.topo.metric_nodes)

    def __call__(self, batch: Any, run: Callable[[Any], KernelOutput]) -> KernelOutput:
        out, crit = run_recorded(batch, run, self.topo, self.n_out)
        out.criteria = crit
        return out


def run_recorded(
    batch: Any, run: Callable[[Any], KernelOutput], topo: Any, n_out: int, budget: int | None = None
) -> tuple[KernelOutput, ChunkCriteria]:
    """Run ``batch`` through ``run`` (a kernel call that records the metric nodes) in groups whose
    record stays within ``budget`` bytes (default :data:`RECORD_BUDGET`); the criteria of each group
    are computed at once and its record dropped."""
    from crashstudy.kernel.output import block_rows

    width = len(topo.metric_nodes) * topo.dim
    budget = RECORD_BUDGET if budget is None else budget
    outs: list[KernelOutput] = []
    crits: list[ChunkCriteria] = []
    batch = replace(batch, rec_block=record_blocks(topo, batch.dt))
    for g in batch_groups(block_rows(batch.n_steps, batch.rec_block) - 1, width, budget):
        sub = batch if g == slice(0, batch.n_variants) else batch.take(np.arange(g.start, g.stop))
        o = run(sub)
        crits.append(criteria_of(topo, sub, o, n_out))
        o.step_acceleration = None
        outs.append(o)
    crit = ChunkCriteria(
        {k: np.concatenate([c.values[k] for c in crits]) for k in crits[0].values},
        np.concatenate([c.notes for c in crits]),
    )
    return concatenate(outs), crit


def _directions(mt: Any, v0: np.ndarray) -> np.ndarray:
    """(V, D) unit direction of travel of a metric entry: its own, else the node's initial velocity (x at rest)."""
    V, D = v0.shape
    if mt.direction is not None:
        return np.broadcast_to(np.asarray(mt.direction, dtype=np.float64), (V, D)).copy()
    speed = np.sqrt(np.sum(v0 * v0, axis=1))
    unit_x = np.zeros(D)
    unit_x[0] = 1.0
    return np.where(speed[:, None] > 0, v0 / np.where(speed > 0, speed, 1.0)[:, None], unit_x[None, :])


def criteria_of(topo: Any, b: Any, o: KernelOutput, n_out: int) -> ChunkCriteria:
    """The criteria of every metric entry for the variants of batch ``b`` and its output ``o``; puts the
    ``filtered_acceleration`` history into ``o.histories`` when the topology asks for it."""
    from crashstudy.kernel.output import block_rows
    from crashstudy.metrics import criteria

    u = UNIT_SYSTEMS[topo.units]
    metre, second = METRE[u.length], SECOND[u.time]
    V, N = b.n_variants, topo.n_nodes
    rec = o.step_acceleration
    assert rec is not None, "the kernel did not record the metric nodes"
    kb = np.asarray(b.rec_block, dtype=np.int64)
    last = np.rint(np.divide(o.t_end, b.dt)).astype(np.int64)  # the last step run
    count = block_rows(last, kb)  # rows r: block means at t = r k dt
    step = b.dt * kb  # the record's spacing
    ok = np.flatnonzero((o.status == 0) & (count >= 2))
    values = {name: np.full((V, N), np.nan) for name in result_names(topo)}
    notes: dict[int, list[str]] = {}  # variant -> its notes (most have none)
    filtered = np.full((n_out, N, V), np.nan) if topo.extra_histories else None
    done_filter: set[int] = set()
    for mt in topo.metrics:
        if not len(ok):
            break
        m = topo.metric_nodes.index(mt.node)
        acc = _means_si(rec[:, m], ok, last, kb, metre / second**2)  # (v, T, D) SI
        v0 = b.v0[mt.node][:, ok].T * (metre / second)
        res = criteria.compute(
            acc, count[ok], step[ok] * second, v0, _directions(mt, v0), mt.cfc, list(mt.criteria), G_SI
        )
        scale = {"velocity": second / metre, "time": 1.0 / second}
        wanted = set(mt.criteria) | {e for c in mt.criteria for e in criteria.EXTRA.get(c, ())}
        for name in (n for n in values if n in res and n in wanted):
            values[name][ok, mt.node] = np.asarray(res[name], dtype=np.float64) * scale.get(
                METRIC_META[name][0], 1.0
            )
        node_id = topo.node_ids[mt.node]
        for k, note in zip(ok, res.get("criteria_note", ()), strict=False):
            if note:
                notes.setdefault(int(k), []).append(f"{node_id}: {note}")
        if filtered is not None and mt.node not in done_filter:
            done_filter.add(mt.node)
            filtered[:, mt.node, ok] = _filtered_samples(
                acc, count[ok], step[ok] * second, b.out_every[ok] / kb[ok], mt.cfc, n_out
            )
    if filtered is not None:
        o.histories["filtered_acceleration"] = filtered
    texts = np.full(V, "", dtype=object)
    for var, texts_of in notes.items():
        texts[var] = "; ".join(texts_of)
    return ChunkCriteria(values, texts)


def _means_si(rec: np.ndarray, ok: np.ndarray, last: np.ndarray, k: np.ndarray, scale: float) -> np.ndarray:
    """(v, T, D) block means of the block sums ``rec`` (T, D, V) of variants ``ok``, times ``scale``: the
    rows divided by ``k`` with the scale in one pass, the first and the last row by their own steps."""
    from crashstudy.kernel.output import block_ends

    first, r_last, n_last = block_ends(last[ok], k[ok])
    T = rec.shape[0]
    sums = (rec if len(ok) == rec.shape[2] else rec[..., ok]).transpose(2, 0, 1)  # (v, T, D) view
    rows = np.arange(len(ok))
    r_last = np.minimum(r_last, T - 1)
    head, tail = sums[:, 0] * (scale / first[:, None]), sums[rows, r_last] * (scale / n_last[:, None])
    acc = np.empty(sums.shape)  # one pass: the view scaled into a (v, T, D) contiguous array
    np.multiply(sums, (scale / k[ok].astype(np.float64))[:, None, None], out=acc)
    acc[:, 0] = head
    acc[rows, r_last] = tail
    return acc


def _filtered_samples(
    acc: np.ndarray, count: np.ndarray, dt: np.ndarray, every: np.ndarray, cfc: int, n_out: int
) -> np.ndarray:
    """(n_out, v) filtered resultant [g] of ``acc`` (v, T, D) [m/s^2] at rows ``i * every`` (``every``: the
    history's sampling interval in record rows, not always whole: linear between rows), NaN after the end."""
    from crashstudy.metrics.criteria import j211_filter

    comps = [j211_filter(np.ascontiguousarray(acc[:, :, d]), count, dt, cfc) for d in range(acc.shape[2])]
    mag = np.sqrt(np.sum(np.stack(comps) ** 2, axis=0)) / G_SI  # (v, T)
    pos = np.arange(n_out)[:, None] * np.asarray(every, dtype=np.float64)[None, :]  # (n_out, v)
    lo = np.floor(pos + 1e-9).astype(np.int64)
    frac = np.where(lo + 1 < count[None, :], np.clip(pos - lo, 0.0, 1.0), 0.0)
    cols = np.arange(mag.shape[0])[None, :]
    top = mag.shape[1] - 1
    a0 = mag[cols, np.clip(lo, 0, top)]
    a1 = mag[cols, np.clip(lo + 1, 0, top)]
    val = np.where(frac > 0.0, a0 + frac * (a1 - a0), a0)
    inside = lo < count[None, :]
    return np.where(inside, val, np.nan)


def plan_warnings(plan: Any) -> list[str]:
    """What ``validate`` and ``run`` say about a plan's metrics: a time step too long for a filter class
    (sample rate below 10 CFC, SAE J211-1; the variants' criteria_note says it too)."""
    from crashstudy.arrays.batch import build_batch

    topo = plan.topology
    if not topo.metrics:
        return []
    where = plan.study_file or plan.model_file
    sample, _ = build_batch(topo, plan.params(0, min(plan.n_variants, 64)), plan.interval)
    second = SECOND[UNIT_SYSTEMS[topo.units].time]
    rate = 1.0 / (float(np.max(sample.dt)) * second)
    out = []
    for k, mt in enumerate(topo.metrics):
        if rate < 10.0 * mt.cfc:
            out.append(
                f"{where}: metrics.{k}.cfc: CFC {mt.cfc} asks for a sample rate of {10 * mt.cfc:g} Hz, the "
                f"time step gives {rate:.4g} Hz: the filtered pulse and its criteria depend on the step "
                "(criteria_note says so); a smaller dt or tolerance resolves it"
            )
    return out
