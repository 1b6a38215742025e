"""How much work a run is: element-steps (springs x time steps, summed over variants), the limit a run
may take, and how long that is in words. Counted on a sample of the variants for a large study."""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from crashstudy.errors import InputError, Problem

if TYPE_CHECKING:
    from crashstudy.study.plan import Plan

MAX_WORK = 1e13  # element-steps (springs x time steps, summed over variants) a run may take: ~3 h at 1e9/s
WORK_ENV = "CRASHSTUDY_MAX_WORK"  # environment variable that replaces MAX_WORK
WORK_REPORT = 1e10  # element-steps from which validate and run say how long the run takes
WORK_RATE = 1e9  # element-steps a second, for the hours quoted in messages (one core of the compiled kernel)
WORK_ENTRIES = 2**26  # parameters x variants whose steps are counted (exactly up to this, else a sample)
WORK_BLOCK = 2**16  # variants per step count, and at most this many counted (a larger study: a sample)


def max_work() -> float:
    """The most element-steps a run may take: :data:`MAX_WORK`, or the environment's :data:`WORK_ENV`."""
    raw = os.environ.get(WORK_ENV, "").strip()
    if not raw:
        return MAX_WORK
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not value > 0:  # also NaN
        raise InputError(
            [
                Problem(
                    WORK_ENV,
                    None,
                    "",
                    f"expected a number of element-steps > 0 (the default is {MAX_WORK:g}), got {raw[:40]!r}",
                )
            ]
        )
    return value


def estimate_work(plan: Plan) -> tuple[float, int, float]:
    """Element-steps of a run (springs x time steps, summed over variants), the variant with the most
    steps and its steps. A dimension of the study whose axes change initial velocities only
    (``impact_velocity``) changes no variant's step count (the step choice reads masses, stiffnesses,
    curves, walls and times, never velocities): the steps are counted with it at its first value and
    weighted by its length. Of the rest, up to :data:`WORK_BLOCK` variants (and :data:`WORK_ENTRIES`
    parameters x variants) are counted exactly, more on that many drawn evenly at random (always with the
    first and the last) and scaled: counting all of 10^6 variants cost 0.3 us each, a third of the
    bookkeeping."""
    from crashstudy.arrays.batch import variant_steps

    V = plan.n_variants
    shape = _step_shape(plan)
    Vs = math.prod(shape) if shape else 1
    per = max(1, min(WORK_BLOCK, WORK_ENTRIES // max(1, len(plan.base))))
    if Vs <= per:
        idx = np.arange(Vs, dtype=np.int64)
    else:
        rng = np.random.default_rng(0)
        idx = np.unique(np.concatenate([[0, Vs - 1], rng.integers(0, Vs, per - 2)]))
    if (
        shape != plan.shape
    ):  # variant numbers of the study (the velocity-only dimensions at their first value)
        idx = np.ravel_multi_index(np.unravel_index(idx, shape), plan.shape).astype(np.int64)
    total, worst, most = 0.0, 0, -1.0
    for lo in range(0, len(idx), WORK_BLOCK):
        at = idx[lo : lo + WORK_BLOCK]
        # the step choice alone (what build_batch's n_steps holds), not the whole batch: half the time
        steps = np.asarray(
            variant_steps(plan.topology, plan.params_at(at), plan.interval).n_steps, dtype=np.float64
        )
        total += float(steps.sum())
        k = int(np.argmax(steps))
        if steps[k] > most:
            worst, most = int(at[k]), float(steps[k])
    return total * max(1, plan.topology.n_springs) * V / len(idx), worst, most


def step_dims(plan: Plan) -> tuple[int, ...]:
    """The study's dimensions holding an axis that sets anything but initial velocities (parameter block
    ``velocity``): the only ones that change a variant's time steps (the step choice never reads velocities)."""
    vel = plan.topology.blocks["velocity"]
    return tuple(
        sorted({ax.dim for ax in plan.axes if any(not vel.start <= s < vel.stop for s in ax.ref.slots)})
    )


def _step_shape(plan: Plan) -> tuple[int, ...]:
    """The study's shape with each dimension whose axes set initial velocities only reduced to one value."""
    dims = step_dims(plan)
    return tuple(n if d in dims else 1 for d, n in enumerate(plan.shape))


def format_duration(seconds: float) -> str:
    """``seconds`` in the largest unit it fills: "3.2 hours"."""
    for unit, size in (("years", 3.15e7), ("days", 86400.0), ("hours", 3600.0), ("minutes", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"
