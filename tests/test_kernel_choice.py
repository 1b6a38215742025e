"""Kernel choice by expected time (crashstudy.kernel.choice): a tiny run never waits for a compiler, a
compile in the background makes the next chunk (and the next run) compiled, Ctrl-C stops a compile or
a reference run at once, and the numbers never depend on which kernel ran."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from crashstudy.arrays.batch import build_batch
from crashstudy.arrays.compiler import apply_axis
from crashstudy.kernel import choice
from crashstudy.kernel.decision import StartPlan, decide
from crashstudy.kernel.output import KernelOutput
from crashstudy.kernel.reference import STOP_EVERY, run_reference
from crashstudy.run.runner import Progress, run_kernel
from helpers import ROOT, model_plan


def _chain(n_springs: int, end_time: float, stiffness: float = 2.0e5) -> dict:
    """A 1-D chain of unit masses hit at 10 m/s (its own shape: no other test compiles it)."""
    nodes = {"n0": {"position": [0.0], "fixed": True}}
    springs = {}
    for k in range(1, n_springs + 1):
        nodes[f"n{k}"] = {"position": [0.1 * k], "mass": 1.0 + 0.25 * k}
        springs[f"s{k}"] = {
            "nodes": [f"n{k - 1}", f"n{k}"],
            "material": {"type": "linear_elastic", "stiffness": stiffness * (1 + 0.1 * k)},
        }
    return {
        "name": f"chain{n_springs}",
        "nodes": nodes,
        "springs": springs,
        "end_time": end_time,
        "initial_velocity": {f"n{n_springs}": [-10.0]},
        "output": {"histories": ["spring_force"]},
    }


def _batch(model: dict, n: int):
    plan = model_plan(model)
    P = np.repeat(plan.base[:, None], n, axis=1)
    apply_axis(P, plan.topology.paths["nodes.n1.mass"], np.linspace(1.0, 2.0, n))
    batch, _ = build_batch(plan.topology, P, plan.interval)
    return batch, plan


def _bitwise(a: KernelOutput, b: KernelOutput) -> None:
    for name in ("status", "peak_force", "max_crush", "absorbed_energy", "peak_acceleration", "energy_error"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for h in a.histories:
        np.testing.assert_array_equal(a.histories[h], b.histories[h], err_msg=h)


def test_reference_time_model_matches_its_calibration_points() -> None:
    """The cost model reproduces the reference timings it was fitted to (benchmarks/reference_cost.py, quiet
    2-core machine, 2026-11-27): one linear spring 299 us/step, frontal (8 springs) one variant 1891 us/step
    and 1000 variants 3486 us/step, each within 10%."""
    assert choice.reference_seconds(1, 1, 1) == pytest.approx(299e-6, rel=0.1)
    assert choice.reference_seconds(1, 8, 8) == pytest.approx(1891e-6, rel=0.1)
    assert choice.reference_seconds(1, 8, 8000) == pytest.approx(3486e-6, rel=0.1)


def test_a_tiny_run_takes_the_reference_even_when_nothing_is_compiled(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """One variant of 400 steps: expected reference time ~0.12 s, below loading any compiled kernel,
    so the reference runs whatever is compiled; its numbers equal the generic kernel's bitwise."""
    batch, plan = _batch(_chain(1, 0.008), 1)
    assert choice.reference_seconds(float(batch.n_steps.max()), 1, float(batch.n_steps.sum())) < choice.LOAD
    monkeypatch.setattr(choice, "_LOADED", set())  # compiled on disk, not loaded in this process
    for ready in (False, True):
        monkeypatch.setattr(choice, "generic_ready", lambda r=ready: r)
        assert choice.pick(batch, plan.topology.histories, None) == "reference"
    _bitwise(
        run_kernel(batch, plan.topology.histories, plan.n_out, "generic"),
        run_kernel(batch, plan.topology.histories, plan.n_out),
    )


def test_a_long_run_compiles_the_quicker_kernel_only_when_that_beats_the_reference(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """With nothing compiled and no other process compiling, a chunk whose reference time exceeds a
    kernel's compile + run time goes to the kernel quicker to compile and run: this shape's generated
    one (3 linear springs: ~3 s against the generic kernel's 50 s), the generic one when the generated
    kernel cannot run the shape; a shorter chunk to the reference; while a background compile this run
    started is running, the reference (the run planned for it; another process's compile never strands
    a run: tests/test_compile_lock.py)."""
    from crashstudy.kernel import generated

    monkeypatch.setattr(choice, "generic_ready", lambda: False)
    monkeypatch.setattr(choice, "generated_ready", lambda *a: False)
    monkeypatch.setattr(choice, "own_compile_running", lambda: False)
    short, plan = _batch(_chain(3, 0.2), 8)
    gen_cost = choice.generated_compile_seconds(short.material, 0)
    assert (
        gen_cost == pytest.approx(choice.GEN_BASE + 3 * choice.GEN_SPRING)
        and gen_cost < choice.GENERIC_COMPILE
    )
    t_short = choice.reference_seconds(float(short.n_steps.max()), 3, float(short.n_steps.sum()) * 3)
    assert choice.LOAD < t_short < gen_cost
    assert choice.pick(short, (), None) == "reference"
    per_step = choice.REF_STEP + 3 * choice.REF_SPRING_STEP
    mid = short.take(np.zeros(8, dtype=np.int64))
    mid.n_steps[:] = int(1.2 * (gen_cost + choice.LOAD) / per_step)
    assert choice.pick(mid, (), None) == "generated"
    monkeypatch.setattr(generated, "unsupported", lambda b: "a shape it cannot run")
    assert choice.pick(mid, (), None) == "reference"
    long_batch = short.take(np.zeros(8, dtype=np.int64))
    long_batch.n_steps[:] = int(1.2 * choice.GENERIC_COMPILE / per_step)
    assert choice.pick(long_batch, (), None) == "generic"
    monkeypatch.setattr(choice, "own_compile_running", lambda: True)
    assert choice.pick(long_batch, (), None) == "reference"


def test_compile_estimates_match_the_measured_cold_compiles() -> None:
    """generated_compile_seconds against the cold compiles of benchmarks/results/compile_costs.md
    (generated kernel, histories none, 2-core machine), each within 30 %: linear spring 2.95 s,
    general_nonlinear 5.47 s, helicopter (2 general_nonlinear, 2-D) 8.15 s, frontal (2 general_nonlinear
    + 6 others) 10.3 s; and every one of them below the generic kernel's compile."""
    from crashstudy.vocabulary.codes import GENERAL, LINEAR

    def mats(general: int, other: int) -> np.ndarray:
        return np.array([GENERAL] * general + [LINEAR] * other)

    for (general, other), measured in {(0, 1): 2.95, (1, 0): 5.47, (2, 0): 8.15, (2, 6): 10.3}.items():
        estimate = choice.generated_compile_seconds(mats(general, other), 0)
        assert estimate == pytest.approx(measured, rel=0.3), (general, other)
        assert estimate < choice.GENERIC_COMPILE


def test_decisions_are_never_slower_than_compiling_the_generic_kernel_first() -> None:
    """The cases of :func:`crashstudy.kernel.decision.decide`, with the frontal 10^4-variant study's estimates (reference
    76 s, generic 1.7 s, generated 0.8 s; compile 24 s generic, 11 s generated): compiling the
    generated kernel first and running it (11.8 s) beats the reference and the generic kernel first
    (25.7 s); with the crash criteria missing too, they compile beside it; a shape the generated kernel
    cannot run gets the generic kernel first, and so does one whose generated kernel is slower to
    compile (then compiled during the run); a 10 s run starts on the reference and compiles the
    generated kernel beside it; with the generic kernel compiled, the generated one is compiled during
    the run only when the run is twice its compile time, else after."""
    both = {"generic": 24.0, "generated": 11.0}
    d = decide(StartPlan(dict(both), 76.0, 1.7, 0.8, "frontal"), background=True)
    assert d.foreground == ("generated",) and not d.now and not d.after and not d.small_chunks
    assert d.estimate == pytest.approx(11.8)
    d = decide(StartPlan(dict(both), 76.0, 1.7, 0.8, "frontal", criteria=7.0), background=False)
    assert d.foreground == ("generated", "criteria") and d.estimate == pytest.approx(11.8)
    d = decide(StartPlan({"generic": 24.0}, 76.0, 1.7, 1.7, "unsupported"), background=True)
    assert d.foreground == ("generic",) and d.estimate == pytest.approx(25.7)
    big = {"generic": 24.0, "generated": 60.0}  # a shape whose generated kernel takes longer to compile
    d = decide(StartPlan(dict(big), 200.0, 130.0, 100.0, "big"), background=True)
    assert d.foreground == ("generic",) and d.now == ("generated",) and d.estimate == pytest.approx(154.0)
    d = decide(StartPlan(dict(both), 10.0, 0.5, 0.3, "short"), background=True)
    assert d.now == ("generated",) and d.small_chunks and not d.foreground and d.estimate == 10.0
    assert decide(StartPlan(dict(both), 10.0, 0.5, 0.3, "short"), background=False).now == ()
    gen = {"generated": 10.0}
    assert decide(StartPlan(dict(gen), 300.0, 30.0, 10.0, "long"), background=True).now == ("generated",)
    assert decide(StartPlan(dict(gen), 300.0, 15.0, 5.0, "mid"), background=True).after == ("generated",)
    assert decide(StartPlan(dict(gen), 300.0, 30.0, 10.0, "long"), False).foreground == ("generated",)
    assert decide(StartPlan(dict(gen), 300.0, 15.0, 8.0, "mid"), False).foreground == ()


def test_background_compile_makes_the_generated_kernel_ready_and_its_numbers_are_the_references(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A fresh private kernel cache: the shape is not compiled; :func:`start_background` compiles it in a
    child process; afterwards :func:`pick` takes the generated kernel for a chunk worth loading it and
    its results are bitwise the reference's. (One spring: the compile is the subject, not the model; a
    1-spring kernel compiled in ~9 CPU s against ~11.5 for the 2-spring chain used before. Its histories
    make it a shape of its own: a shape another test of this process loaded from another kernel folder
    would not be seen as ready here.)"""
    monkeypatch.setenv("CRASHSTUDY_KERNEL_CACHE", str(tmp_path / "kernels"))
    model = _chain(1, 0.2, stiffness=3.0e5)
    model["output"] = {"histories": ["spring_force", "spring_elongation"]}
    batch, plan = _batch(model, 64)
    hist = plan.topology.histories
    assert not choice.generated_ready(batch, hist, None)
    proc = choice.start_background(("generated",), batch, hist, None)
    assert proc is not None
    assert proc.wait(timeout=500) == 0
    assert choice.generated_ready(batch, hist, None)
    assert not list((tmp_path / "kernels").glob(".warm-*.npz")), "the job file is removed"
    monkeypatch.setattr(choice, "LOAD", 0.0)
    assert choice.pick(batch, hist, None) == "generated"
    _bitwise(run_reference(batch, hist, plan.n_out), run_kernel(batch, hist, plan.n_out))


def test_ctrl_c_stops_a_foreground_compile_and_kills_the_compiler(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``stop`` raising (what Ctrl-C does through crashstudy.interrupt) ends the wait with
    KeyboardInterrupt and the compiler process is killed: the shape never becomes compiled."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL_CACHE", str(tmp_path / "kernels"))
    batch, plan = _batch(_chain(4, 0.2), 4)
    started: list[subprocess.Popen] = []
    real = choice.start_background
    monkeypatch.setattr(
        choice, "start_background", lambda *a, **k: started.append(real(*a, **k)) or started[-1]
    )
    calls = []

    def stop() -> None:
        calls.append(1)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        choice.compile_foreground(("generated",), batch, plan.topology.histories, None, stop)
    assert calls == [1] and started[0].returncode is not None and started[0].returncode < 0
    assert not choice.generated_ready(batch, plan.topology.histories, None)


def test_ctrl_c_stops_the_reference_within_its_stop_interval() -> None:
    """The reference calls ``check`` every STOP_EVERY steps: a check that raises on its third call
    ends a 20,000-step run there."""
    batch, plan = _batch(_chain(1, 1.0), 2)
    assert batch.n_steps.max() > 10 * STOP_EVERY
    calls = []

    def stop() -> None:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_reference(batch, (), 1, stop)
    assert len(calls) == 3


def test_progress_line_never_shows_an_infinite_eta_and_writes_lines_into_a_file() -> None:
    """Before the first chunk the ETA is the estimate ('starting  ETA ~12 s'); afterwards a rate; into a
    file (not a terminal) one line per update, no carriage returns."""
    out = io.StringIO()
    bar = Progress(100, enabled=True, stream=out, estimate=12.0)
    bar.start(0)
    bar.update(100)
    bar.close()
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue() and len(lines) == 2
    assert lines[0].startswith("  0/100 variants  starting  ETA ~1") and "inf" not in out.getvalue()
    assert lines[1].startswith("  100/100 variants") and "ETA 0 s" in lines[1]


def test_cli_run_of_a_small_study_on_empty_caches_compiles_nothing(tmp_path: Path) -> None:
    """The README's example study on empty kernel and numba caches, background compiles allowed: the run
    is short, so nothing is compiled (no numba cache file) and no note is printed;
    its peaks equal an in-process reference run of variant 0."""
    env = dict(
        os.environ,
        HOME=str(tmp_path / "home"),
        NUMBA_CACHE_DIR=str(tmp_path / "numba"),
        CRASHSTUDY_KERNEL_CACHE=str(tmp_path / "kernels"),
        CRASHSTUDY_BACKGROUND_COMPILE="1",
    )
    env.pop("CRASHSTUDY_KERNEL", None)
    out = tmp_path / "res"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "crashstudy.cli",
            "run",
            str(ROOT / "studies/subfloor-small.yaml"),
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "note:" not in proc.stderr
    # nothing compiled: no numba index anywhere (the kernel folder may hold the generated source that the
    # choice's readiness check writes to find that index: text, not a compile)
    assert not list(tmp_path.rglob("*.nbi")) and not list(tmp_path.rglob("*.nbc"))
    import pandas as pd

    from crashstudy.study.plan import load_study

    summary = pd.read_csv(out / "summary.csv")
    plan = load_study(ROOT / "studies/subfloor-small.yaml")
    batch, _ = build_batch(plan.topology, plan.params(0, plan.n_variants), plan.interval)
    ref = run_reference(batch, (), 1)
    assert len(summary) == 12 and (summary["status"] == "ok").all()
    for s, sid in enumerate(plan.topology.spring_ids):
        np.testing.assert_allclose(summary[f"peak_force.{sid}"], ref.peak_force[s], rtol=1e-12)
