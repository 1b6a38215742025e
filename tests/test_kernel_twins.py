"""Both fast kernels (generic and generated) bitwise equal to the NumPy reference, on every feature.

The independent truth is the reference kernel (:mod:`crashstudy.kernel.reference`, plain NumPy,
itself checked against closed forms and scipy in test_physics_* and test_materials_*). The fast kernels
share their laws (:mod:`crashstudy.kernel.laws`) but not the reference's code. Tolerance: bitwise
(every summary, every history; NaN where the reference has NaN).

Cases (the models: tests/twins.py), five generated-kernel shapes: the 1-D full twin (all materials drawn
both ways, gravity, a load, prescribed velocity, a rigid wall, per-variant scaled spring, load and motion
curves); the 2-D full twin (crush, damper, linear, nonlinear; prescribed displacement and acceleration; an
inclined rigid wall) beside the helicopter (general_nonlinear, a load, a rigid floor and a penalty side
wall); 2-D: the SPEC v2 spring features (elastoplastic, nonlinear_damper, initial_elongation, failure,
max_elongation) breaking, rate_elastic and the knot crossings of every curve material, and on the same
shape a general_nonlinear spring crushed to zero length; 1-D: the knot crossings of every curve material on
constant and scaled curves, the crush-rebound front, the general_nonlinear reversal (rule 4) and the v2
features breaking and intact, rate_elastic; early termination with 40 variants of 13 different steps (lane
compaction).
Where features can live together they are disjoint sub-systems of one model (``twins.disjoint``): one
generated kernel compile instead of several (a compile costs about 30 ms of CPU per line of its source,
about 250 lines of which are the same in every shape), each sub-system keeping its own check.
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
from twin_models import one_d_materials
from twins import CASES, RECORD_CASES, record_case

FAST = ["generic", "generated"]


def _springs(plan: Any, prefix: str) -> list[int]:
    """The spring indices of sub-system ``prefix`` of a :func:`twins.disjoint` model."""
    return [k for k, sid in enumerate(plan.topology.spring_ids) if sid.startswith(prefix + "-")]


def _check_scaled(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """Every variant runs; the scaled curves keep one shape (the generated kernel's factor curves)."""
    from crashstudy.kernel.gen_shape import _constant_curves, _factor_curves

    assert np.all(ref.status == 0) and np.unique(batch.cfac[0], axis=1).shape[1] > 1
    assert _factor_curves(batch, None, _constant_curves(batch, None))


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
    # both ways, the crush springs reach their plateau (at least 1800 N, scaled) and the general_nonlinear
    # ones their yield (1500 N) in some variant, and each has unloaded from its peak in some variant
    ids, last = plan.topology.spring_ids, np.abs(ref.histories["spring_force"][-1])
    for s in ("crush", "rev-crush", "yielding", "rev-yielding"):
        k = ids.index(s)
        assert np.max(ref.peak_force[k]) >= 1500.0 and np.any(last[k] < ref.peak_force[k]), s


def _check_full_twin_2d(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """:func:`_check_full_twin` (2-D); every wall is hit (the inclined ``slope``, the helicopter's rigid
    ``h-floor`` and penalty ``h-side``: a rigid wall that only stops a node reports an impulse, one that
    holds it against a force a contact force); the penalty wall pushes (a force, no impulse) in every
    variant, with per-variant stiffness, and the rigid ones have none."""
    _check_full_twin(ref, batch, plan)
    walls = plan.topology.wall_ids
    side = walls.index("h-side")
    assert batch.x0.shape[1] == 2 and len(walls) == 3
    assert np.all(np.max(ref.peak_wall_force + ref.wall_impulse, axis=1) > 0), "every wall is hit"
    assert np.all(batch.wall_stiffness[[walls.index("slope"), walls.index("h-floor")]] == 0.0)
    assert len(np.unique(batch.wall_stiffness[side])) == 5 and np.all(batch.wall_stiffness[side] > 0)
    assert np.all(ref.wall_impulse[side] == 0.0) and np.all(ref.peak_wall_force[side] > 0)
    # the helicopter's underfloor (general_nonlinear) has turned (in 4 of the 5 variants by 0.06 s): its
    # crush at the end is smaller than its largest
    under = plan.topology.spring_ids.index("h-underfloor")
    assert np.sum(-ref.histories["spring_elongation"][-1, under] < ref.max_crush[under]) >= 3


def _check_crushed(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """The 2-D general_nonlinear knot spring ``general-s`` (of a heavy body) crushes to zero length in the
    last two variants, and that ends them; the others run to the end."""
    gen = plan.topology.spring_ids.index("general-s")
    assert list(ref.status) == [0, 0, 0, CRUSHED_TO_ZERO, CRUSHED_TO_ZERO]
    assert list(ref.fail_item[3:]) == [gen, gen]
    assert np.all(ref.t_end[3:] < ref.t_end[0])


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


def _check_termination(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """Every variant stops early, at its own time; the variants' step counts differ (lanes end at
    different steps within a block: lane compaction)."""
    assert np.all(ref.t_end < 0.2) and len(np.unique(ref.t_end)) >= 30
    assert len(np.unique(batch.n_steps)) >= 8, "variants end at different steps"


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


def _check_springs_1d(ref: KernelOutput, batch: Any, plan: Any) -> None:
    _check_knots_and_reversal(ref, batch, plan)
    _check_v2_and_rate(ref, batch, plan)


def _check_springs_2d(ref: KernelOutput, batch: Any, plan: Any) -> None:
    """:func:`_check_v2_and_rate` 2-D and :func:`_check_knots` on the knot springs (``*-s``)."""
    _check_v2_and_rate(ref, batch, plan)
    knots = [k for k, sid in enumerate(plan.topology.spring_ids) if sid.endswith("-s")]
    assert len(knots) == 3
    _check_knots(ref, batch, plan, knots)


# case (tests/twins.py CASES) -> what the case must exercise
CHECKS: dict[str, Callable[[KernelOutput, Any, Any], None]] = {
    "full-twin-1d-every-material-both-ways-scaled-curves": _check_full_twin_scaled_both_ways,
    "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls": _check_full_twin_2d,
    "2d-v2-spring-features-rate-elastic-and-knots": _check_springs_2d,
    "2d-crushed-to-zero": _check_crushed,
    "1d-knots-constant-and-scaled-crush-rebound-reversal-v2-spring-features-and-rate-elastic": _check_springs_1d,
    "early-termination": _check_termination,
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
