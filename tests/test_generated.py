"""Generated (model-specialised) kernels against the NumPy reference kernel.

The bitwise twin tests of both fast kernels are in test_kernel_twins; here: what only the generated
kernel has (the runner's kernel choice, the environment variable, termination by closed form), and
the model builders the twin suite shares.
"""

from __future__ import annotations

import copy
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import run_model
from crashstudy.kernel import generated
from crashstudy.kernel.output import KernelOutput
from crashstudy.run.runner import run_chunk
from crashstudy.study.plan import load_study
from test_physics import TWIN_1D

ROOT = Path(__file__).resolve().parents[1]
FRONTAL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
HELICOPTER = ROOT / "studies" / "models" / "helicopter-subfloor.yaml"
ALL_1D = ["position", "displacement", "velocity", "acceleration", "spring_force", "spring_elongation",
          "kinetic_energy", "internal_energy", "external_work", "wall_energy"]  # fmt: skip


def same_bits(r: np.ndarray, g: np.ndarray) -> bool:
    """Equal values, NaN where NaN, and the same sign of every zero (a summary's -0.0 prints as "-0.0")."""
    if not np.array_equal(r, g, equal_nan=r.dtype.kind == "f"):
        return False
    if r.dtype.kind != "f":
        return True
    zero = r == 0.0
    return bool(np.array_equal(np.signbit(r[zero]), np.signbit(g[zero])))


def assert_bitwise(ref: KernelOutput, got: KernelOutput) -> None:
    for f in fields(KernelOutput):
        if f.name == "histories":
            continue
        r, g = getattr(ref, f.name), getattr(got, f.name)
        if r is None or g is None:  # optional outputs (the metrics' step record, criteria)
            assert r is None and g is None, f"{f.name} only in one of them"
            continue
        assert r.shape == g.shape, f.name
        assert same_bits(r, g), f"{f.name} differs"
    assert set(ref.histories) == set(got.histories)
    for name, r in ref.histories.items():  # the sign of a zero sample may differ (the files hold +0.0 only)
        assert np.array_equal(r, got.histories[name], equal_nan=True), f"history {name} differs"


def _without_walls_and_loads(model: dict[str, Any], keep_gravity: bool = True, keep_walls: bool = False
                             ) -> dict[str, Any]:  # fmt: skip
    """``model`` without what generated kernels leave to the generic one (prescribed motion), and without
    its walls and loads / gravity unless kept."""
    m = copy.deepcopy(model)
    for key in ("prescribed_motion",) + (() if keep_walls else ("rigid_walls", "loads")) + (
            () if keep_gravity else ("gravity",)):  # fmt: skip
        m.pop(key, None)
    for node in m["nodes"].values():  # a prescribed dof of the twin becomes a free one
        node.pop("fixed", None) if node.get("fixed") is not True else None
    m["output"]["histories"] = "all"
    return m


def _one_d_materials(mirror: bool = False, gravity: bool = False) -> dict[str, Any]:
    """TWIN_1D without loads and prescribed motion: crush, linear + damper in parallel, nonlinear elastic,
    general_nonlinear; ``gravity`` keeps its gravity, its rigid wall and its load pulse. ``mirror`` draws
    the model right to left (every spring's 1-D sign is -1)."""
    m = _without_walls_and_loads(TWIN_1D, keep_gravity=gravity, keep_walls=gravity)
    if mirror:
        for node in m["nodes"].values():
            node["position"] = [-node["position"][0]]
        m["initial_velocity"] = {k: [-v[0]] for k, v in m["initial_velocity"].items()}
    return m


def _mount_reversal() -> dict[str, Any]:
    """A 170 kg engine driven at 3 m/s into an engine mount (general_nonlinear, yield +-20 kN): it yields
    in compression, unloads along the 4.5e6 N/m line and the spring-back (about 100 J stored against
    44 J needed) carries it past the tension yield: general_nonlinear rule 4 (the reversal path) runs."""
    return {
        "name": "mount-reversal",
        "curves": {
            "load": {"x": [-0.1, -0.04, -0.01, 0.0, 0.01, 0.04, 0.1],
                     "y": [-3.0e5, -3.0e4, -2.0e4, 0.0, 2.0e4, 3.0e4, 3.0e5]},
            "unload": {"x": [-0.01, 0.0, 0.01], "y": [-4.5e4, 0.0, 4.5e4]},
        },
        "nodes": {"frame": {"position": [0.0], "fixed": True}, "engine": {"position": [0.2], "mass": 170.0}},
        "springs": {"mount": {"nodes": ["frame", "engine"],
                              "material": {"type": "general_nonlinear", "loading": "load", "unloading": "unload",
                                           "tension_yield": 2.0e4, "compression_yield": -2.0e4}}},
        "initial_velocity": {"engine": [-3.0]},
        "end_time": 0.08,
        "output": {"interval": 2.0e-4, "histories": ["spring_force", "spring_elongation", "acceleration"]},
    }  # fmt: skip


def test_runner_takes_the_fastest_compiled_kernel_and_results_do_not_change(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``run_chunk`` with the default kernel takes the fastest kernel that is compiled: the generated one
    when this shape's is, else the generic one, else (while this run's own background compile runs) the NumPy
    reference; the numbers are bitwise the same every time."""
    from crashstudy.kernel import choice

    study = {"name": "pick", "model": str(FRONTAL), "matrix": {"curves.rail-loading.scale": [0.8, 1.2],
             "impact_velocity": [12.0, 15.0, 18.0]}, "set": {"end_time": 0.03}}  # fmt: skip
    plan = load_study(study)
    assert plan.varying_curves == frozenset({-1 - plan.topology.curve_ids.index("rail-loading")})  # scaled only
    calls: list[str] = []
    real_generated, real_generic = generated.run_generated, runner_generic()
    monkeypatch.setattr(generated, "run_generated", lambda *a, **k: calls.append("generated") or real_generated(*a, **k))
    monkeypatch.setattr("crashstudy.kernel.compiled.run_compiled",
                        lambda *a, **k: calls.append("generic") or real_generic(*a, **k))  # fmt: skip
    monkeypatch.setattr(choice, "_LOADED", set())  # no kernel loaded yet: the choice does not depend on test order
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: True)
    fast = run_chunk(plan, 0, plan.n_variants)
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: False)
    monkeypatch.setattr(choice, "generic_ready", lambda: True)
    slow = run_chunk(plan, 0, plan.n_variants)
    monkeypatch.setattr(choice, "generic_ready", lambda: False)
    monkeypatch.setattr(choice, "own_compile_running", lambda: True)  # the reference while this run's compile runs
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
    proc = subprocess.run([sys.executable, "-m", "crashstudy.cli", "simulate", str(HELICOPTER), "--output", str(out)],
                          capture_output=True, text=True, env=env, timeout=300)  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert ("environment: CRASHSTUDY_KERNEL: expected reference, generic or generated (unset: the fastest kernel "
            "that is ready), got 'fastest'") in proc.stderr
    assert "Traceback" not in proc.stderr and not out.exists()


def test_kernel_environment_variable_chooses_the_kernel_of_a_small_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """``CRASHSTUDY_KERNEL`` decides the kernel of a run that leaves the choice open: ``generated`` sends
    it to the generated one, ``generic`` keeps it off even when that shape is compiled, ``reference``
    to NumPy; results are the reference's either way."""
    import crashstudy.kernel.compiled as compiled

    calls: list[str] = []
    real_gen, real_generic = generated.run_generated, compiled.run_compiled
    monkeypatch.setattr(generated, "run_generated", lambda *a, **k: calls.append("generated") or real_gen(*a, **k))
    monkeypatch.setattr(compiled, "run_compiled", lambda *a, **k: calls.append("generic") or real_generic(*a, **k))
    ref, _, _ = run_model(_mount_reversal(), kernel="reference")
    for env, expected in (("generated", "generated"), ("generic", "generic"), ("reference", "generic")):
        monkeypatch.setenv("CRASHSTUDY_KERNEL", env)
        got, _, _ = run_model(_mount_reversal(), kernel="compiled")
        assert calls[-1] == expected and len(calls) == 1 + (env != "generated")
        assert_bitwise(ref, got)


def _crush_bounce(v0: float = 10.0) -> dict[str, Any]:
    """A 100 kg mass at v0 onto a crush spring with a 20 kN plateau (reached after 0.1 mm) and unloading
    stiffness 2e6 N/m, then free flight: crush for m v0 / F0, spring-back for a quarter period of
    sqrt(k_u / m), then the spring is separated and opening."""
    return {
        "name": "crush-bounce",
        "curves": {"plateau": {"x": [-2.0, -1.0e-4, 0.0], "y": [-2.0e4, -2.0e4, 0.0]}},
        "nodes": {"wall": {"position": [0.0], "fixed": True}, "body": {"position": [1.0], "mass": 100.0}},
        "springs": {"pad": {"nodes": ["wall", "body"],
                            "material": {"type": "crush", "loading": "plateau", "unloading_stiffness": 2.0e6}}},
        "initial_velocity": {"body": [-v0]},
        "end_time": 0.2,
        "time_step": {"tolerance": 1.0e-5},
        "termination": {"kinetic_energy_fraction": 1.0e-3},
        "output": {"interval": 1.0e-3, "histories": ["spring_force"]},
    }  # fmt: skip


@pytest.mark.parametrize("kernel", ["reference", "generic", "generated"])
def test_early_termination_stops_when_the_spring_has_separated(kernel: str) -> None:
    """Termination (spring force ~0 and the spring opening): the run ends at the separation time
    m v0 / F0 + (pi / 2) sqrt(m / k_u) = 0.05 + 0.01111 s (closed form; the 0.1 mm ramp adds ~1e-5 s),
    within 2 steps, instead of at end_time 0.2 s; peaks equal those of the run without termination."""
    v0, m, f0, ku = 10.0, 100.0, 2.0e4, 2.0e6
    t_sep = m * v0 / f0 + 0.5 * np.pi * np.sqrt(m / ku)
    out, batch, _ = run_model(_crush_bounce(v0), kernel=kernel)
    full_model = {k: v for k, v in _crush_bounce(v0).items() if k != "termination"}
    full, _, _ = run_model(full_model, kernel="generic")  # (bitwise the reference's: test_physics twins)
    assert out.status[0] == 0
    assert abs(out.t_end[0] - t_sep) <= 2.0 * batch.dt[0] + 2.0e-5, (out.t_end[0], t_sep)
    assert full.t_end[0] == pytest.approx(0.2)
    assert out.peak_force[0, 0] == full.peak_force[0, 0] and out.max_crush[0, 0] == full.max_crush[0, 0]
    assert np.all(np.isnan(out.histories["spring_force"][int(out.t_end[0] / 1.0e-3) + 2 :, 0, 0]))
