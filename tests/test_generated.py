"""Generated (model-specialised) kernels against the NumPy reference kernel.

The bitwise twin tests of both fast kernels are in test_kernel_twins (their models: twins.py); here:
what only the generated kernel has (the runner's kernel choice, the environment variable, termination
by closed form).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.kernel import generated
from crashstudy.run.runner import run_chunk
from crashstudy.study.plan import load_study
from helpers import assert_bitwise, generated_parts_model, model_batch, run_model
from twin_models import HELICOPTER, crush_bounce


def test_runner_takes_the_fastest_compiled_kernel_and_results_do_not_change(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """``run_chunk`` with the default kernel takes the fastest kernel that is compiled: the generated one
    when this shape's is, else the generic one, else (while this run's own background compile runs) the NumPy
    reference; the numbers are bitwise the same every time. (The side-by-side model of the physics tests,
    300 steps, its curve scaled in y and x: the choice does not depend on the model's size once the reference
    is expected to take longer than loading a kernel, and its generated kernel is compiled at start-up,
    helpers.generated_parts_model, so this test compiles nothing.)"""
    from crashstudy.kernel import choice

    model, axes = generated_parts_model(1.0e-4, 0.03, 1.0e-3)
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(model, sort_keys=False))
    study = {"name": "pick", "model": str(tmp_path / "m.yaml"), "matrix": axes}
    plan = load_study(study)
    assert plan.varying_curves == frozenset({-1 - plan.topology.curve_ids.index("scaled-c")})  # scaled only
    calls: list[str] = []
    real_generated, real_generic = generated.run_generated, runner_generic()
    monkeypatch.setattr(
        generated, "run_generated", lambda *a, **k: calls.append("generated") or real_generated(*a, **k)
    )
    monkeypatch.setattr(
        "crashstudy.kernel.compiled.run_compiled",
        lambda *a, **k: calls.append("generic") or real_generic(*a, **k),
    )
    monkeypatch.setattr(
        choice, "_LOADED", set()
    )  # no kernel loaded yet: the choice does not depend on test order
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: True)
    fast = run_chunk(plan, 0, plan.n_variants)
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: False)
    monkeypatch.setattr(choice, "generic_ready", lambda: True)
    slow = run_chunk(plan, 0, plan.n_variants)
    monkeypatch.setattr(choice, "generic_ready", lambda: False)
    monkeypatch.setattr(
        choice, "own_compile_running", lambda: True
    )  # the reference while this run's compile runs
    plain = run_chunk(plan, 0, plan.n_variants)
    assert calls == ["generated", "generic"]
    assert_bitwise(slow.out, fast.out)
    assert_bitwise(plain.out, fast.out)


def runner_generic():  # the generic kernel's entry point (looked up at call time by the runner)
    from crashstudy.kernel.compiled import run_compiled

    return run_compiled


def test_bad_kernel_environment_variable_is_an_input_error_before_anything_is_written(tmp_path: Path) -> None:
    """``CRASHSTUDY_KERNEL=fastest crashstudy simulate``: exit 2, a one-line message naming the variable and
    the accepted values, no traceback, no result folder."""
    import os
    import subprocess
    import sys

    out = tmp_path / "res"
    env = dict(os.environ, CRASHSTUDY_KERNEL="fastest")
    proc = subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", "simulate", str(HELICOPTER), "--output", str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert (
        "environment: CRASHSTUDY_KERNEL: expected reference, generic or generated (unset: the fastest kernel "
        "that is ready), got 'fastest'"
    ) in proc.stderr
    assert "Traceback" not in proc.stderr and not out.exists()


def test_kernel_environment_variable_chooses_the_kernel_of_a_small_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``CRASHSTUDY_KERNEL`` decides the kernel of a run that leaves the choice open: ``generated`` sends
    it to the generated one, ``generic`` keeps it off even when that shape is compiled, ``reference``
    to NumPy; results are the reference's either way."""
    import crashstudy.kernel.compiled as compiled

    calls: list[str] = []
    real_gen, real_generic = generated.run_generated, compiled.run_compiled
    monkeypatch.setattr(
        generated, "run_generated", lambda *a, **k: calls.append("generated") or real_gen(*a, **k)
    )
    monkeypatch.setattr(
        compiled, "run_compiled", lambda *a, **k: calls.append("generic") or real_generic(*a, **k)
    )
    # the side-by-side model of the physics tests, 10 steps: its generated kernel is compiled at start-up
    # (helpers.generated_parts_model; before, a twin case's, compiled by test_kernel_twins unless this test
    # came first, and a NumPy reference run of that case)
    model, axes = generated_parts_model(1.0e-4, 1.0e-3, 1.0e-3)
    ref, _, _ = run_model(model, kernel="reference", variants=axes)
    for env, expected in (("generated", "generated"), ("generic", "generic"), ("reference", "generic")):
        monkeypatch.setenv("CRASHSTUDY_KERNEL", env)
        got, _, _ = run_model(model, kernel="compiled", variants=axes)
        assert calls[-1] == expected and len(calls) == 1 + (env != "generated")
        assert_bitwise(ref, got)


@pytest.mark.parametrize("kernel", ["reference", "generic", "generated"])
def test_early_termination_stops_when_the_spring_has_separated(kernel: str) -> None:
    """Termination (spring force ~0 and the spring opening): the run ends at the separation time
    m v0 / F0 + (pi / 2) sqrt(m / k_u) = 0.05 + 0.01111 s (closed form; the 0.1 mm ramp adds ~1e-5 s),
    within 2 steps, instead of at end_time 0.2 s; peaks equal those of the run without termination.
    (At the model's tolerance 1e-5, dt 4.4 us: the error is 1.0e-6 s against a bound of 2.9e-5 s; a force
    threshold 10x too loose stops 6.3e-5 s early. At 1e-4, 3x less reference CPU, that planted bug stopped
    5.2e-5 s early against a bound of 4.8e-5 s: too close, so the step stays.)"""
    from crashstudy.kernel.entry import run_batch

    v0, m, f0, ku = 10.0, 100.0, 2.0e4, 2.0e6
    t_sep = m * v0 / f0 + 0.5 * np.pi * np.sqrt(m / ku)
    model = crush_bounce(v0)
    batch, plan = model_batch(model)
    # with the per-step record of the body (node 1): the generated kernel of the twin case
    # "early-termination" (twins.RECORD_CASES; the step is no part of the shape), which
    # tests/test_kernel_twins.py compiles: this test compiles nothing
    out = run_batch(batch, plan.topology.histories, plan.n_out, kernel, record=(1,))
    full_model = {k: v for k, v in model.items() if k != "termination"}
    full, _, _ = run_model(full_model, kernel="generic")  # (bitwise the reference's: test_kernel_twins)
    assert out.status[0] == 0
    assert abs(out.t_end[0] - t_sep) <= 2.0 * batch.dt[0] + 2.0e-5, (out.t_end[0], t_sep)
    assert full.t_end[0] == pytest.approx(0.2)
    assert out.peak_force[0, 0] == full.peak_force[0, 0] and out.max_crush[0, 0] == full.max_crush[0, 0]
    assert np.all(np.isnan(out.histories["spring_force"][int(out.t_end[0] / 1.0e-3) + 2 :, 0, 0]))
