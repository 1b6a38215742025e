"""The one entry point into the kernels: which kernel runs a batch, in what order, with what error estimate.

- :func:`run_batch` integrates a batch with a kernel: "compiled" (the fastest kernel that is
  compiled, or the NumPy reference while none is: :func:`crashstudy.kernel.choice.pick`, which also
  reads ``CRASHSTUDY_KERNEL``), "generic", "generated" or "reference". A kernel that is not compiled
  yet is compiled in a child process first when a stop check is given, so a stop request kills it.
- :func:`run_ordered` is what a study chunk needs: the variants sorted by step count (so a block
  holds variants that finish together; not when their counts are within ``SORT_SPREAD``), run, the optional error estimate, and the results spread
  back to the caller's columns (``spread``: e.g. a deduplicated batch back to every variant).
- :func:`set_threads` / :func:`get_threads`: the threads of both fast kernels
  (:mod:`crashstudy.kernel.driver`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from crashstudy.kernel import choice
from crashstudy.kernel.driver import get_threads, set_threads
from crashstudy.kernel.output import KernelOutput, allocate
from crashstudy.vocabulary.codes import KernelName

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch


class Recorder(Protocol):
    """Turns a batch's per-step record of ``nodes`` into results (:class:`crashstudy.metrics.record.Recorder`)."""

    @property
    def nodes(self) -> tuple[int, ...]: ...

    def __call__(self, batch: Batch, run: Callable[[Batch], KernelOutput]) -> KernelOutput: ...


__all__ = ["error_estimate", "get_threads", "run_batch", "run_ordered", "set_threads", "spread_columns"]
SORT_SPREAD = 0.05  # step counts within this fraction of the longest: the batch runs unsorted (a copy saved)
SUMMARIES = (
    "status",
    "fail_time",
    "fail_item",
    "t_end",
    "peak_force",
    "max_crush",
    "absorbed_energy",
    "peak_acceleration",
    "peak_wall_force",
    "energy_error",
    "final_energy",
    "max_elongation",
    "spring_fail_time",
    "wall_impulse",
)


def compile_first(
    kernel: KernelName,
    batch: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    check: Callable[[], None],
    record: tuple[int, ...] = (),
) -> None:
    """Compile ``kernel`` ("generic" or "generated") for ``batch`` in a child process when it is not
    compiled yet, polling ``check`` while it runs (numba cannot be interrupted in this process)."""
    if kernel == "generic" and not choice.generic_ready():
        choice.compile_foreground(("generic",), batch, histories, vary, check, record)
    elif kernel == "generated" and not choice.generated_ready(batch, histories, vary, record):
        choice.compile_foreground(("generated",), batch, histories, vary, check, record)


def run_batch(
    batch: Batch,
    histories: tuple[str, ...],
    n_out: int,
    kernel: KernelName = "compiled",
    vary: frozenset[int] | None = None,
    repeat: float = 1.0,
    check: Callable[[], None] | None = None,
    record: tuple[int, ...] = (),
) -> KernelOutput:
    """Integrate ``batch`` with ``kernel`` (see the module docstring). ``vary``: indices of the curves
    the study varies (the generated kernel keeps the others as constants); ``repeat``: how many
    batches like this one the run holds (for the choice); ``check``: raises to abandon the run;
    ``record``: nodes whose acceleration is kept at every step (``KernelOutput.step_acceleration``, for
    the crash criteria): only a kernel of ``choice.RECORDING`` is used then."""
    kernel = choice.pick(batch, histories, vary, kernel, repeat, record=record)
    if kernel == "reference":
        from crashstudy.kernel.reference import run_reference

        with np.errstate(
            all="ignore"
        ):  # overflow is found by the energy check (status), as in the compiled kernels
            return run_reference(batch, histories, n_out, check, record)
    if check is not None:
        compile_first(kernel, batch, histories, vary, check, record)
    if kernel == "generated":
        from crashstudy.kernel.generated import run_generated

        out = run_generated(batch, histories, n_out, vary, record=record)
        choice.note_loaded("generated")
        return out
    from crashstudy.kernel.compiled import run_compiled

    choice.note_loaded("generic")
    return run_compiled(batch, histories, n_out, record=record)


def spread_columns(
    out: KernelOutput, take: np.ndarray, histories: tuple[str, ...], n_out: int
) -> KernelOutput:
    """The output with column k = column ``take[k]`` of ``out``."""
    S, N, W = out.peak_force.shape[0], out.peak_acceleration.shape[0], out.peak_wall_force.shape[0]
    full = allocate(S, N, 1, W, len(take), (), n_out)
    for name in SUMMARIES:
        getattr(full, name)[...] = getattr(out, name)[..., take]
    full.histories = {
        h: out.histories[h][..., take] for h in (*histories, *out.histories) if h in out.histories
    }
    full.criteria = out.criteria.take(take) if out.criteria is not None else None
    return full


def run_ordered(
    batch: Batch,
    histories: tuple[str, ...],
    n_out: int,
    spread: np.ndarray,
    kernel: KernelName = "compiled",
    vary: frozenset[int] | None = None,
    repeat: float = 1.0,
    accuracy: bool = False,
    check: Callable[[], None] | None = None,
    recorder: Recorder | None = None,
) -> tuple[KernelOutput, np.ndarray]:
    """Run ``batch`` sorted by step count; returns the output and the error estimate (NaN unless
    ``accuracy``) for columns ``spread`` of ``batch`` (column k = variant ``spread[k]``).
    ``recorder`` (crash criteria, :class:`crashstudy.metrics.record.Recorder`): records its nodes at every
    step and turns each record into ``KernelOutput.criteria`` (and extra histories)."""
    n = batch.n_steps
    if not len(n) or n.max() - n.min() <= SORT_SPREAD * n.max() or np.all(n[1:] >= n[:-1]):
        order = np.arange(len(n))  # sorting would gain less than copying the batch costs
        sorted_batch = batch
    else:
        order = np.argsort(n, kind="stable")
        sorted_batch = batch.take(order)
    if recorder is None:
        out = run_batch(sorted_batch, histories, n_out, kernel, vary, repeat, check)
    else:
        out = recorder(
            sorted_batch,
            lambda sub: run_batch(sub, histories, n_out, kernel, vary, repeat, check, recorder.nodes),
        )
    estimate = (
        error_estimate(sorted_batch, out, kernel, repeat, check) if accuracy else np.full(len(order), np.nan)
    )
    pos = np.empty_like(order)
    pos[order] = np.arange(len(order))
    cols = pos[spread]
    if len(cols) == len(order) and np.array_equal(cols, np.arange(len(cols))):
        return out, estimate  # the kernel's columns are the caller's already
    return spread_columns(out, cols, histories, n_out), estimate[cols]


def error_estimate(
    batch: Batch,
    out: KernelOutput,
    kernel: KernelName = "compiled",
    repeat: float = 1.0,
    check: Callable[[], None] | None = None,
) -> np.ndarray:
    """Richardson estimate of the relative error of the reported peaks, per variant.

    The variants are run again at half the step; for a second-order method the error of a value
    ``X_h`` is about ``(X_h - X_{h/2}) * 4/3``. The estimate is the largest relative error over the
    peak forces and peak decelerations (items below 1e-9 of the variant's largest value of that kind
    are left out). Absorbed energy is not included: for an elastic spring it is the energy stored at
    the end time, a phase-sensitive value whose relative error says little about the peaks.
    """
    half = dataclasses.replace(
        batch, dt=batch.dt / 2, n_steps=batch.n_steps * 2, out_every=batch.out_every * 2
    )
    fine = run_batch(half, (), 1, kernel, repeat=repeat, check=check)
    worst = np.zeros(batch.n_variants)
    for name in ("peak_force", "peak_acceleration"):
        coarse, ref = getattr(out, name), getattr(fine, name)
        scale = np.max(np.abs(ref), axis=0, initial=0.0)
        keep = np.abs(ref) > 1e-9 * scale
        rel = np.divide(np.abs(coarse - ref) * 4.0 / 3.0, np.abs(ref), out=np.zeros_like(ref), where=keep)
        worst = np.maximum(worst, np.max(rel, axis=0, initial=0.0))
    return np.where((out.status == 0) & (fine.status == 0), worst, np.nan)


_ = (get_threads, set_threads)
