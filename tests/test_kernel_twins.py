"""Both fast kernels (generic and generated) bitwise equal to the NumPy reference, on every feature.

The independent truth is the reference kernel (:mod:`crashstudy.kernel.reference`, plain NumPy,
itself checked against closed forms and scipy in test_physics and test_materials). The fast kernels
share their laws (:mod:`crashstudy.kernel.laws`) but not the reference's code. Tolerance: bitwise
(every summary, every history; NaN where the reference has NaN).

Cases (the models: tests/twins.py): three full twins (all materials, gravity, loads, prescribed
displacement / velocity / acceleration, rigid walls incl. an inclined one, 1-D and 2-D; the 1-D one with
per-variant scaled spring, load and motion curves, and every material drawn both ways); 2-D rigid and
penalty walls; a 2-D spring crushed to zero length; knot crossings of every curve material in 1-D and 2-D,
on constant and (1-D) on scaled curves, beside the general_nonlinear reversal (rule 4); the frontal model
with per-variant and constant curves and lane compaction; early termination; the SPEC v2 spring features
(elastoplastic, nonlinear_damper, initial_elongation, failure, max_elongation) breaking (and, in 1-D,
intact) beside rate_elastic, in 1-D and 2-D.
Where features can live together they are disjoint sub-systems of one model (``twins.disjoint``): one
generated kernel compile instead of several (a compile costs about 5 s of CPU per shape plus its springs'
code), each sub-system keeping its own check.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields
from typing import Any

import numpy as np
import pytest

from crashstudy.kernel import entry, generated
from crashstudy.kernel.entry import run_batch
from crashstudy.kernel.output import CRUSHED_TO_ZERO, KernelOutput
from helpers import output_differences, run_model
from twins import CASES, RECORD_CASES, one_d_materials, record_case

FAST = ["generic", "generated"]


def _springs(plan: Any, prefix: str) -> list[int]:
    """The spring indices of sub-system ``prefix`` of a :func:`twins.disjoint` model."""
    return [k for k, sid in enumerate(plan.topology.spring_ids) if sid.startswith(prefix + "-")]


def _check_scaled(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """Every variant runs; the scaled curves keep one shape (the generated kernel's factor curves)."""
    from crashstudy.kernel.gen_shape import _constant_curves, _factor_curves

    assert np.all(ref.status == 0) and np.unique(batch.cfac[0], axis=1).shape[1] > 1
    assert _factor_curves(batch, None, _constant_curves(batch, None))


def _check_ok(ref: KernelOutput, batch: Any, plan: Any) -> None:
    assert np.all(ref.status == 0)


def _check_both_ways(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """Every material drawn left to right (1-D sign +1: the springs without a prefix) and right to left
    (-1: ``rev-``); the variants' output intervals differ (their time steps do)."""
    rev = _springs(plan, "rev")
    for springs, sign in (([k for k in range(len(batch.sign)) if k not in rev], 1.0), (rev, -1.0)):
        assert (
            len(springs) == 5 and np.all(batch.sign[springs] == sign) and np.all(ref.peak_force[springs] > 0)
        )
    assert np.all(ref.status == 0) and len(np.unique(batch.out_every)) > 1


def _check_full_twin(ref: KernelOutput, batch: Any, plan: Any) -> None:
    assert len(batch.pm_node) + len(batch.load_node) > 0 and np.all(ref.status == 0)
    assert np.unique(batch.mass, axis=1).shape[1] == batch.mass.shape[1] == 5, "5 different variants"
    assert np.nanmax(np.abs(ref.histories["external_work"])) > 0
    assert np.nanmax(ref.histories["wall_energy"]) > 0


def _check_full_twin_scaled_both_ways(ref: KernelOutput, batch: Any, plan: Any) -> None:
    _check_full_twin(ref, batch, plan)
    _check_scaled(ref, batch, plan)
    _check_both_ways(ref, batch, plan)


def _check_walls(ref: KernelOutput, batch: Any, plan: Any) -> None:
    assert batch.x0.shape[1] == 2 and np.all(ref.status == 0)
    # a wall that only stops a node reports an impulse; one that holds it against a force, a contact force
    assert np.all(np.max(ref.peak_wall_force + ref.wall_impulse, axis=1) > 0), "both walls are hit"


def _check_full_twin_walls(ref: KernelOutput, batch: Any, plan: Any) -> None:
    _check_full_twin(ref, batch, plan)
    _check_walls(ref, batch, plan)


def _check_penalty(ref: KernelOutput, batch: Any, plan: Any) -> None:
    _check_walls(ref, batch, plan)
    assert (
        np.all(batch.wall_stiffness[1] > 0)
        and np.all(ref.wall_impulse[1] == 0.0)
        and np.all(ref.peak_wall_force[1] > 0)
    )


def _check_crushed(ref: KernelOutput, batch: Any, plan: Any) -> None:
    assert list(ref.status) == [0, 0, CRUSHED_TO_ZERO, CRUSHED_TO_ZERO] and list(ref.fail_item[2:]) == [0, 0]


def _check_reversal(ref: KernelOutput, batch: Any, plan: Any, spring: int = 0) -> None:
    """The general_nonlinear ``spring`` yields in compression and then in tension (rule 4) in every variant."""
    force = ref.histories["spring_force"][:, spring, :]
    assert np.all(np.nanmin(force, axis=0) <= -2.0e4) and np.all(np.nanmax(force, axis=0) >= 2.0e4 - 1.0)


def _check_knots(ref: KernelOutput, batch: Any, plan: Any, springs: Any = slice(None)) -> None:
    """On every spring (of ``springs``), the knot candidate raised the peak force above every sample (in
    some variant)."""
    sampled = np.nanmax(np.abs(ref.histories["spring_force"][:, springs]), axis=0)
    assert np.all(ref.status == 0) and np.all(np.any(ref.peak_force[springs] > sampled, axis=1))


def _check_knots_and_reversal(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """:func:`_check_knots` on every knot spring (``k-``), on constant curves and on scaled ones
    (``k-s-``), and on the crush-rebound front (``cr-front``); :func:`_check_reversal` on the mount."""
    knots, scaled, mount = _springs(plan, "k"), _springs(plan, "k-s"), _springs(plan, "mount")
    front = plan.topology.spring_ids.index("cr-front")
    assert len(knots) == 6 and len(scaled) == 3 and len(mount) == 1
    _check_knots(ref, batch, plan, [*knots, front])
    _check_scaled(ref, batch, plan)
    _check_reversal(ref, batch, plan, mount[0])


def _check_frontal(ref: KernelOutput, batch: Any, plan: Any) -> None:
    _check_scaled(ref, batch, plan)
    assert len(np.unique(batch.n_steps)) >= 8, "variants end at different steps"


def _check_termination(ref: KernelOutput, batch: Any, plan: Any) -> None:
    assert np.all(ref.t_end < 0.2) and len(np.unique(ref.t_end)) >= 30


def _check_v2_and_rate(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """Every variant runs (on the generated kernel too). Breaking sub-system: springs break in some
    variants, not all; preloads store energy. Intact one (1-D): nothing breaks; preloads store energy.
    rate_elastic: its preload stores energy."""
    assert np.all(ref.status == 0) and generated.unsupported(batch) is None
    ids = plan.topology.spring_ids
    f, i = _springs(plan, "f"), _springs(plan, "i")
    assert len(i) == (4 if batch.x0.shape[1] == 1 else 0)
    broke = np.isfinite(ref.spring_fail_time[f])
    assert broke.any() and not broke.all() and np.all(np.isnan(ref.spring_fail_time[i]))
    preloaded = ("f-ep", "f-gn", "f-cr", "r-re") + (("i-ep", "i-cr") if i else ())
    for p in preloaded:
        assert np.all(batch.ie0[ids.index(p)] > 0), p
    assert np.all(ref.max_elongation[[ids.index(p) for p in preloaded if p.endswith("-ep")]] > 0)


# case (tests/twins.py CASES) -> what the case must exercise
CHECKS: dict[str, Callable[[KernelOutput, Any, Any], None]] = {
    "full-twin-1d-every-material-both-ways-scaled-curves": _check_full_twin_scaled_both_ways,
    "full-twin-2d-helicopter-two-walls": _check_full_twin_walls,
    "2d-rigid-and-penalty-walls": _check_penalty,
    "full-twin-2d-mixed-prescribed": _check_full_twin,
    "2d-crushed-to-zero": _check_crushed,
    "knots-1d-every-curve-material-constant-and-scaled-crush-rebound-and-reversal": _check_knots_and_reversal,
    "knots-every-curve-material-2d": _check_knots,
    "frontal-curve-and-mass-axes-lane-compaction": _check_frontal,
    "early-termination": _check_termination,
    **{f"v2-spring-features-and-rate-elastic-{dim}d": _check_v2_and_rate for dim in (1, 2)},
}


def test_every_case_has_its_check() -> None:
    assert set(CHECKS) == set(CASES)


@pytest.mark.parametrize("case", list(CASES))
def test_fast_kernels_bitwise_equal_to_reference(case: str) -> None:
    """Every summary and history of both fast kernels equals the reference's bit for bit on ``case``, and
    the case really exercises its feature (checked on the reference's output). One reference run serves
    both kernels (it is the costly part: NumPy, step by step). The cases of ``twins.RECORD_CASES`` keep the
    per-step acceleration record of every movable node too (the crash criteria's input), also bitwise."""
    batch, plan, record = record_case(case)
    histories = plan.topology.histories
    ref = run_batch(batch, histories, plan.n_out, "reference", record=record)
    CHECKS[case](ref, batch, plan)
    assert (ref.step_acceleration is not None and np.any(ref.step_acceleration != 0.0)) == (
        case in RECORD_CASES
    )
    for kernel in FAST:
        got = run_batch(batch, histories, plan.n_out, kernel, record=record)
        diff = output_differences(ref, got)
        assert not diff, f"{kernel} kernel: {diff} differ from the reference's"


def test_ordered_run_spreads_each_variant_back_to_the_callers_columns() -> None:
    """``entry.run_ordered`` sorts the variants by step count, runs them and spreads the results back
    (here 6 columns from 5 variants of different masses, one taken twice): column k equals, bitwise,
    column ``spread[k]`` of the reference run in the caller's order; no error estimate was asked (NaN)."""
    axes = {"nodes.a.mass": [8.0, 1.0, 4.0, 2.0, 6.0]}
    ref, batch, plan = run_model(one_d_materials(False), kernel="reference", variants=axes)
    assert not np.all(np.diff(batch.n_steps) >= 0), "the variants are not in step-count order"
    spread = np.array([2, 0, 2, 4, 1, 3])
    got, estimate = entry.run_ordered(batch, plan.topology.histories, plan.n_out, spread, "generic")
    for f in fields(KernelOutput):
        if f.name != "histories" and not (
            getattr(got, f.name) is None is getattr(ref, f.name)
        ):  # optional outputs
            assert np.array_equal(getattr(got, f.name), getattr(ref, f.name)[..., spread], equal_nan=True), (
                f.name
            )
    for name, r in ref.histories.items():
        assert np.array_equal(got.histories[name], r[..., spread], equal_nan=True), name
    assert estimate.shape == (6,) and np.all(np.isnan(estimate))
