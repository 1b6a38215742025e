"""SPEC v2 spring features: the summary ``max_elongation`` (and a max crush of +0 for a spring only in
tension, no negative zero in the results files), and the input errors of v2 springs, in a model file or
from a study's axis values per variant.

Every model is a single mass on one spring (1-D, and 2-D along a slanted axis where the feature has a 2-D
form), so the truth is a formula of mechanics, written here from docs/format.md, not from the kernels.
Most tests run the NumPy reference; tests/test_kernel_twins.py holds both fast kernels bitwise equal to it
on every feature."""

from __future__ import annotations

import contextlib
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from crashstudy.arrays.compiler import apply_axis
from crashstudy.arrays.parameter_checks import check_parameters
from crashstudy.cli.main import main
from crashstudy.errors import InputError
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import loads_yaml
from helpers import generated_part, model_plan, run_model
from models import PULL
from models import one_spring as _one_spring


def run_main(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(list(argv))
    return rc, out.getvalue(), err.getvalue()


# --------------------------------------------------------------------------------------------------
# max_elongation, summaries, kernel choice, input errors
# --------------------------------------------------------------------------------------------------


def test_max_elongation_of_a_linear_oscillator_is_its_amplitude_in_summary_csv(tmp_path: Path) -> None:
    """k = 1e4 N/m, m = 1 kg, v0 = 2 m/s: amplitude v0 / w = 0.02 m both ways; ``summary.csv`` has
    ``max_elongation.s`` = 0.02 (1e-3, default step) and ``failure_time.s`` empty (NaN): a model with no
    failure option. The numbers come from every time step (the histories are not kept)."""
    model = _one_spring({"type": "linear_elastic", "stiffness": 1.0e4}, 1.0, 2.0, end_time=0.05)
    model["output"] = {"histories": "none"}
    path = tmp_path / "osc.yaml"
    path.write_text(yaml.safe_dump(model, sort_keys=False))
    rc, _, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    assert rc == 0, err
    row = pd.read_csv(tmp_path / "out" / "summary.csv").iloc[0]
    assert row["max_elongation.s"] == pytest.approx(0.02, rel=1e-3)
    assert row["max_crush.s"] == pytest.approx(0.02, rel=1e-3)
    assert math.isnan(row["failure_time.s"])
    pq = pd.read_parquet(tmp_path / "out" / "summary.parquet").iloc[0]
    assert pq["max_elongation.s"] == row["max_elongation.s"]


BAD = {
    "tangent-not-below-stiffness": (
        {"type": "elastoplastic", "stiffness": 100.0, "tangent_stiffness": 100.0, "yield_force": 1.0},
        {},
        "springs.s.material.tangent_stiffness",
        "tangent_stiffness must be below stiffness",
    ),
    "damper-with-initial-elongation": (
        {"type": "damper", "damping": 1.0},
        {"initial_elongation": 0.1},
        "springs.s.initial_elongation",
        "initial elongation",
    ),
    "failure-below-initial-elongation": (
        {"type": "linear_elastic", "stiffness": 1.0},
        {"initial_elongation": 0.1, "failure": {"tension": 0.05}},
        "springs.s.failure.tension",
        "above initial_elongation",
    ),
    "compression-failure-positive": (
        {"type": "linear_elastic", "stiffness": 1.0},
        {"failure": {"compression": 0.05}},
        "springs.s.failure.compression",
        "less than 0",
    ),
    "damper-curve-decreasing": (
        {
            "type": "nonlinear_damper",
            "curve": "c",
            "_curves": {"c": {"x": [-1.0, 0.0, 1.0], "y": [1.0, 0.0, -1.0]}},
        },
        {},
        "springs.s.material.curve",
        "must be increasing",
    ),
    "crush-curve-off-origin": (
        {
            "type": "crush",
            "loading": "c",
            "unloading_stiffness": 1.0,
            "_curves": {"c": {"x": [-1.0, 0.0], "y": [-2.0, -1.0]}},
        },
        {},
        "springs.s.material.loading",
        "initial_elongation",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_v2_spring_input_is_refused_with_field_and_expectation(case: str) -> None:
    material, options, field, text = BAD[case]
    model = _one_spring(material, 1.0, **options)
    with pytest.raises(InputError) as err:
        parse_model(loads_yaml(yaml.safe_dump(model, sort_keys=False), file="bad.yaml"))
    found = [p for p in err.value.problems if p.field == field]
    assert found, [(p.field, p.message) for p in err.value.problems]
    assert text in found[0].message and found[0].line is not None


def test_study_axis_values_that_break_a_v2_rule_are_refused_per_variant() -> None:
    """The per-variant check of a study's axis values (parameter_checks.check_parameters) holds the same rules as the
    schema: a failure elongation on the wrong side of the initial elongation, a tangent stiffness not below
    the stiffness, a damper curve point that takes the curve off the origin (the reason names
    initial_elongation). Valid columns pass."""
    model = _one_spring(
        {"type": "elastoplastic", "stiffness": 100.0, "tangent_stiffness": 10.0, "yield_force": 1.0},
        1.0,
        1.0,
        initial_elongation=0.01,
        failure={"tension": 0.05},
    )
    plan = model_plan(model)
    topo = plan.topology
    P = np.repeat(plan.base[:, None], 4, axis=1)
    apply_axis(P, topo.paths["springs.s.failure.tension"], np.array([0.05, 0.005, 0.05, 0.05]))
    apply_axis(P, topo.paths["springs.s.material.tangent_stiffness"], np.array([10.0, 10.0, 100.0, 10.0]))
    apply_axis(P, topo.paths["springs.s.initial_elongation"], np.array([0.01, 0.01, 0.01, -0.2]))
    check = check_parameters(topo, P, plan.interval)
    assert check.bad.tolist() == [False, True, True, False]
    assert (
        "springs.s.failure.tension: expected an elongation above initial_elongation (0.01)" in check.reason(1)
    )
    assert (
        "springs.s.material.tangent_stiffness: expected a tangent_stiffness >= 0 and below stiffness"
        in check.reason(2)
    )

    damper = _one_spring(
        {
            "type": "nonlinear_damper",
            "curve": "c",
            "_curves": {"c": {"x": [-1.0, 0.0, 1.0], "y": [-1.0, 0.0, 1.0]}},
        },
        1.0,
        1.0,
    )
    plan = model_plan(damper)
    P = np.repeat(plan.base[:, None], 2, axis=1)
    apply_axis(P, plan.topology.paths["curves.c.y.1"], np.array([0.0, 0.5]))
    check = check_parameters(plan.topology, P, plan.interval)
    assert check.bad.tolist() == [False, True]
    assert "must pass through the origin" in check.reason(1) and "initial_elongation" in check.reason(1)


@pytest.mark.parametrize("kernel", ["reference", "generic", "generated"])
def test_a_spring_only_in_tension_has_a_max_crush_of_plus_zero(kernel: str) -> None:
    """A spring stretched from its rest length (x = sin(10 t) / 10, up to t = 0.1 s) never shortens:
    max_crush is +0.0 on every kernel (the reference's np.maximum(0.0, -0.0) gave -0.0, printed "-0.0"),
    max_elongation sin(1) / 10 (closed form, 1e-3)."""
    from helpers import same_bits

    out = generated_part("pull", PULL) if kernel == "generated" else run_model(PULL, kernel=kernel)[0]
    assert same_bits(out.max_crush, np.zeros_like(out.max_crush))
    assert out.max_elongation[0, 0] == pytest.approx(0.1 * math.sin(1.0), rel=1e-3)


def test_results_files_hold_no_negative_zero(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The reference kernel's acceleration history of tests/test_kernel_twins.py's every-material model
    holds -0.0 samples (a zero force divided by a mass, with its sign); results.nc stores them as +0.0
    and every value is the kernel's (second implementation: the kernel output itself, copied as the
    run's chunk returns it, before anything writes it; one reference run, two before)."""
    import netCDF4

    from crashstudy.run import runner
    from twin_models import one_d_materials

    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(one_d_materials(False)))
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "reference")
    computed: list[np.ndarray] = []
    real = runner.run_chunk

    def kept(*args: Any, **kwargs: Any) -> Any:
        res = real(*args, **kwargs)
        computed.append(res.out.histories["acceleration"].copy())
        return res

    monkeypatch.setattr(runner, "run_chunk", kept)
    runner.simulate(str(path), tmp_path / "out").close()
    assert len(computed) == 1
    acc = computed[0]  # what the run computed
    assert np.any((acc == 0.0) & np.signbit(acc))  # the case has what the files must not show
    with netCDF4.Dataset(tmp_path / "out" / "results.nc") as nc:
        stored = np.moveaxis(np.asarray(nc.variables["acceleration"][:]), 0, -1)
        assert np.array_equal(stored, acc, equal_nan=True)
        for name, var in nc.variables.items():
            if var.dtype.kind == "f":
                values = np.ma.filled(var[:], np.nan)
                assert not np.any((values == 0.0) & np.signbit(values)), name
