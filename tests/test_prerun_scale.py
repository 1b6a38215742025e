"""Pre-run checks scale with the distinct axis values, not the variants (issue 25 item 2, issue 24
item 9): the "axis changes nothing" check against a brute force over every variant, and its memory at
10^7 variants."""

from __future__ import annotations

import tracemalloc
from typing import Any

import numpy as np
import pytest

from crashstudy.study.plan import load_study
from crashstudy.study.sanity import _axis_changes_model, check_plan
from helpers import LINEAR_SPRING

MODEL = LINEAR_SPRING.replace("end_time: 0.1", "end_time: 0.05") + "output: {histories: none}\n"


def _brute(plan: Any, path: str) -> bool:
    """Independent truth: some two variants that differ only in ``path`` have different parameters."""
    n = plan.n_variants
    if len(np.unique(plan.axis_values(0, n)[path])) < 2:
        return True  # one value is a fixed setting (like set:), never "changes nothing"
    P, values = plan.params(0, n), plan.axis_values(0, n)
    others = [v for k, v in values.items() if k != path]
    key = np.stack(others, axis=1) if others else np.zeros((n, 0))
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.reshape(-1)
    return any(
        not np.array_equal(P[:, group == g], np.repeat(P[:, group == g][:, :1], (group == g).sum(), axis=1))
        for g in np.unique(group)
    )


@pytest.mark.parametrize("seed", range(12))
def test_axis_check_agrees_with_every_variant(tmp_path: Any, seed: int) -> None:
    """Matrix studies whose axes may do nothing (an initial velocity under impact_velocity 0, a repeated
    value) or matter only for some values of another axis: the check equals the brute force."""
    rng = np.random.default_rng(seed)
    (tmp_path / "m.yaml").write_text(MODEL)
    choices = {
        "initial_velocity.body.0": [1.0, -2.0, 3.0],
        "impact_velocity": [0.0, 0.0, 1.5, 2.0],
        "nodes.body.mass": [2.0, 2.0, 3.0],
        "springs.s.material.stiffness": [2.0e4, 3.0e4],
    }
    matrix = {}
    for path in rng.permutation(list(choices)):
        k = int(rng.integers(1, len(choices[path]) + 1))
        matrix[str(path)] = [float(v) for v in rng.choice(choices[path], size=k, replace=False)]
    plan = load_study({"name": "s", "model": str(tmp_path / "m.yaml"), "matrix": matrix})
    for ax in plan.axes:
        assert _axis_changes_model(plan, ax) == _brute(plan, ax.path), (matrix, ax.path)


def test_axis_that_matters_for_one_value_of_a_big_axis_is_found_by_the_sample(tmp_path: Any) -> None:
    """220,000 settings of the other axes (more than are ever built): the initial velocity's sign matters
    only at impact_velocity 1.5 (0 rescales it away); the sample always holds each dimension's first and
    last row, so it is found; with impact_velocity all 0 it changes nothing (refused)."""
    import dataclasses

    (tmp_path / "m.yaml").write_text(MODEL)
    for speeds, changes in (([0.0, 1.5], True), ([0.0], False)):
        plan = load_study(
            {
                "name": "s",
                "model": str(tmp_path / "m.yaml"),
                "matrix": {
                    "initial_velocity.body.0": [1.0, -2.0],
                    "nodes.body.mass": [1.0, 3.0],
                    "impact_velocity": speeds,
                },
            }
        )
        iv, mass, speed = (
            plan.axes
        )  # the mass axis widened to 110,000 values (its validation is not under test)
        mass = dataclasses.replace(mass, values=np.linspace(1.0, 3.0, 110_000))
        plan = dataclasses.replace(plan, axes=(iv, mass, speed), shape=(2, 110_000, len(speeds)))
        assert _axis_changes_model(plan, iv) is changes


def test_checks_of_a_1e7_variant_study_take_memory_of_its_distinct_values(tmp_path: Any) -> None:
    """10^7 variants (1000 x 100 x 100): check_plan allocated the other axes' settings of 800,000 sampled
    variants per axis (about 60 MB; 2.3 s of np.unique at 10^6); now its peak follows the 1200 distinct values."""
    (tmp_path / "m.yaml").write_text(MODEL)
    plan = load_study(
        {
            "name": "s",
            "model": str(tmp_path / "m.yaml"),
            "matrix": {
                "nodes.body.mass": [float(v) for v in np.linspace(1.0, 3.0, 1000)],
                "springs.s.material.stiffness": [float(v) for v in np.linspace(1e4, 3e4, 100)],
                "impact_velocity": [float(v) for v in np.linspace(1.0, 2.0, 100)],
            },
        }
    )
    assert plan.n_variants == 10**7
    tracemalloc.start()
    try:
        problems, _ = check_plan(plan)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert not problems
    assert peak < 16 * 2**20, f"peak {peak / 2**20:.1f} MiB"


@pytest.mark.parametrize(("n", "size"), [(1, 4), (10, 3), (65536, 4096), (100_001, 65536)])
def test_ranges_of_a_fresh_run_cover_every_variant_once_in_order(n: int, size: int) -> None:
    """The fresh-run shortcut of reuse._ranges (no index array of every variant) gives the same ranges
    as a plain walk: consecutive, at most ``size`` long, covering 0 .. n - 1 exactly once."""
    from crashstudy.run.reuse import _ranges

    expected = [(lo, min(lo + size, n)) for lo in range(0, n, size)]
    assert _ranges(np.ones(n, dtype=bool), size) == expected
    todo = np.ones(n, dtype=bool)
    todo[0] = False  # the general path, for comparison
    assert _ranges(todo, size) == [
        (lo, hi)
        for lo, hi in [(1, min(1 + size, n))] + [(lo, min(lo + size, n)) for lo in range(1 + size, n, size)]
        if lo < hi
    ]


def test_work_estimate_counts_each_step_setting_once_and_exactly(tmp_path: Any, monkeypatch: Any) -> None:
    """90,000 variants (300 masses x 300 impact velocities): the step count depends on the mass only, so the
    estimate builds the 300 mass settings and weights each by the 300 velocities: equal (1e-12) to a count
    over every variant (before: a sample of 65,536 variants, scaled, and a full batch built for each)."""
    import crashstudy.arrays.batch as batch_mod
    from crashstudy.arrays.batch import build_batch
    from crashstudy.study.work import estimate_work

    (tmp_path / "m.yaml").write_text(
        MODEL.replace("end_time: 0.05", "end_time: 2.0").replace(
            "histories: none}", "histories: none, interval: 2.0}\ntime_step: {safety_factor: 0.5}"
        )
    )  # steps vary with the mass
    masses = [float(v) for v in np.linspace(1.0, 4.0, 300)]
    plan = load_study(
        {
            "name": "s",
            "model": str(tmp_path / "m.yaml"),
            "matrix": {
                "nodes.body.mass": masses,
                "impact_velocity": [float(v) for v in np.linspace(0.5, 3.0, 300)],
            },
        }
    )
    every = np.concatenate(
        [
            build_batch(plan.topology, plan.params(lo, min(lo + 30000, plan.n_variants)), plan.interval)[
                0
            ].n_steps
            for lo in range(0, plan.n_variants, 30000)
        ]
    )
    truth = float(every.sum())
    assert len(np.unique(every)) > 50
    built: list[int] = []
    real = batch_mod.variant_steps  # the step choice alone: estimate_work builds no whole batch

    def counted(topo: Any, P: np.ndarray, interval: float) -> Any:
        built.append(P.shape[1])
        return real(topo, P, interval)

    monkeypatch.setattr(batch_mod, "variant_steps", counted)
    monkeypatch.setattr(
        batch_mod, "build_batch", lambda *a: pytest.fail("a whole batch built to count steps")
    )
    work, worst, steps = estimate_work(plan)
    assert work == pytest.approx(truth * plan.topology.n_springs, rel=1e-12)
    assert sum(built) == 300
    assert steps == every.max() and every[worst] == every.max()
