"""Both fast kernels (generic and generated) bitwise equal to the NumPy reference, on every feature.

The independent truth is the reference kernel (:mod:`crashstudy.kernel.reference`, plain NumPy,
itself checked against closed forms and scipy in test_physics and test_materials). The fast kernels
share their laws (:mod:`crashstudy.kernel.laws`) but not the reference's code. Tolerance: bitwise
(every summary, every history; NaN where the reference has NaN).

Cases: every material in 1-D drawn both ways; the three full twins of test_physics (all materials,
gravity, loads, prescribed displacement / velocity / acceleration, rigid walls incl. an inclined one,
1-D and 2-D); 2-D walls; a 2-D spring crushed to zero length; the general_nonlinear reversal (rule 4);
knot crossings of every curve material in 1-D and 2-D; the frontal model with per-variant and constant
curves; lane compaction; early termination; an unstable variant; the SPEC v2 spring features (elastoplastic,
nonlinear_damper, initial_elongation, failure, max_elongation) in 1-D and 2-D.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import fields
from typing import Any

import numpy as np
import pytest
import yaml

from conftest import run_model
from crashstudy.kernel import entry, generated
from crashstudy.kernel.output import CRUSHED_TO_ZERO, UNSTABLE, KernelOutput
from crashstudy.run.runner import run_kernel
from test_generated import (
    FRONTAL,
    HELICOPTER,
    _crush_bounce,
    _mount_reversal,
    _one_d_materials,
    _without_walls_and_loads,
    assert_bitwise,
)
from test_knot_peaks import CRUSH_REBOUND, _one_mass
from test_physics import TWIN_2D_HELI, TWINS
from test_stress import forced_batch, outputs_equal

FAST = ["generic", "generated"]
MASSES = [6.0, 8.0, 10.0, 12.0, 14.0]


def _helicopter_walls() -> dict[str, Any]:
    model = _without_walls_and_loads(TWIN_2D_HELI, keep_walls=True)
    model["rigid_walls"][0]["nodes"] = ["transmission", "cabin"]  # the floor
    model["rigid_walls"].append({"id": "side", "point": [0.03, 0.0], "normal": [-1.0, 0.0],
                                 "nodes": ["transmission", "cabin"]})  # fmt: skip
    return model


def _frontal(histories: Any, end_time: float) -> dict[str, Any]:
    model = yaml.safe_load(FRONTAL.read_text())
    model["output"] = {"interval": 1.0e-3, "histories": histories}
    model["end_time"] = end_time
    return model


def _helicopter_crushed() -> dict[str, Any]:
    model = yaml.safe_load(HELICOPTER.read_text())
    model["output"]["histories"] = ["position", "spring_force", "kinetic_energy"]
    return model


def _bounce_many() -> dict[str, Any]:
    model = _crush_bounce()
    model["end_time"] = 0.3
    return model


_rng = np.random.default_rng(4)
_FRONTAL_AXES = {"curves.rail-loading.scale": list(_rng.uniform(0.6, 1.6, 12)),
                 "nodes.engine.mass": list(_rng.uniform(100.0, 250.0, 12))}  # fmt: skip
_COMPACTION_AXES = {"nodes.bumper.mass": list(np.random.default_rng(7).permutation(np.linspace(3.0, 40.0, 48))),
                    "curves.rail-loading.scale": list(np.linspace(0.7, 1.5, 48))}  # fmt: skip


# force and abscissa scales of spring, time and motion curves (a constant shape and per-variant factors)
_SCALED_1D = {"curves.plateau.scale": [0.6, 0.7, 0.8, 0.9, 1.0], "curves.soft.x_scale": [1.0, 1.1, 1.2, 1.3, 1.4],
              "curves.gn-load.scale": [1.0, 0.9, 0.8, 0.7, 0.95], "curves.pulse.x_scale": [0.5, 0.8, 1.0, 1.5, 2.0],
              "curves.pull.x_scale": [1.0, 0.5, 2.0, 1.5, 0.8]}  # fmt: skip
_SCALED_KNOTS = {f"curves.{c}.{f}": v for c in ("crush", "elastic") for f, v in
                 (("scale", [0.7, 0.8, 0.9, 1.0, 0.75]), ("x_scale", [1.0, 1.1, 1.2, 1.3, 1.4]))}  # fmt: skip


def _check_scaled(ref: KernelOutput, batch: Any) -> None:
    """Every variant runs; the scaled curves keep one shape (the generated kernel's factor curves)."""
    from crashstudy.kernel.gen_shape import _constant_curves, _factor_curves

    assert np.all(ref.status == 0) and np.unique(batch.cfac[0], axis=1).shape[1] > 1
    assert _factor_curves(batch, None, _constant_curves(batch, None))


def _check_ok(ref: KernelOutput, batch: Any) -> None:
    assert np.all(ref.status == 0)


def _check_1d(mirror: bool) -> Callable[[KernelOutput, Any], None]:
    def check(ref: KernelOutput, batch: Any) -> None:
        assert np.all(batch.sign == (-1.0 if mirror else 1.0)) and len(np.unique(batch.out_every)) > 1
        assert np.all(ref.status == 0) and np.all(ref.peak_force > 0)

    return check


def _check_full_twin(ref: KernelOutput, batch: Any) -> None:
    assert len(batch.pm_node) + len(batch.load_node) > 0 and np.all(ref.status == 0)
    assert np.nanmax(np.abs(ref.histories["external_work"])) > 0


def _check_walls(ref: KernelOutput, batch: Any) -> None:
    assert batch.x0.shape[1] == 2 and np.all(ref.status == 0)
    # a wall that only stops a node reports an impulse; one that holds it against a force, a contact force
    assert np.all(np.max(ref.peak_wall_force + ref.wall_impulse, axis=1) > 0), "both walls are hit"


def _helicopter_penalty_side() -> dict[str, Any]:
    """:func:`_helicopter_walls` with a penalty side wall (contact stiffness a study axis)."""
    model = _helicopter_walls()
    model["rigid_walls"][1]["stiffness"] = 1.0e6
    return model


def _check_penalty(ref: KernelOutput, batch: Any) -> None:
    _check_walls(ref, batch)
    assert np.all(batch.wall_stiffness[1] > 0) and np.all(ref.wall_impulse[1] == 0.0) and np.all(ref.peak_wall_force[1] > 0)


def _check_crushed(ref: KernelOutput, batch: Any) -> None:
    assert list(ref.status) == [0, 0, CRUSHED_TO_ZERO, CRUSHED_TO_ZERO] and list(ref.fail_item[2:]) == [0, 0]


def _check_reversal(ref: KernelOutput, batch: Any) -> None:
    force = ref.histories["spring_force"][:, 0, :]
    assert np.all(np.nanmin(force, axis=0) <= -2.0e4) and np.all(np.nanmax(force, axis=0) >= 2.0e4 - 1.0)


def _check_knots(ref: KernelOutput, batch: Any) -> None:
    """The knot candidate raised the peak force above every sample (in some variant)."""
    sampled = np.nanmax(np.abs(ref.histories["spring_force"][:, 0, :]), axis=0)
    assert np.all(ref.status == 0) and np.any(ref.peak_force[0] > sampled)


def _check_compaction(ref: KernelOutput, batch: Any) -> None:
    assert len(np.unique(batch.n_steps)) >= 8, "variants end at different steps"


def _check_termination(ref: KernelOutput, batch: Any) -> None:
    assert np.all(ref.t_end < 0.2) and len(np.unique(ref.t_end)) >= 30


def _v2_springs(dim: int) -> dict[str, Any]:
    """The SPEC v2 spring features together: elastoplastic (preloaded, breaking in tension), a blow-off
    nonlinear_damper, a preloaded general_nonlinear that yielded on the way, a preloaded crush, a linear
    spring breaking both ways."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    at = lambda r: [r * c for c in ax]  # noqa: E731
    return {
        "name": f"v2-springs-{dim}d",
        "curves": {"blow-off": {"x": [-10.0, -1.0, 0.0, 1.0, 10.0], "y": [-300.0, -300.0, 0.0, 300.0, 300.0]},
                   "load": {"x": [-0.1, 0.0, 0.01, 0.02, 0.2], "y": [-1.0e4, 0.0, 600.0, 400.0, 900.0]},
                   "unload": {"x": [-0.1, 0.0, 0.1], "y": [-1.0e4, 0.0, 1.0e4]},
                   "crush": {"x": [-0.3, -0.01, 0.0], "y": [-3000.0, -1500.0, 0.0]}},
        "nodes": {"a": {"position": at(0.0), "fixed": True}, "b": {"position": at(1.0), "mass": 10.0},
                  "c": {"position": at(2.0), "mass": 5.0}},
        "springs": {
            "ep": {"nodes": ["a", "b"], "initial_elongation": 0.02, "failure": {"tension": 0.12},
                   "material": {"type": "elastoplastic", "stiffness": 4.0e4, "tangent_stiffness": 1.0e4,
                                "yield_force": 2.0e3}},
            "nd": {"nodes": ["a", "b"], "material": {"type": "nonlinear_damper", "curve": "blow-off"}},
            "gn": {"nodes": ["b", "c"], "initial_elongation": 0.015,
                   "material": {"type": "general_nonlinear", "loading": "load", "unloading": "unload",
                                "tension_yield": 500.0}},
            "cr": {"nodes": ["b", "c"], "initial_elongation": -0.01, "failure": {"compression": -0.2},
                   "material": {"type": "crush", "loading": "crush", "unloading_stiffness": 2.0e5}},
            "lin": {"nodes": ["a", "c"], "failure": {"tension": 0.06, "compression": -0.06},
                    "material": {"type": "linear_elastic", "stiffness": 2.0e3}},
        },
        "initial_velocity": {"b": at(3.0), "c": at(-2.0)},
        "end_time": 0.3, "time_step": {"safety_factor": 0.5},
        "output": {"interval": 1.0e-3},
    }  # fmt: skip


def _v2_intact(dim: int) -> dict[str, Any]:
    """:func:`_v2_springs` without failures (another generated shape: no thresholds, no broken flags)."""
    model = _v2_springs(dim)
    for sp in model["springs"].values():
        sp.pop("failure", None)
    return model


def _check_v2_intact(ref: KernelOutput, batch: Any) -> None:
    assert np.all(ref.status == 0) and generated.unsupported(batch) is None and np.all(np.isnan(ref.spring_fail_time))
    assert np.all(batch.ie0[[0, 2, 3]] > 0) and np.all(ref.max_elongation[0] > 0)


def _check_v2(ref: KernelOutput, batch: Any) -> None:
    """Every variant runs (on the generated kernel too); springs break in some variants, not all; preloads
    store energy."""
    assert np.all(ref.status == 0) and generated.unsupported(batch) is None
    broke = np.isfinite(ref.spring_fail_time)
    assert broke.any() and not broke.all()
    assert np.all(batch.ie0[[0, 2, 3]] > 0) and np.all(ref.max_elongation[0] > 0)


def _rate_elastic(dim: int) -> dict[str, Any]:
    """rate_elastic: three curves (rates 0, 2, 6 m/s) on a preloaded spring, one curve on another, beside a
    linear spring; the impact speeds put the elongation rates below, between and above the rates, and a
    curve scale axis makes one of its curves a per-variant factor curve."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    at = lambda r: [r * c for c in ax]  # noqa: E731
    return {
        "name": f"rate-elastic-{dim}d",
        "curves": {"soft": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-800.0, -500.0, 0.0, 500.0, 800.0]},
                   "mid": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-1600.0, -1000.0, 0.0, 1000.0, 1600.0]},
                   "stiff": {"x": [-0.2, 0.0, 0.1, 0.2], "y": [-4000.0, 0.0, 1500.0, 2500.0]}},
        "nodes": {"a": {"position": at(0.0), "fixed": True}, "b": {"position": at(1.0), "mass": 10.0},
                  "c": {"position": at(2.0), "mass": 5.0}},
        "springs": {
            "re": {"nodes": ["a", "b"], "initial_elongation": 0.01,
                   "material": {"type": "rate_elastic", "curves": [{"rate": 0.0, "curve": "soft"},
                                                                   {"rate": 2.0, "curve": "mid"},
                                                                   {"rate": 6.0, "curve": "stiff"}]}},
            "re1": {"nodes": ["b", "c"], "material": {"type": "rate_elastic", "curves": [{"rate": 1.0, "curve": "mid"}]}},
            "lin": {"nodes": ["a", "c"], "material": {"type": "linear_elastic", "stiffness": 2.0e3}},
        },
        "initial_velocity": {"b": at(3.0), "c": at(-2.0)},
        "end_time": 0.3, "time_step": {"safety_factor": 0.5},
        "output": {"interval": 1.0e-3},
    }  # fmt: skip


def _check_rate_elastic(ref: KernelOutput, batch: Any) -> None:
    """Every variant runs (on the generated kernel too); the preload stores energy."""
    assert np.all(ref.status == 0) and generated.unsupported(batch) is None and np.all(batch.ie0[0] > 0)


# case -> (model builder, study axes, what the case must exercise)
CASES: dict[str, tuple[Callable[[], dict[str, Any]], dict[str, list[float]], Callable[[KernelOutput, Any], None]]] = {
    "1d-every-material": (lambda: _one_d_materials(False), {"nodes.a.mass": [1.0, 2.0, 4.0, 6.0, 8.0]},
                          _check_1d(False)),
    "1d-every-material-mirrored": (lambda: _one_d_materials(True), {"nodes.a.mass": [1.0, 2.0, 4.0, 6.0, 8.0]},
                                   _check_1d(True)),
    **{f"full-twin-{case}": ((lambda c=case: TWINS[c][0]), {TWINS[case][1]: TWINS[case][2]}, _check_full_twin)
       for case in TWINS},
    "2d-two-walls-gravity-load": (_helicopter_walls, {"nodes.cabin.mass": [200.0, 250, 300, 350, 400]},
                                  _check_walls),
    "2d-rigid-and-penalty-walls": (_helicopter_penalty_side, {"rigid_walls.1.stiffness": [2e5, 5e5, 1e6, 2e6, 4e6]},
                                   _check_penalty),
    "2d-crushed-to-zero": (_helicopter_crushed, {"impact_velocity": [6.0, 8.2, 10.0, 30.0]}, _check_crushed),
    "general-nonlinear-reversal": (_mount_reversal, {"impact_velocity": [2.0, 2.5, 3.0, 3.5]}, _check_reversal),
    "knots-crush-rebound": (lambda: dict(CRUSH_REBOUND, time_step={"tolerance": 1e-3},
                                         output={"interval": 1e-3, "histories": ["spring_force"]}),
                            {"nodes.body.mass": [900.0, 1100.0, 1200.0, 1300.0, 1500.0]}, _check_knots),
    **{f"knots-{kind}-{dim}d": ((lambda k=kind, d=dim: _one_mass(k, dim=d, dt=4e-4)), {"nodes.body.mass": MASSES},
                                _check_knots)
       for kind in ("crush", "nonlinear_elastic", "general_nonlinear") for dim in (1, 2)},
    "frontal-curve-and-mass-axes": (lambda: _frontal("all", 0.06), _FRONTAL_AXES, _check_ok),
    "scaled-curves-1d": ((lambda: TWINS["1d-all-materials"][0]), _SCALED_1D, _check_scaled),
    **{f"scaled-knots-{kind}": ((lambda k=kind: _one_mass(k, dim=1, dt=4e-4)), _SCALED_KNOTS, _check_scaled)
       for kind in ("crush", "nonlinear_elastic", "general_nonlinear")},
    "frontal-lane-compaction": (lambda: _frontal(["spring_force", "kinetic_energy"], 0.03), _COMPACTION_AXES,
                                _check_compaction),
    "early-termination": (_bounce_many, {"impact_velocity": list(np.linspace(4.0, 16.0, 40))}, _check_termination),
    **{f"v2-spring-features-{dim}d": ((lambda d=dim: _v2_springs(d)), {"impact_velocity": [0.5, 2.0, 4.0, 6.0, 9.0]},
                                      _check_v2) for dim in (1, 2)},
    **{f"v2-preload-and-materials-{dim}d": ((lambda d=dim: _v2_intact(d)),
                                            {"impact_velocity": [0.5, 2.0, 4.0, 6.0, 9.0]}, _check_v2_intact)
       for dim in (1, 2)},
    **{f"rate-elastic-{dim}d": ((lambda d=dim: _rate_elastic(d)), {"impact_velocity": [0.5, 2.0, 4.0, 6.0, 9.0],
                                "curves.mid.scale": [1.0, 0.8, 1.2, 1.0, 1.5]}, _check_rate_elastic)
       for dim in (1, 2)},
}  # fmt: skip


@functools.cache
def _reference(case: str) -> tuple[KernelOutput, Any]:
    build, axes, _ = CASES[case]
    ref, batch, _ = run_model(build(), kernel="reference", variants=axes)
    return ref, batch


@pytest.mark.parametrize("kernel", FAST)
@pytest.mark.parametrize("case", list(CASES))
def test_fast_kernel_bitwise_equal_to_reference(case: str, kernel: str) -> None:
    """Every summary and history of ``kernel`` equals the reference's bit for bit on ``case``, and the
    case really exercises its feature (checked on the reference's output)."""
    build, axes, check = CASES[case]
    ref, batch = _reference(case)
    check(ref, batch)
    got, _, _ = run_model(build(), kernel=kernel, variants=axes)
    assert_bitwise(ref, got)


@pytest.mark.parametrize("kernel", FAST)
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_instability_fails_that_variant_only_as_in_the_reference(kernel: str) -> None:
    """One variant of four runs at 3 x dt_crit (forced by hand): UNSTABLE at the reference's step, NaN
    histories after it, the other three bitwise equal to their runs alone."""
    batch, _, plan = forced_batch(3.0)
    hist = plan.topology.histories
    ref = run_kernel(batch, hist, plan.n_out, "reference")
    got = run_kernel(batch, hist, plan.n_out, kernel)
    assert list(got.status) == [0, UNSTABLE, 0, 0]
    assert_bitwise(ref, got)
    alone = run_kernel(batch.take(np.array([2])), hist, plan.n_out, kernel)
    assert outputs_equal(got, 2, alone, 0) == []


def test_ordered_run_spreads_each_variant_back_to_the_callers_columns() -> None:
    """``entry.run_ordered`` sorts the variants by step count, runs them and spreads the results back
    (here 6 columns from 5 variants of different masses, one taken twice): column k equals, bitwise,
    column ``spread[k]`` of the reference run in the caller's order; no error estimate was asked (NaN)."""
    axes = {"nodes.a.mass": [8.0, 1.0, 4.0, 2.0, 6.0]}
    ref, batch, plan = run_model(_one_d_materials(False), kernel="reference", variants=axes)
    assert not np.all(np.diff(batch.n_steps) >= 0), "the variants are not in step-count order"
    spread = np.array([2, 0, 2, 4, 1, 3])
    got, estimate = entry.run_ordered(batch, plan.topology.histories, plan.n_out, spread, "generic")
    for f in fields(KernelOutput):
        if f.name != "histories" and not (getattr(got, f.name) is None is getattr(ref, f.name)):  # optional outputs
            assert np.array_equal(getattr(got, f.name), getattr(ref, f.name)[..., spread], equal_nan=True), f.name
    for name, r in ref.histories.items():
        assert np.array_equal(got.histories[name], r[..., spread], equal_nan=True), name
    assert estimate.shape == (6,) and np.all(np.isnan(estimate))
