"""The fixed cost of a run (issue 25 item 2): what a run does not need is never loaded. A run whose
kernel is this shape's compiled generated one never imports the generic kernel's module nor looks at
its cache, and the choice it makes is the one the full comparison makes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from crashstudy.arrays.batch import build_batch
from crashstudy.arrays.compiler import apply_axis
from crashstudy.kernel import choice
from helpers import LINEAR_SPRING, model_plan


def _batch(n: int, end_time: float) -> Any:
    model = {
        "name": "fixedcost",
        "nodes": {"w": {"position": [0.0], "fixed": True}, "m": {"position": [0.5], "mass": 1.0}},
        "springs": {"s": {"nodes": ["w", "m"], "material": {"type": "linear_elastic", "stiffness": 1.0e5}}},
        "initial_velocity": {"m": [-5.0]},
        "end_time": end_time,
        "output": {"histories": "none"},
    }
    plan = model_plan(model)
    P = np.repeat(plan.base[:, None], n, axis=1)
    apply_axis(P, plan.topology.paths["nodes.m.mass"], np.linspace(1.0, 2.0, n))
    return build_batch(plan.topology, P, plan.interval)[0], plan


def _full_choice(b: Any, repeat: float, generic: bool) -> str:
    """Independent truth: the expected-time comparison of every kernel, as choice.pick documents it."""
    S = len(b.spring_i)
    work = float(np.sum(b.n_steps)) * S * repeat
    t_ref = choice.reference_seconds(float(np.max(b.n_steps)), S, float(np.sum(b.n_steps)) * S) * repeat
    if t_ref <= choice.LOAD:
        return "reference"
    times = {"reference": t_ref, "generated": work / choice.GENERATED_RATE + choice.LOAD}
    if generic:
        times["generic"] = work / choice.GENERIC_RATE + choice.LOAD
    return min(times, key=lambda k: times[k])


@pytest.mark.parametrize(
    "end_time, n, repeat", [(0.05, 64, 1.0), (0.05, 64, 1e4), (0.5, 1000, 100.0), (0.002, 8, 1.0)]
)
def test_a_ready_generated_kernel_never_loads_the_generic_one(
    monkeypatch: pytest.MonkeyPatch, end_time: float, n: int, repeat: float
) -> None:
    """With this shape's generated kernel compiled, pick and plan_start never ask whether the generic
    kernel is compiled (that imports its module: ~0.1-0.5 s of a short run) whenever the generated one
    wins anyway; the kernel picked equals the full comparison with the generic kernel compiled."""
    from crashstudy.kernel import generated

    b, plan = _batch(n, end_time)
    asked = []
    monkeypatch.setattr(choice, "_LOADED", set())
    monkeypatch.setattr(choice, "kernel_override", lambda: "compiled")
    monkeypatch.setattr(generated, "is_compiled", lambda *a, **k: True)
    monkeypatch.setattr(choice, "generic_ready", lambda: asked.append(1) or True)
    picked = choice.pick(b, (), None, "compiled", repeat)
    truth = _full_choice(b, repeat, generic=True)
    assert picked == truth
    assert not asked or truth == "generic"
    assert choice.plan_start(b, (), None, int(n * repeat)) is None
    assert not asked or truth == "generic"


DT_MODEL = (
    LINEAR_SPRING.replace("end_time: 0.1", "end_time: 0.05")
    + "time_step: {dt: 0.004}\noutput: {histories: none}\n"
)


@pytest.mark.parametrize("seed", range(8))
def test_fixed_dt_check_equals_every_variants_batch_and_builds_only_distinct_steps(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    """The pre-run check of a fixed dt (study.sanity._dt_refused) refuses exactly the variants whose
    batch (build_batch over every variant: the independent truth) is refused, with their critical
    steps; and it computes one step choice per distinct setting of the dimensions holding a non-velocity
    axis (velocity axes and zip groups of velocities multiply the variants, not the work)."""
    from crashstudy.arrays import batch as batch_mod
    from crashstudy.arrays.batch import build_batch
    from crashstudy.study import sanity
    from crashstudy.study.plan import load_study

    rng = np.random.default_rng(seed)
    (tmp_path / "m.yaml").write_text(DT_MODEL)
    choices = {
        "nodes.body.mass": [0.05, 0.3, 2.0, 0.1],
        "springs.s.material.stiffness": [1.0e4, 4.0e4, 9.0e4],
        "impact_velocity": [1.0, 2.0, 3.0],
        "initial_velocity.body.0": [0.5, -1.0],
    }
    matrix = {}
    for path in rng.permutation(list(choices)):
        k = int(rng.integers(1, len(choices[path]) + 1))
        matrix[str(path)] = [float(v) for v in rng.choice(choices[path], size=k, replace=False)]
    study: dict[str, Any] = {"name": "s", "model": str(tmp_path / "m.yaml"), "matrix": matrix}
    if seed % 2:  # a zip group of two velocity axes beside the matrix
        study["matrix"].pop("impact_velocity", None)
        study["matrix"].pop("initial_velocity.body.0", None)
        study["zip"] = [{"impact_velocity": [1.0, 2.5, 4.0], "initial_velocity.body.0": [1.0, -1.0, 2.0]}]
    plan = load_study(study)
    n = plan.n_variants
    _, steps = build_batch(plan.topology, plan.params(0, n), plan.interval)
    built = []
    real = sanity.fixed_dt_check
    monkeypatch.setattr(sanity, "fixed_dt_check", lambda t, P: built.append(P.shape[1]) or real(t, P))
    refused, crit = sanity._dt_refused(plan)
    np.testing.assert_array_equal(refused, np.flatnonzero(steps.refused))
    np.testing.assert_array_equal(crit, steps.dt_crit[steps.refused])
    other = [p for p in plan.topology.paths if p in ("nodes.body.mass", "springs.s.material.stiffness")]
    distinct = int(np.prod([len(matrix[p]) for p in other if p in matrix] or [1]))
    assert sum(built) == distinct, (matrix, built)
    assert np.array_equal(
        batch_mod.variant_steps(plan.topology, plan.params(0, n), plan.interval).dt_crit, steps.dt_crit
    )  # the step choice alone equals the batch's


def test_a_chunk_is_built_in_step_order_never_copied_and_its_numbers_are_unchanged(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A chunk whose variants' step counts are unsorted (a safety-factor step over a mass axis given
    heavy-light-heavy) is built in step order: the kernel entry never copies the batch into that order
    (``Batch.take`` not called), and every output equals the earlier path's (build the batch in variant
    order, then ``entry.run_ordered`` sorts it with a copy) bitwise, on the NumPy reference kernel."""
    from crashstudy.arrays.batch import Batch, build_batch
    from crashstudy.kernel import entry
    from crashstudy.run.runner import run_chunk
    from crashstudy.study.plan import load_study

    text = DT_MODEL.replace("time_step: {dt: 0.004}", "time_step: {safety_factor: 0.5}")
    (tmp_path / "m.yaml").write_text(text.replace("{histories: none}", "{histories: none, interval: 0.05}"))
    masses = [2.0, 0.05, 1.0, 0.2, 3.0, 0.5, 0.1, 1.5]
    plan = load_study(
        {
            "name": "s",
            "model": str(tmp_path / "m.yaml"),
            "matrix": {"nodes.body.mass": masses, "impact_velocity": [1.0, 2.0]},
        }
    )
    n = plan.n_variants
    batch, _ = build_batch(plan.topology, plan.params(0, n), plan.interval)
    assert not np.all(np.diff(batch.n_steps) >= 0)  # the case: unsorted, spread beyond SORT_SPREAD
    assert np.ptp(batch.n_steps) > entry.SORT_SPREAD * batch.n_steps.max()
    before, _ = entry.run_ordered(batch, (), plan.n_out, np.arange(n), "reference")
    taken = []
    real = Batch.take
    monkeypatch.setattr(Batch, "take", lambda self, idx: taken.append(len(idx)) or real(self, idx))
    after = run_chunk(plan, 0, n, "reference")
    assert not taken
    for name in ("status", "peak_force", "max_crush", "absorbed_energy", "peak_acceleration", "energy_error"):
        np.testing.assert_array_equal(getattr(after.out, name), getattr(before, name), err_msg=name)


def test_a_chunk_with_repeated_variants_is_made_from_variant_numbers_in_step_order(tmp_path: Any) -> None:
    """``chunk._step_order`` takes the variant numbers of a chunk's distinct variants and makes their
    parameters in step order from those numbers (``Plan.params_at``; gathering the columns of the unsorted
    matrix cost 16x as much): equal to the brute-force sort of the unsorted parameters; and a chunk with
    repeated variants (a mass given twice) equals each variant run alone, bitwise, on the NumPy reference."""
    from crashstudy.arrays.batch import build_batch, variant_steps
    from crashstudy.kernel import entry
    from crashstudy.run.chunk import _step_order, run_chunk
    from crashstudy.study.plan import load_study
    from helpers import assert_bitwise

    text = DT_MODEL.replace("time_step: {dt: 0.004}", "time_step: {safety_factor: 0.5}")
    (tmp_path / "m.yaml").write_text(text.replace("{histories: none}", "{histories: none, interval: 0.05}"))
    masses = [2.0, 0.05, 1.0, 0.2, 2.0, 0.5, 0.05]
    plan = load_study(
        {
            "name": "s",
            "model": str(tmp_path / "m.yaml"),
            "matrix": {"impact_velocity": [1.0, 2.0], "nodes.body.mass": masses},
        }
    )
    n = plan.n_variants
    cols = np.array([1, 2, 3, 4, 6, 8, 10])
    inverse = np.arange(len(cols))
    P, inv = _step_order(plan, cols, inverse)
    unsorted = plan.params(0, n)[:, cols]
    order = np.argsort(variant_steps(plan.topology, unsorted, plan.interval).n_steps, kind="stable")
    np.testing.assert_array_equal(P, unsorted[:, order])
    np.testing.assert_array_equal(P[:, inv], unsorted)
    assert not plan.variants_distinct
    got = run_chunk(plan, 0, n, "reference")
    for k in range(n):
        alone, _ = entry.run_ordered(
            build_batch(plan.topology, plan.params(k, k + 1), plan.interval)[0],
            (),
            plan.n_out,
            np.arange(1),
            "reference",
        )
        assert_bitwise(alone, entry.spread_columns(got.out, np.array([k]), (), plan.n_out))
