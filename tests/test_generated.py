"""Generated (model-specialised) kernels against the NumPy reference kernel.

The generated kernel is a third implementation of the same step; the independent truth is the
reference kernel (:mod:`crashstudy.kernel.reference`, itself checked against closed forms and scipy in
test_physics). Tolerance: bitwise (every summary, every history; NaN where the reference has NaN).
"""

from __future__ import annotations

import copy
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from conftest import run_model
from crashstudy.kernel import generated
from crashstudy.kernel.output import CRUSHED_TO_ZERO, UNSTABLE, KernelOutput
from crashstudy.runner import run_chunk, run_kernel, varying_curves
from crashstudy.study import load_study
from test_physics import TWIN_1D, TWIN_2D_HELI, TWIN_2D_MIXED, TWINS
from test_stress import forced_batch, outputs_equal

ROOT = Path(__file__).resolve().parents[1]
FRONTAL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
HELICOPTER = ROOT / "studies" / "models" / "helicopter-subfloor.yaml"
ALL_1D = ["position", "displacement", "velocity", "acceleration", "spring_force", "spring_elongation",
          "kinetic_energy", "internal_energy", "external_work", "wall_energy"]  # fmt: skip


def _assert_bitwise(ref: KernelOutput, got: KernelOutput) -> None:
    for f in fields(KernelOutput):
        if f.name == "histories":
            continue
        r, g = getattr(ref, f.name), getattr(got, f.name)
        assert r.shape == g.shape, f.name
        assert np.array_equal(r, g, equal_nan=r.dtype.kind == "f"), f"{f.name} differs"
    assert set(ref.histories) == set(got.histories)
    for name, r in ref.histories.items():
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


@pytest.mark.parametrize("case", list(TWINS))
def test_the_full_twin_models_bitwise_equal_to_reference(case: str) -> None:
    """The three twin models of test_physics with every feature at once (all materials, gravity, loads,
    prescribed displacement / velocity / acceleration, rigid walls incl. an inclined one, 1-D and 2-D), 5
    variants with different masses, every history: the generated kernel is bitwise the reference's."""
    model, path, values = TWINS[case]
    ref, batch, _ = run_model(model, kernel="reference", variants={path: values})
    got, _, _ = run_model(model, kernel="generated", variants={path: values})
    assert generated.unsupported(batch) is None and len(batch.pm_node) + len(batch.load_node) > 0
    assert np.all(ref.status == 0) and np.nanmax(np.abs(ref.histories["external_work"])) > 0
    _assert_bitwise(ref, got)


@pytest.mark.parametrize(("mirror", "gravity"), [(False, False), (True, False)],
                         ids=["left-to-right", "right-to-left"])  # fmt: skip  (gravity, load, wall: the full twins)
def test_every_1d_material_bitwise_equal_to_reference(mirror: bool, gravity: bool) -> None:
    """Crush, linear, damper, nonlinear elastic and general_nonlinear springs, 5 variants with different
    masses (so different steps and sampling strides), every history (with gravity, a load pulse on node b
    and a rigid wall that node a hits: external work, wall energy and force): bitwise the reference's."""
    model = _one_d_materials(mirror, gravity)
    variants = {"nodes.a.mass": [1.0, 2.0, 4.0, 6.0, 8.0]}
    ref, batch, _ = run_model(model, kernel="reference", variants=variants)
    got, _, _ = run_model(model, kernel="generated", variants=variants)
    assert np.all(batch.sign == (-1.0 if mirror else 1.0))
    assert len(np.unique(batch.out_every)) > 1, "variants sample at different strides"
    assert np.all(ref.status == 0) and np.all(ref.peak_force > 0)
    assert (np.nanmax(np.abs(ref.histories["external_work"])) > 0) == gravity
    if gravity:
        assert np.sum(ref.peak_wall_force > 0) >= 3 and np.nanmax(ref.histories["wall_energy"]) > 0  # heavy a
    _assert_bitwise(ref, got)


@pytest.mark.parametrize("case", ["helicopter-gravity-load-two-walls"])  # the mixed twin: the full-twin test
def test_2d_models_bitwise_equal_to_reference(case: str) -> None:
    """2-D: the helicopter twin (two general_nonlinear springs, gravity, a gust load; its floor and a side
    wall, each holding both nodes: the walls act in the reference's order) and the mixed twin (crush, damper,
    linear, nonlinear elastic; a node fixed in x only), 5 variants, every history: bitwise the
    reference's."""
    if case == "helicopter-gravity-load-two-walls":
        model = _without_walls_and_loads(TWIN_2D_HELI, keep_walls=True)
        model["rigid_walls"][0]["nodes"] = ["transmission", "cabin"]  # the floor
        model["rigid_walls"].append({"id": "side", "point": [0.03, 0.0], "normal": [-1.0, 0.0],
                                     "nodes": ["transmission", "cabin"]})  # fmt: skip
        path, values = "nodes.cabin.mass", [200.0, 250, 300, 350, 400]
    else:
        model, path, values = _without_walls_and_loads(TWIN_2D_MIXED, False), "nodes.bob.mass", [0.5, 1, 1.5, 2, 3]
    ref, batch, _ = run_model(model, kernel="reference", variants={path: values})
    got, _, _ = run_model(model, kernel="generated", variants={path: values})
    assert generated.unsupported(batch) is None and batch.x0.shape[1] == 2
    assert np.all(ref.status == 0)
    if case.startswith("helicopter"):
        assert np.all(np.max(ref.peak_wall_force, axis=1) > 0), "both walls are hit"
    _assert_bitwise(ref, got)


def test_2d_spring_crushed_to_zero_length_fails_as_in_the_reference() -> None:
    """The helicopter example at 6, 8.2, 10 and 30 m/s: the two fast drops crush the underfloor through
    zero length (CRUSHED_TO_ZERO, spring 0, at the reference's step); all outputs bitwise the reference's."""
    model = yaml.safe_load(HELICOPTER.read_text())
    model["output"]["histories"] = ["position", "spring_force", "kinetic_energy"]
    variants = {"impact_velocity": [6.0, 8.2, 10.0, 30.0]}
    ref, _, _ = run_model(model, kernel="reference", variants=variants)
    got, _, _ = run_model(model, kernel="generated", variants=variants)
    assert list(got.status) == [0, 0, CRUSHED_TO_ZERO, CRUSHED_TO_ZERO] and list(got.fail_item[2:]) == [0, 0]
    _assert_bitwise(ref, got)


def test_general_nonlinear_reversal_bitwise_equal_to_reference() -> None:
    """The rule-4 reversal (a lane leaves the vectorised pass for the scalar path): bitwise equal, and the
    reversal really happens (the force history reaches the tension yield after the compression yield)."""
    model = _mount_reversal()
    variants = {"impact_velocity": [2.0, 2.5, 3.0, 3.5]}
    ref, _, _ = run_model(model, kernel="reference", variants=variants)
    got, _, _ = run_model(model, kernel="generated", variants=variants)
    force = ref.histories["spring_force"][:, 0, :]
    assert np.all(np.nanmin(force, axis=0) <= -2.0e4) and np.all(np.nanmax(force, axis=0) >= 2.0e4 - 1.0)
    _assert_bitwise(ref, got)


@pytest.mark.parametrize("histories", [["spring_force", "kinetic_energy"], "all"])  # "none": the runner test
def test_frontal_model_with_curve_and_mass_axes_bitwise_equal_to_reference(histories: Any) -> None:
    """The frontal example (crush, general_nonlinear, linear; a fixed barrier node) with the front-rail
    curve scaled per variant (its coefficients stay per-variant rows) and the engine mass varied (the
    other curves are constants of the kernel): bitwise the reference's for 12 variants."""
    model = yaml.safe_load(FRONTAL.read_text())
    model["output"]["histories"] = histories
    model["end_time"] = 0.06
    rng = np.random.default_rng(4)
    variants = {"curves.rail-loading.scale": list(rng.uniform(0.6, 1.6, 12)),
                "nodes.engine.mass": list(rng.uniform(100.0, 250.0, 12))}  # fmt: skip
    ref, batch, plan = run_model(model, kernel="reference", variants=variants)
    got, _, _ = run_model(model, kernel="generated", variants=variants)
    shape = generated._shape(batch, plan.topology.histories)
    rail = plan.topology.curve_ids.index("rail-loading")
    assert rail not in shape["const"] and len(shape["const"]) >= 5
    _assert_bitwise(ref, got)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_instability_fails_that_variant_only_as_in_the_reference() -> None:
    """One variant of four runs at 3 x dt_crit (forced by hand): UNSTABLE at the reference's step, NaN
    histories after it, the other three bitwise equal to their runs alone."""
    batch, _, plan = forced_batch(3.0)
    hist = plan.topology.histories
    ref = run_kernel(batch, hist, plan.n_out, "reference")
    got = run_kernel(batch, hist, plan.n_out, "generated")
    assert list(got.status) == [0, UNSTABLE, 0, 0]
    _assert_bitwise(ref, got)
    alone = run_kernel(batch.take(np.array([2])), hist, plan.n_out, "generated")
    assert outputs_equal(got, 2, alone, 0) == []


def test_runner_takes_the_fastest_compiled_kernel_and_results_do_not_change(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``run_chunk`` with the default kernel takes the fastest kernel that is compiled: the generated one
    when this shape's is, else the generic one, else (while another process compiles) the NumPy
    reference; the numbers are bitwise the same every time."""
    from crashstudy.kernel import choice

    study = {"name": "pick", "model": str(FRONTAL), "matrix": {"curves.rail-loading.scale": [0.8, 1.2],
             "impact_velocity": [12.0, 15.0, 18.0]}, "set": {"end_time": 0.03}}  # fmt: skip
    plan = load_study(study)
    assert varying_curves(plan) == frozenset({plan.topology.curve_ids.index("rail-loading")})
    calls: list[str] = []
    real_generated, real_generic = generated.run_generated, runner_generic()
    monkeypatch.setattr(generated, "run_generated", lambda *a, **k: calls.append("generated") or real_generated(*a, **k))
    monkeypatch.setattr("crashstudy.kernel.compiled.run_compiled",
                        lambda *a, **k: calls.append("generic") or real_generic(*a, **k))  # fmt: skip
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: True)
    fast = run_chunk(plan, 0, plan.n_variants)
    monkeypatch.setattr(choice, "generated_ready", lambda *a, **k: False)
    monkeypatch.setattr(choice, "generic_ready", lambda: True)
    slow = run_chunk(plan, 0, plan.n_variants)
    monkeypatch.setattr(choice, "generic_ready", lambda: False)
    monkeypatch.setattr(choice, "compiling", lambda: True)
    plain = run_chunk(plan, 0, plan.n_variants)
    assert calls == ["generated", "generic"]
    _assert_bitwise(slow.out, fast.out)
    _assert_bitwise(plain.out, fast.out)


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
    assert "environment: CRASHSTUDY_KERNEL: unknown kernel 'fastest': expected reference, generic or generated" in proc.stderr
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
        _assert_bitwise(ref, got)


def test_lanes_of_ended_variants_leave_the_block_and_results_do_not_change() -> None:
    """48 frontal variants with bumper masses 3-40 kg (so different steps and step counts, unsorted):
    as variants end, the generated kernel compacts its block (at least 8 ended lanes move out). Every
    output bitwise the reference's, histories included."""
    model = yaml.safe_load(FRONTAL.read_text())  # the shape of the frontal test above (its kernel is reused)
    model["output"] = {"interval": 1.0e-3, "histories": ["spring_force", "kinetic_energy"]}
    model["end_time"] = 0.03
    masses = list(np.random.default_rng(7).permutation(np.linspace(3.0, 40.0, 48)))
    variants = {"nodes.bumper.mass": masses, "curves.rail-loading.scale": list(np.linspace(0.7, 1.5, 48))}
    ref, batch, _ = run_model(model, kernel="reference", variants=variants)
    got, _, _ = run_model(model, kernel="generated", variants=variants)
    assert len(np.unique(batch.n_steps)) >= 8, "variants end at different steps"
    _assert_bitwise(ref, got)


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


def test_early_termination_bitwise_equal_to_reference_and_lanes_leave_the_block() -> None:
    """40 bounce variants (impact speed 4-16 m/s: each stops at its own separation time, so ended lanes
    leave the generated kernel's block): every output bitwise the reference's."""
    model = _crush_bounce()
    model["end_time"] = 0.3
    variants = {"impact_velocity": list(np.linspace(4.0, 16.0, 40))}
    ref, batch, _ = run_model(model, kernel="reference", variants=variants)
    got, _, _ = run_model(model, kernel="generated", variants=variants)
    assert np.all(ref.t_end < 0.2) and len(np.unique(ref.t_end)) >= 30
    _assert_bitwise(ref, got)
