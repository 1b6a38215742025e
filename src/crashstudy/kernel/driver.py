"""What both fast kernels share around their compiled step: threads, blocks, argument records and
output buffers.

A fast kernel is a compiled function ``run(b_lo, b_hi, ...)`` that integrates blocks ``b_lo:b_hi``
of variants; :func:`run_blocks` cuts the variants into blocks and runs them on a thread pool (the
compiled functions release the GIL). The arrays a kernel reads and writes travel as plain records
(named tuples of arrays; numba passes them as one argument):

- :class:`Topo` the topology (what every variant shares), :class:`Vars` the per-variant inputs,
  both straight from a :class:`crashstudy.arrays.batch.Batch`;
- :class:`Hist` the per-step outputs kept (histories; a new optional per-step output is one more
  field here, one ``allocate`` line and the writes in each kernel's record stage);
- :class:`Summ` the per-variant summaries (the arrays of :class:`crashstudy.kernel.output.KernelOutput`).
"""

from __future__ import annotations

import os
from collections import namedtuple
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

import numpy as np

from crashstudy.kernel.output import KernelOutput, allocate, block_rows
from crashstudy.vocabulary.batch_fields import SHARED_FIELDS
from crashstudy.vocabulary.codes import ENERGIES, HISTORY_ORDER

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

_THREADS = [os.cpu_count() or 1]
PER_THREAD = 8  # runs of blocks per thread (a thread that finishes early takes the next run)

TOPO_FIELDS = SHARED_FIELDS  # the topology record T: the fields every variant shares
VARS_FIELDS = (
    "mass",
    "inv_mass",
    "x0",
    "v0",
    "length0",
    "sign",
    "kpar",
    "yield_t",
    "yield_c",
    "cx",
    "cy",
    "cds",
    "cs0",
    "cs1",
    "knot_y",
    "gravity",
    "load_force",
    "pm_scale",
    "wall_point",
    "wall_normal",
    "wall_stiffness",
    "dt",
    "n_steps",
    "out_every",
    "ke_fraction",
    "min_time",
    "invalid",
    "energy_floor",
    "rec_block",
    "ktan",
    "fy",
    "e0",
    "fail_t",
    "fail_c",
    "state0",
    "ie0",
    "rate0",
    "cfac",
    "rate_at",
)
Topo = namedtuple("Topo", TOPO_FIELDS)  # type: ignore[misc]
Vars = namedtuple("Vars", VARS_FIELDS)  # type: ignore[misc]
# rec: which histories are kept (HISTORY_ORDER); energy: (T, 4, V) for the four ENERGIES
# step_nodes (M,) and steps (T, M, D, V): the acceleration of nodes step_nodes summed over blocks of
# Vars.rec_block steps (crash criteria; output.block_rows)
Hist = namedtuple(
    "Hist", ("rec", "pos", "disp", "vel", "acc", "force", "elong", "energy", "wall", "step_nodes", "steps")
)  # type: ignore[misc]
Summ = namedtuple(
    "Summ",
    (
        "status",
        "fail_time",
        "fail_item",
        "t_end",
        "peak_force",
        "max_crush",
        "absorbed",
        "peak_acc",
        "peak_wall",
        "energy_error",
        "final_energy",
        "max_elongation",
        "spring_fail_time",
        "wall_impulse",
    ),
)  # type: ignore[misc]


def set_threads(n: int) -> None:
    """Threads the fast kernels use (default: every core)."""
    _THREADS[0] = max(1, int(n))


def get_threads() -> int:
    return _THREADS[0]


def records(b: Batch) -> tuple[Any, Any]:
    """The batch as the (Topo, Vars) argument records."""
    return Topo(*(getattr(b, f) for f in TOPO_FIELDS)), Vars(*(getattr(b, f) for f in VARS_FIELDS))


def outputs(
    b: Batch, histories: tuple[str, ...], n_out: int, record: tuple[int, ...] = ()
) -> tuple[KernelOutput, Any, Any]:
    """The kernel output (summaries zeroed, histories NaN) and its (Hist, Summ) records. Histories not
    kept get a small placeholder the kernel never writes. ``record``: nodes whose acceleration is kept
    summed over blocks of ``b.rec_block`` steps (``out.step_acceleration``; zero after a variant's end, as
    the reference has it)."""
    N, D, V = b.x0.shape
    S = len(b.spring_i)
    out = allocate(S, N, D, b.wall_nodes.shape[0], V, histories, n_out)
    if record:
        out.step_acceleration = np.zeros(
            (int(np.max(block_rows(b.n_steps, b.rec_block), initial=0)), len(record), D, V)
        )
    steps = out.step_acceleration if out.step_acceleration is not None else np.empty((1, 1, 1, 1))
    want_energy = any(h in histories for h in ENERGIES)
    energy = np.full((n_out, 4, V), np.nan) if want_energy else np.empty((1, 4, 1))
    rec = np.array([h in histories or (want_energy and h in ENERGIES) for h in HISTORY_ORDER], dtype=np.bool_)

    def buf(name: str, nd: int) -> np.ndarray:
        return out.histories[name] if name in out.histories else np.empty((1,) * nd)

    hist = Hist(
        rec,
        buf("position", 4),
        buf("displacement", 4),
        buf("velocity", 4),
        buf("acceleration", 4),
        buf("spring_force", 3),
        buf("spring_elongation", 3),
        energy,
        buf("wall_force", 3),
        np.asarray(record, dtype=np.int64),
        steps,
    )
    summ = Summ(
        out.status,
        out.fail_time,
        out.fail_item,
        out.t_end,
        out.peak_force,
        out.max_crush,
        out.absorbed_energy,
        out.peak_acceleration,
        out.peak_wall_force,
        out.energy_error,
        out.final_energy,
        out.max_elongation,
        out.spring_fail_time,
        out.wall_impulse,
    )
    return out, hist, summ


def finish(out: KernelOutput, hist: Any) -> KernelOutput:
    """Copy the energy columns into the output's histories."""
    for k, name in enumerate(ENERGIES):
        if name in out.histories:
            out.histories[name][:] = hist.energy[:, k, :]
    return out


MIN_LANES = 16  # a block split over the threads keeps at least this many variants (two AVX-512 vectors)


def block_starts(V: int, block: int) -> np.ndarray:
    """First variant of each block of at most ``block`` variants, and V. Fewer variants than the threads'
    full blocks are split evenly over the threads (blocks of at least :data:`MIN_LANES`): 64 variants of a
    large model were one block on one core while the other idled (a block's variants are independent: each
    variant's numbers are those it has alone)."""
    nb = min(get_threads(), V // MIN_LANES)
    if 1 < nb and V < nb * block:
        block = -(-V // nb)
    return np.unique(np.minimum(np.arange(0, V + block, block), V)).astype(np.int64)


def run_blocks(run: Any, starts: np.ndarray, *args: Any) -> None:
    """``run(b_lo, b_hi, starts, *args)`` over every block, on at most :func:`get_threads` threads."""
    nblocks = len(starts) - 1
    threads = min(get_threads(), nblocks)
    if threads <= 1:
        run(0, nblocks, starts, *args)
    else:  # a call per run of blocks, not per block: each call unboxes every argument record (~30 us)
        cuts = np.linspace(0, nblocks, min(nblocks, PER_THREAD * threads) + 1).astype(np.int64)
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda k: run(cuts[k], cuts[k + 1], starts, *args), range(len(cuts) - 1)))
