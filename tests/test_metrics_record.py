"""The record the criteria are computed from: the per-step record, a chunk's record run in batches
within the budget, the criteria of a chunk on every kernel, and the block record (k steps a block,
docs/criteria.md "Record rate"): against the every-step record, bitwise the references' on the fast
kernels, and within tolerance on the examples.

The truth, a half-sine pulse imposed exactly with prescribed acceleration whose criteria have closed forms,
is described in half_sine_sled.py."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from half_sine_sled import A_G, T_PULSE, G, pulse_model


def _plan(tmp_path: Path, text: str, study: str = ""):
    from crashstudy.study.plan import load_study

    (tmp_path / "m.yaml").write_text(text)
    (tmp_path / "s.yaml").write_text(
        study or "name: s\nmodel: m.yaml\nmatrix:\n  curves.pulse.scale: [0.5, 1.0, 0.75]\n"
    )
    return load_study(tmp_path / "s.yaml")


# The per-step record of both fast kernels bitwise against the reference's on the twin models (prescribed
# displacement / velocity / acceleration, loads, gravity, walls, a variant crushed to zero length, early
# termination, lane compaction): tests/test_kernel_twins.py runs the cases of twins.RECORD_CASES with the
# record of every movable node, so one generated kernel per shape serves both files.


def test_step_record_is_the_acceleration_history_at_its_samples(tmp_path: Path) -> None:
    from crashstudy.arrays.batch import build_batch
    from crashstudy.kernel.reference import run_reference

    plan = _plan(tmp_path, _short_pulse())
    batch, _ = build_batch(plan.topology, plan.params(0, 3), plan.interval)
    assert batch.n_steps[0] % batch.out_every[0] != 0  # the last step is not a sample
    sled = plan.topology.node_ids.index("sled")
    out = run_reference(batch, ("acceleration",), plan.n_out, record=(sled,))
    rec = out.step_acceleration
    assert rec is not None and rec.shape == (int(batch.n_steps.max()) + 1, 1, 1, 3)
    every = int(batch.out_every[0])
    sampled = rec[::every][: plan.n_out, 0]  # (time, axis, variant)
    assert np.array_equal(sampled, out.histories["acceleration"][: len(sampled), sled])
    # the prescribed half-sine exactly, at every step (the curve's knots every 50 steps)
    t = np.arange(rec.shape[0]) * batch.dt[0]
    truth = np.where(t <= T_PULSE, -A_G * G * np.sin(np.pi * np.minimum(t, T_PULSE) / T_PULSE), 0.0)
    assert rec[:-1, 0, 0, 1] == pytest.approx(truth[:-1], abs=A_G * G * 2e-4)


def test_a_chunk_whose_record_passes_the_budget_runs_in_batches_with_the_same_results(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from crashstudy.metrics import record as metrics
    from crashstudy.run.runner import run_chunk

    plan = _plan(tmp_path, pulse_model())
    whole = run_chunk(plan, 0, 3)
    groups = metrics.batch_groups(np.array([3000, 3000, 3000]), 1, budget=8 * 3001 * 2)
    assert groups == [slice(0, 2), slice(2, 3)]
    from crashstudy.arrays.batch import build_batch
    from crashstudy.kernel.output import block_rows

    batch, _ = build_batch(plan.topology, plan.params(0, 3), plan.interval)
    rows = int(block_rows(batch.n_steps, metrics.record_blocks(plan.topology, batch.dt)).max())
    monkeypatch.setattr(metrics, "RECORD_BUDGET", 8 * rows)  # one variant's block record per batch
    calls = []
    real = metrics.criteria_of
    monkeypatch.setattr(metrics, "criteria_of", lambda *a: calls.append(a[1].n_variants) or real(*a))
    split = run_chunk(plan, 0, 3)
    assert calls == [1, 1, 1]
    for name, arr in whole.criteria.values.items():
        assert np.array_equal(arr, split.criteria.values[name], equal_nan=True), name
    assert np.array_equal(
        whole.out.histories["filtered_acceleration"],
        split.out.histories["filtered_acceleration"],
        equal_nan=True,
    )
    assert np.array_equal(whole.out.peak_acceleration, split.out.peak_acceleration)


@pytest.fixture(scope="module")
def every_criterion_reference(tmp_path_factory: pytest.TempPathFactory):
    """(plan, the reference's chunk of its 3 variants) of the half-sine sled with every criterion: run once
    for both fast kernels' comparisons."""
    from crashstudy.run.runner import run_chunk

    plan = _plan(
        tmp_path_factory.mktemp("criteria"),
        pulse_model(
            metrics="  - {node: sled, cfc: 600, criteria: [peak_g, hic15, clip3ms, "
            "clip3ms_cumulative, olc, dri, delta_v]}"
        ),
    )
    return plan, run_chunk(plan, 0, 3, kernel="reference")


@pytest.mark.parametrize("kernel", ["generic", "generated"])
def test_criteria_of_a_chunk_are_the_same_on_every_kernel(kernel: str, every_criterion_reference) -> None:
    """The criteria, notes and filtered pulse of a chunk computed on a fast kernel equal the reference's
    bit for bit (the record is bitwise equal, the criteria a function of it)."""
    from crashstudy.run.runner import run_chunk

    plan, ref = every_criterion_reference
    got = run_chunk(plan, 0, 3, kernel=kernel)
    assert set(ref.criteria.values) == set(got.criteria.values)
    for name, arr in ref.criteria.values.items():
        assert np.array_equal(arr, got.criteria.values[name], equal_nan=True), name
    assert list(ref.criteria.notes) == list(got.criteria.notes)
    f_ref, f_got = ref.out.histories["filtered_acceleration"], got.out.histories["filtered_acceleration"]
    assert np.array_equal(f_ref, f_got, equal_nan=True)


# ---- the block record (k steps a block, docs/criteria.md "Record rate") ----


def _short_pulse() -> str:
    """:func:`pulse_model` cut to 8.13 ms, inside the 10 ms pulse (samples every 0.1 ms): 813 steps, and the
    last block of every block size below (3, 5, 7, 9) is partial and holds non-zero accelerations, so its
    mean tells whether it was divided by the steps that ran (after the pulse the sled's record is 0, where
    any divisor gives 0); 27 % of the NumPy reference's time for the 30 ms model."""
    return pulse_model(extra="output: {interval: 1.0e-4}\n").replace(
        "end_time: 0.03\n", "end_time: 0.00813\n"
    )


def _step_record(tmp_path: Path, k: list[int]):
    """(batch, reference output) of the half-sine sled (3 variants, :func:`_short_pulse`) recorded with
    blocks ``k``."""
    from dataclasses import replace

    from crashstudy.arrays.batch import build_batch
    from crashstudy.kernel.reference import run_reference

    plan = _plan(tmp_path, _short_pulse())
    batch, _ = build_batch(plan.topology, plan.params(0, 3), plan.interval)
    batch = replace(batch, rec_block=np.asarray(k, dtype=np.int64))
    sled = plan.topology.node_ids.index("sled")
    return batch, run_reference(batch, (), plan.n_out, record=(sled,))


@pytest.fixture(scope="module")
def every_step(tmp_path_factory: pytest.TempPathFactory):
    """:func:`_step_record` with k = 1 (every step), run once for the tests that compare against it."""
    return _step_record(tmp_path_factory.mktemp("every"), [1, 1, 1])


@pytest.mark.parametrize("k", [[5, 5, 5], [1, 3, 5], [7, 1, 9]])
def test_block_record_of_the_reference_is_the_mean_of_the_every_step_record(
    k: list[int], tmp_path: Path, every_step
) -> None:
    """Row r of variant v is the mean of a^n over steps r k - h .. r k + h (h = (k - 1) / 2) that ran:
    the first row holds steps 0 .. h, the last the steps up to the end. Truth: the every-step record
    (k = 1) averaged by hand; 1e-12 of the largest |a| (summation order)."""
    from crashstudy.kernel.output import block_means, block_rows

    batch, every = every_step
    _, blocks = _step_record(tmp_path, k)
    assert every.step_acceleration is not None and blocks.step_acceleration is not None
    last = np.rint(every.t_end / batch.dt).astype(np.int64)
    means = block_means(blocks.step_acceleration, last, np.asarray(k))
    scale = float(np.max(np.abs(every.step_acceleration)))
    rows = block_rows(last, np.asarray(k))
    assert means.shape[0] == int(np.max(block_rows(batch.n_steps, np.asarray(k))))
    for v, kv in enumerate(k):
        h = (kv - 1) // 2
        for r in range(int(rows[v])):
            lo, hi = max(r * kv - h, 0), min(r * kv + h, int(last[v]))
            truth = every.step_acceleration[lo : hi + 1, :, :, v].mean(axis=0)
            assert np.max(np.abs(means[r, :, :, v] - truth)) <= 1e-12 * scale, (v, r)
        assert np.all(means[int(rows[v]) :, :, :, v] == 0.0)


def test_block_record_with_k_1_is_the_every_step_record_bit_for_bit(every_step) -> None:
    from crashstudy.kernel.output import block_means

    batch, every = every_step
    assert every.step_acceleration is not None
    assert every.step_acceleration.shape[0] == int(batch.n_steps.max()) + 1
    last = np.rint(every.t_end / batch.dt).astype(np.int64)
    assert np.array_equal(
        block_means(every.step_acceleration, last, np.ones(3, dtype=np.int64)), every.step_acceleration
    )


@pytest.mark.parametrize(
    "case",
    [
        "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls",
        "early-termination",
        "2d-crushed-to-zero",
    ],
)
def test_block_record_is_bitwise_the_references_on_the_fast_kernels(case: str) -> None:
    """Blocks of 1, 3, 5 and 7 steps mixed over the variants (lanes compacted, variants ending early or
    failing): every kernel adds a^n into the same rows in step order, so the sums are equal bit for bit
    (both fast kernels against one reference run)."""
    from dataclasses import replace

    from crashstudy.kernel.entry import run_batch
    from crashstudy.kernel.output import block_rows
    from helpers import output_differences
    from twins import record_case

    batch, plan, record = record_case(case)
    topo = plan.topology
    batch = replace(batch, rec_block=np.resize(np.array([1, 3, 5, 7]), batch.n_variants))
    ref = run_batch(batch, topo.histories, plan.n_out, "reference", record=record)
    assert ref.step_acceleration is not None and np.any(ref.step_acceleration != 0.0)
    seven = batch.rec_block == 7  # blocks, not every step: nothing past the last block's row
    assert np.all(
        ref.step_acceleration[int(np.max(block_rows(batch.n_steps[seven], 7))) :, ..., seven] == 0.0
    )
    for kernel in ("generic", "generated"):
        got = run_batch(batch, topo.histories, plan.n_out, kernel, record=record)
        assert output_differences(ref, got) == [], kernel


def test_record_blocks_are_odd_and_keep_the_record_rate() -> None:
    """k is odd (a block centred on its sample) and the largest odd k whose rate 1 / (k dt) is at least
    max(RECORD_RATE, RECORD_PER_CFC x the highest CFC); in a ms model dt is in ms."""
    from types import SimpleNamespace

    from crashstudy.metrics import record as metrics

    for units, second in (("SI", 1.0), ("mm-ms-kg-kN", 1e-3)):
        topo = SimpleNamespace(units=units, metrics=[SimpleNamespace(cfc=60), SimpleNamespace(cfc=1000)])
        rate = max(metrics.RECORD_RATE, metrics.RECORD_PER_CFC * 1000)
        dt = np.array([1e-7, 1e-6, 7.3e-6, 2e-5, 1e-4, 1e-3]) / second
        k = metrics.record_blocks(topo, dt)
        assert np.all(k % 2 == 1) and np.all(k >= 1)
        assert np.all((1.0 / (k * dt * second) >= rate * (1 - 1e-12)) | (k == 1))
        assert np.all(1.0 / ((k + 2) * dt * second) < rate)
    assert list(metrics.record_blocks(topo, np.array([1e-5]) / 1e-3)) == [9]  # 10 kHz at 10 us: 9 steps


EXAMPLE_STUDIES = {
    "frontal-occupant": "  curves.crash-box-loading.scale: [0.6, 1.2, 1.8]\n  impact_velocity: [13.889, 17.778]\n",
    "helicopter-seat": "  impact_velocity: [6.0, 8.2]\n",
}


def _example_criteria(
    tmp_path: Path, model: str, every_step: bool, tolerance: float | None, monkeypatch: pytest.MonkeyPatch
) -> dict[str, np.ndarray]:
    from crashstudy.metrics import record as metrics
    from crashstudy.run.runner import run_chunk

    d = tmp_path / f"{model}-{every_step}-{tolerance}"
    d.mkdir()
    (d / "m.yaml").write_text(
        (Path(__file__).resolve().parents[1] / "studies" / "models" / f"{model}.yaml").read_text()
    )
    ts = f"set:\n  time_step: {{tolerance: {tolerance}}}\n" if tolerance else ""
    plan = _plan(
        d, (d / "m.yaml").read_text(), f"name: s\nmodel: m.yaml\nmatrix:\n{EXAMPLE_STUDIES[model]}{ts}"
    )
    with monkeypatch.context() as mp:
        if every_step:
            mp.setattr(metrics, "RECORD_RATE", math.inf)
        res = run_chunk(plan, 0, plan.n_variants)
    assert np.all(res.out.status == 0)
    topo = plan.topology
    return {
        f"{name}.{topo.node_ids[n]}": arr[:, n]
        for name, arr in res.criteria.values.items()
        for n in range(topo.n_nodes)
        if np.all(np.isfinite(arr[:, n]))
    }


@pytest.mark.parametrize("model", list(EXAMPLE_STUDIES))
def test_criteria_from_the_block_record_are_within_tolerance_on_the_examples(
    model: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """At default settings (the step and the record rate crashstudy chooses) every criterion of the
    example models is within 0.5 % of the every-step record's (k = 1; measured at most 0.21 %,
    peak_g of the survival room at CFC 60) and within 1 % of the converged value (every step, the step
    halved: tolerance / 4); HIC t1/t2 relative to the largest t2 of the study."""
    dflt = _example_criteria(tmp_path, model, False, None, monkeypatch)
    every = _example_criteria(tmp_path, model, True, None, monkeypatch)
    conv = _example_criteria(tmp_path, model, True, 2.5e-4, monkeypatch)
    assert set(dflt) == set(every) == set(conv) and len(dflt) >= 6
    for name, truth in conv.items():
        times = name.split(".")[0].endswith(("_t1", "_t2"))
        scale = np.max(np.abs(truth)) if times else np.abs(truth)
        assert np.all(np.abs(dflt[name] - every[name]) <= 5e-3 * scale), name
        assert np.all(np.abs(dflt[name] - truth) <= 1e-2 * scale), name


def test_record_groups_are_the_longest_runs_within_the_budget() -> None:
    """batch_groups (by bisection) against its definition, grown one variant at a time."""
    from crashstudy.metrics import record as metrics

    def grown(n: np.ndarray, width: int, budget: int) -> list[slice]:
        out, lo = [], 0
        while lo < len(n):
            hi = lo + 1
            while hi < len(n) and 8.0 * (float(np.max(n[lo : hi + 1])) + 1) * width * (hi + 1 - lo) <= budget:
                hi += 1
            out.append(slice(lo, hi))
            lo = hi
        return out

    rng = np.random.default_rng(3)
    for _ in range(50):
        n = np.sort(rng.integers(1, 500, rng.integers(1, 60)))
        width, budget = int(rng.integers(1, 4)), int(rng.integers(100, 200_000))
        assert metrics.batch_groups(n, width, budget) == grown(n, width, budget)
