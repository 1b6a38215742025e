"""What a kernel returns: per-variant summaries and the requested sampled histories."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crashstudy.vocabulary.codes import CRUSHED_TO_ZERO, HISTORY_ORDER, HISTORY_SHAPES, INVALID, OK, UNSTABLE

# histories made after the kernel from its per-step record (crashstudy.metrics.record): never passed to a kernel
EXTRA_SHAPES = {"filtered_acceleration": ("node",)}
ALL_SHAPES = {**HISTORY_SHAPES, **EXTRA_SHAPES}

__all__ = [
    "ALL_SHAPES",
    "CRUSHED_TO_ZERO",
    "EXTRA_SHAPES",
    "HISTORY_ORDER",
    "HISTORY_SHAPES",
    "INVALID",
    "OK",
    "UNSTABLE",
    "KernelOutput",
    "allocate",
    "block_ends",
    "block_means",
    "block_rows",
    "concatenate",
]


@dataclass
class KernelOutput:
    """Results for V variants (variants on the last axis of every array).

    Summary arrays are computed from every time step. ``histories`` maps a name of
    :data:`HISTORY_SHAPES` to an array (T, ..., V), NaN after a variant's end.
    """

    status: np.ndarray  # (V,) int64 failure code
    fail_time: np.ndarray  # (V,) [time] when the failure was detected (NaN if ok)
    fail_item: np.ndarray  # (V,) int64 spring index (crushed) or invalid-input code
    t_end: np.ndarray  # (V,) [time] last time computed (early termination may cut it)
    peak_force: np.ndarray  # (S, V) max |F| [force]
    max_crush: np.ndarray  # (S, V) max shortening max(-e) [length]
    absorbed_energy: np.ndarray  # (S, V) work done on the spring up to the end [energy]
    peak_acceleration: np.ndarray  # (N, V) max |a| [length/time^2]
    peak_wall_force: np.ndarray  # (W, V) [force] largest contact force (docs/solver.md, "Rigid walls")
    energy_error: np.ndarray  # (V,) max relative energy balance error
    final_energy: np.ndarray  # (4, V) KE, IE, W_ext, E_wall at the end [energy]
    histories: dict[str, np.ndarray] = field(default_factory=dict)
    # SPEC v2 summaries
    max_elongation: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (S, V) max stretch max(e)
    # while intact [length]
    spring_fail_time: np.ndarray = field(
        default_factory=lambda: np.zeros((0, 0))
    )  # (S, V) [time] when a spring
    # with a failure option broke (NaN while intact)
    # (T, M, D, V) [length/time^2] acceleration of the recorded (metric) nodes in blocks of k = Batch.rec_block[v]
    # steps: row r of variant v is the SUM of a^n over the steps of block r (block_rows; block_means gives the
    # means, centred on t = r k dt; k = 1: a^n at every step, as the acceleration history has it); zero after a
    # variant's last block. None: not recorded
    step_acceleration: np.ndarray | None = None
    wall_impulse: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (W, V) [force*time] impacts
    # derived from the record after the kernel (crashstudy.metrics.record.ChunkCriteria: .take(columns)); None: none
    criteria: Any = None


def concatenate(parts: list[KernelOutput]) -> KernelOutput:
    """One output of the variants of ``parts`` in order (their step records padded to the longest)."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    names = [f for f in vars(first) if f not in ("histories", "step_acceleration", "criteria")]
    out = KernelOutput(
        **{n: np.concatenate([getattr(p, n) for p in parts], axis=-1) for n in names},
        histories={h: np.concatenate([p.histories[h] for p in parts], axis=-1) for h in first.histories},
    )
    recs = [p.step_acceleration for p in parts]
    if all(r is not None for r in recs):
        T = max(r.shape[0] for r in recs if r is not None)
        out.step_acceleration = np.concatenate(
            [np.pad(r, [(0, T - r.shape[0])] + [(0, 0)] * (r.ndim - 1)) for r in recs if r is not None],
            axis=-1,
        )
    return out


def allocate(S: int, N: int, D: int, W: int, V: int, histories: tuple[str, ...], n_out: int) -> KernelOutput:
    """An output with summaries zeroed and histories filled with NaN."""
    sizes = {"node": N, "axis": D, "spring": S, "wall": W}
    hist = {h: np.full((n_out, *(sizes[d] for d in ALL_SHAPES[h]), V), np.nan) for h in histories}
    return KernelOutput(
        status=np.zeros(V, dtype=np.int64),
        fail_time=np.full(V, np.nan),
        fail_item=np.full(V, -1, dtype=np.int64),
        t_end=np.zeros(V),
        peak_force=np.zeros((S, V)),
        max_crush=np.zeros((S, V)),
        absorbed_energy=np.zeros((S, V)),
        peak_acceleration=np.zeros((N, V)),
        peak_wall_force=np.zeros((W, V)),
        energy_error=np.zeros(V),
        final_energy=np.zeros((4, V)),
        histories=hist,
        max_elongation=np.zeros((S, V)),
        spring_fail_time=np.full((S, V), np.nan),
        wall_impulse=np.zeros((W, V)),
    )


def block_rows(n_steps: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(V,) rows of the block record of steps ``0 .. n_steps`` with ``k`` (odd) steps a block: step n adds to
    row ``(n + (k - 1) // 2) // k`` (row 0 holds steps ``0 .. (k - 1) // 2``, row r steps ``r k - h .. r k + h``)."""
    k = np.asarray(k, dtype=np.int64)
    return (np.asarray(n_steps, dtype=np.int64) + (k - 1) // 2) // k + 1


def block_ends(last: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per variant of last step ``last`` and block length ``k`` (odd): the steps in the first row, the
    index of the last row, the steps in the last row (every other row holds ``k`` steps)."""
    last = np.asarray(last, dtype=np.int64)
    k = np.asarray(k, dtype=np.int64)
    h = (k - 1) // 2
    r_last = (last + h) // k
    n_last = last - np.maximum(r_last * k - h, 0) + 1
    return np.minimum(h, last) + 1, r_last, n_last


def block_means(rec: np.ndarray, last: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The means of a kernel's block record ``rec`` (T, M, D, V) of block sums: each row divided by the
    steps of its block that ran (steps ``0 .. last``); rows past the end stay 0."""
    first, r_last, n_last = block_ends(last, k)
    V = rec.shape[-1]
    cols = np.arange(V)
    tail = rec[np.minimum(r_last, rec.shape[0] - 1), :, :, cols] / n_last[:, None, None]  # (V, M, D)
    out = rec / np.asarray(k, dtype=np.float64)
    out[0] = rec[0] / first
    mask = r_last < rec.shape[0]
    out[r_last[mask], :, :, cols[mask]] = tail[mask]
    return out
