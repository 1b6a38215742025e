"""Crash criteria (SPEC 6b): every criterion converges as dt is halved; batch rows with their own steps,
counts and directions equal single runs; variants split over threads, the plain-Python criteria and the
warm-up process give the compiled values bitwise; unknown criteria or classes are refused.

Tolerances are stated at each assert. Pulses are written down exactly (prescribed acceleration)."""

from __future__ import annotations

import numpy as np
import pytest

from crashstudy.metrics import criteria as C
from pulses import G, one

# --------------------------------------------------------------------------- convergence, batching


def smooth_pulse(t: np.ndarray) -> np.ndarray:
    """A smooth (C1) 70 ms deceleration with an 80 Hz ripple, peak ~ 35 g."""
    tau = 0.07
    s = np.clip(t / tau, 0.0, 1.0)
    return np.where(t <= tau, 30 * G * np.sin(np.pi * s) ** 2 * (1 + 0.2 * np.sin(2 * np.pi * 80 * t)), 0.0)


def test_every_criterion_converges_as_dt_is_halved() -> None:
    """dt = 40, 20, 10, 5 us (CFC 180; 25-200 kHz) against dt = 2.5 us: at 40 us every criterion is
    within 0.2 % of the reference, and the error divided by dt^2 does not grow as dt is halved
    (at most 4x its value at 40/20 us, allowing for the samples' phase; a first-order error would
    grow 8x over three halvings), up to 1e-8 of the value for the reference's own error."""
    names = list(C.CRITERIA)
    keys = names + ["hic15_t1", "hic15_t2", "hic36_t1", "hic36_t2"]
    vals: dict[str, list[float]] = {k: [] for k in keys}
    dts = np.array([4e-5, 2e-5, 1e-5, 5e-6, 2.5e-6])
    for dt in dts:
        t = np.arange(int(round(0.12 / dt)) + 1) * dt
        r = one(-smooth_pulse(t), dt, names=names, cfc=180, v0=16.0)
        assert r["criteria_note"] == ""
        for k in keys:
            vals[k].append(r[k])
    for k in names:
        v = np.array(vals[k])
        err = np.abs(v[:-1] - v[-1])
        assert err[0] <= 2e-3 * abs(v[-1]), (k, v)
        scaled = np.maximum(err - 1e-8 * abs(v[-1]), 0.0) / dts[:-1] ** 2
        assert (scaled <= 4 * scaled[:2].max() + 1e-30).all(), (k, v)
    for k in keys[len(names) :]:  # the interval's ends settle to within a step
        assert abs(vals[k][-2] - vals[k][-1]) <= 5e-6, (k, vals[k])


def test_batch_rows_with_own_steps_counts_directions_equal_single_runs() -> None:
    """Variants with different dt, count, 2-D directions and NaN past their count: each equals
    the 1-D run of the same pulse along its direction (resultant and projection are rotation-free)."""
    rng = np.random.default_rng(4)
    nv, nt = 6, 9000
    dts = rng.uniform(1e-5, 2e-5, nv)
    counts = rng.integers(5000, nt + 1, nv)
    counts[2] = 1  # too short
    angles = rng.uniform(0, 2 * np.pi, nv)
    acc = np.full((nv, nt, 2), np.nan)
    v0 = np.zeros((nv, 2))
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    pulses = []
    for v in range(nv):
        t = np.arange(counts[v]) * dts[v]
        p = -smooth_pulse(t * rng.uniform(0.8, 1.2))
        pulses.append(p)
        acc[v, : counts[v]] = p[:, None] * dirs[v]
        v0[v] = 16.0 * dirs[v]
    acc[4, 100, 1] = np.nan  # a variant whose solve failed
    r = C.compute(acc, counts, dts, v0, dirs, 180, C.CRITERIA, G)
    assert all(np.isnan(r[k][4]) for k in r if k != "criteria_note") and "not finite" in r["criteria_note"][4]
    for v in range(nv):
        if v == 4:
            continue
        if counts[v] < 2:
            assert all(np.isnan(r[k][v]) for k in r if k != "criteria_note")
            assert r["criteria_note"][v] == "fewer than 2 samples"
            continue
        ref = one(pulses[v], dts[v], cfc=180, v0=16.0)
        for k in ref:
            if k != "criteria_note":
                assert r[k][v] == pytest.approx(ref[k], rel=1e-9, abs=1e-12, nan_ok=True), (v, k)
        assert r["criteria_note"][v] == ref["criteria_note"]
    # a single (D,) direction broadcasts to every variant
    r1 = C.compute(acc[:1], counts[:1], dts[:1], v0[:1], dirs[0], 180, ["olc", "dri"], G)
    assert r1["olc"][0] == pytest.approx(r["olc"][0], rel=1e-12)


def test_unknown_criterion_or_class_is_refused() -> None:
    acc = np.zeros((1, 10, 1))
    with pytest.raises(ValueError, match="unknown criteria"):
        C.compute(acc, np.array([10]), np.array([1e-5]), np.zeros((1, 1)), np.ones(1), 180, ["hic"], G)
    with pytest.raises(ValueError, match="cfc"):
        C.compute(acc, np.array([10]), np.array([1e-5]), np.zeros((1, 1)), np.ones(1), 100, ["hic15"], G)
    r = C.compute(
        acc, np.array([10]), np.array([1e-5]), np.zeros((1, 1)), np.ones(1), 180, ["hic15", "peak_g"], G
    )
    assert set(r) == {"hic15", "hic15_t1", "hic15_t2", "peak_g", "criteria_note"}
    assert r["hic15"][0] == 0.0 and np.isnan(r["hic15_t1"][0]) and r["peak_g"][0] == 0.0  # a quiet record


def test_variants_split_over_threads_give_the_single_thread_values_bitwise(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The driver runs parts of the variants side by side; each variant's row is its own, so the
    values equal the one-thread run bit for bit (second implementation: the same driver unsplit)."""
    from crashstudy.kernel import driver

    rng = np.random.default_rng(7)
    nv, nt = 7, 3000
    dts = rng.uniform(1e-5, 2e-5, nv)
    counts = rng.integers(1000, nt + 1, nv)
    acc = np.zeros((nv, nt, 1))
    for v in range(nv):
        acc[v, : counts[v], 0] = -smooth_pulse(np.arange(counts[v]) * dts[v] * rng.uniform(0.8, 1.2))
    v0 = np.full((nv, 1), 16.0)
    old = driver.get_threads()
    try:
        driver.set_threads(1)
        one_thread = C.compute(acc, counts, dts, v0, [1.0], 180, C.CRITERIA, G)
        monkeypatch.setattr(C, "MIN_PART", 1)
        driver.set_threads(3)
        split = C.compute(acc, counts, dts, v0, [1.0], 180, C.CRITERIA, G)
    finally:
        driver.set_threads(old)
    for k, arr in one_thread.items():
        assert (
            np.array_equal(arr, split[k], equal_nan=True)
            if k != "criteria_note"
            else list(arr) == list(split[k])
        )


def test_plain_python_criteria_equal_the_compiled_ones_bitwise(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a machine where the criteria are not compiled, a small record runs the driver's own code as
    plain Python (crashstudy.metrics.interpreted): every criterion, t1/t2 and note equals the compiled
    driver's bit for bit (numba compiles without fast-math), and so does the J211 filter; past
    PLAIN_MAX_SAMPLES interpreted samples a process compiles."""
    from crashstudy.metrics import criteria_filter as F
    from crashstudy.metrics import interpreted

    rng = np.random.default_rng(11)
    nv, nt = 5, 2500
    dts = rng.uniform(1e-4, 4e-4, nv)
    counts = rng.integers(300, nt + 1, nv)
    acc = np.zeros((nv, nt, 2))
    for v in range(nv):
        t = np.arange(counts[v]) * dts[v]
        acc[v, : counts[v], 0] = -smooth_pulse(t * rng.uniform(0.8, 1.2)) + rng.normal(0.0, 20.0, counts[v])
        acc[v, : counts[v], 1] = rng.normal(0.0, 30.0, counts[v])
    v0 = np.tile([16.0, 0.0], (nv, 1))
    compiled = C.compute(acc, counts, dts, v0, [1.0, 0.0], 180, C.CRITERIA, G)
    filt = F.j211_filter(acc[:, :, 0], counts, dts, 60)
    monkeypatch.setattr(interpreted, "compiled_or_cached", lambda fn: False)
    monkeypatch.setattr(interpreted, "_SPENT", [0])
    assert interpreted.driver_for(C._driver, 10)[1] is False
    plain = C.compute(acc, counts, dts, v0, [1.0, 0.0], 180, C.CRITERIA, G)
    assert interpreted._SPENT[0] == 10 + int(counts.sum())  # it did run interpreted
    for k, arr in compiled.items():
        assert (
            np.array_equal(arr, plain[k], equal_nan=True)
            if k != "criteria_note"
            else list(arr) == list(plain[k])
        )
    assert np.array_equal(F.j211_filter(acc[:, :, 0], counts, dts, 60), filt, equal_nan=True)
    monkeypatch.setattr(interpreted, "_SPENT", [interpreted.PLAIN_MAX_SAMPLES])
    assert interpreted.driver_for(C._driver, 1) == (C._driver, True)


def test_the_criteria_warm_up_process_takes_the_compiled_functions(monkeypatch: pytest.MonkeyPatch) -> None:
    """The process that compiles the criteria beside a kernel (kernel/warm.py calls
    metrics/warmup.compile_criteria) runs a short pulse, which
    would otherwise run as plain Python and leave nothing compiled: it must call the numba functions
    (recorded by wrapping the driver the warm-up gets)."""
    from crashstudy.metrics import interpreted, warmup

    monkeypatch.setattr(interpreted, "compiled_or_cached", lambda fn: False)
    monkeypatch.setattr(interpreted, "_SPENT", [0])
    got: list[bool] = []
    real = interpreted.driver_for
    monkeypatch.setattr(C, "driver_for", lambda fn, n: got.append(real(fn, n)[1]) or real(fn, n))
    warmup.compile_criteria()
    assert got == [True]
