"""Property-based tests (hypothesis) of the command line on generated models, through
:func:`crashstudy.cli.main` in this process, as a user's command would run.

**Random valid models run or fail cleanly.** 1-D and 2-D trees of 2-6 nodes, every material type with
valid curves, random masses, velocities, optional gravity, loads with time curves and rigid walls, all
three unit systems, ``safety_factor`` or ``tolerance`` steps. ``simulate`` returns 0 or 1 and never
raises; on 1 the summary says ``failed`` with a non-empty reason; on 0 ``energy_error`` is finite. With
the cases found by it: a model at rest until a late load, a node that reaches a wall in the first step,
a preloaded spring's energy balance.

The number of generated inputs that actually ran is counted (property_inputs.py) and printed at the end of
the module (run with ``-s`` to see it); docs/robustness.md quotes it. How many examples each property
draws: property_inputs.py."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from crashstudy.results.store import Results
from helpers import dump, run_main
from models import wall_spring
from property_inputs import COUNTS, _report_counts  # noqa: F401 - _report_counts: autouse, prints the counts
from strategies import examples, valid_model

# ------------------------------------------------------------------------------------------------
# 1. valid models run or fail with a clear status
# ------------------------------------------------------------------------------------------------


@contextlib.contextmanager
def _environ(**values: str) -> Iterator[None]:
    """Environment variables set for the duration (for a hypothesis test, where a function-scoped
    ``monkeypatch`` would be shared by all examples)."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@settings(max_examples=examples(40, 120), deadline=None, suppress_health_check=list(HealthCheck))
@given(valid_model())
def test_random_valid_model_runs_or_fails_with_a_clear_status(model: dict[str, Any]) -> None:
    """Draws 40 models (120 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run). They run on the
    generic compiled kernel (``CRASHSTUDY_KERNEL=generic``; the three kernels give bitwise equal results,
    docs/kernels.md): where the generic kernel is not in the cache yet (a first ``pytest -n 0``), the
    automatic choice compiles a generated kernel per model shape, 3-10 s each, which this property is not about."""
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp, _environ(CRASHSTUDY_KERNEL="generic"):
        path = Path(tmp) / "model.yaml"
        path.write_text(dump(model), encoding="utf-8")
        rc, out, err = run_main("validate", str(path))
        assert rc == 0, f"generated model is not valid:\n{err}\n{dump(model)}"
        rc, out, err = run_main("simulate", str(path), "-o", str(Path(tmp) / "out"))
        COUNTS["models_simulated"] += 1
        assert rc in (0, 1), (rc, out, err)
        assert "Traceback" not in err
        res = Results(Path(tmp) / "out")
        row = res.summary.iloc[0]
        res.close()
        checked = _well_posed(model)
        if rc == 1:
            COUNTS["models_failed_cleanly"] += 1
            speeds = [abs(v) for vec in model.get("initial_velocity", {}).values() for v in vec]
            kind = (
                "extreme speed"
                if any(v > 1e100 for v in speeds)
                else "at rest"
                if not any(speeds)
                else "moving"
            )
            COUNTS[f"failure ({kind}): " + str(row["failure_reason"]).split(" at t=")[0].split(" (")[0]] += 1
            assert row["status"] == "failed", row
            assert str(row["failure_reason"]).strip(), row
            assert "failed: " in err and str(row["failure_reason"]) in err
            # a well-posed model may only fail because a 2-D spring collapsed, never as "unstable"
            assert not checked or "crushed to zero length" in row["failure_reason"], (
                row["failure_reason"],
                dump(model),
            )
        else:
            COUNTS["models_ok"] += 1
            assert row["status"] == "ok", row
            assert np.isfinite(row["energy_error"]), row
            if checked:
                # the work of a kink inside a step (yield, unloading, a curve knot) is integrated to second
                # order, so not quite round-off (up to ~3e-6 seen); a damper's work is second-order accurate
                # (about 5 % at safety_factor 1). An accounting bug shows as 1e-3 ... 1 (see the xfails below)
                dampers = any(sp["material"]["type"] == "damper" for sp in model["springs"].values())
                COUNTS["models_energy_balance_checked"] += 1
                assert row["energy_error"] < (0.1 if dampers else 1e-3), (
                    row["energy_error"],
                    dump(model),
                )  # energy balance target 1e-3


def _well_posed(model: dict[str, Any]) -> bool:
    """No rigid wall and moving at the start (KE0 > 0), at most 1 km/s (preloads included: IE0 is in the balance).

    Such a model must run (or fail only by a 2-D collapse) with a small ``energy_error``. Excluded, each
    with its own test below: walls (:func:`test_energy_error_of_a_node_that_reaches_a_wall_in_the_first_step`),
    a preload released from rest (:func:`test_preloaded_spring_keeps_the_energy_balance`) and models that start
    at rest, where ``energy_error`` is relative to a tiny number (:func:`test_model_at_rest_until_a_late_load_runs`).
    """
    if model.get("rigid_walls"):
        return False
    speeds = [abs(v) for vec in model.get("initial_velocity", {}).values() for v in vec]
    return any(speeds) and all(v <= 1e3 for v in speeds)


AT_REST = """\
name: pulse-from-rest
curves:
  load: {x: [-0.097332, -0.087526, -0.009807, 0.0, 0.128734], y: [-822.644089, -822.644089, -61.823486, 0.0, 0.0]}
  unload: {x: [-0.01, 0.0, 0.01], y: [-1000.0, 0.0, 1000.0]}
  pulse: {x: [0.005, 0.01, 0.02], y: [0.0, 1.0, 0.0]}
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [1.0], mass: 10.0}
springs:
  s: {nodes: [a, b], material: {type: general_nonlinear, loading: load, unloading: unload}}
loads:
  - {node: b, force: [-1000.0], curve: pulse}
end_time: 0.05
output: {histories: none}
"""


def test_model_at_rest_until_a_late_load_runs(tmp_path: Path) -> None:
    path = tmp_path / "at-rest.yaml"
    path.write_text(AT_REST)
    rc, out, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    assert rc == 0, err
    res = Results(tmp_path / "out")
    row = res.summary.iloc[0]
    res.close()
    assert row["status"] == "ok" and row["energy_error"] < 1e-6


@pytest.mark.parametrize("kernel", ["reference", "generic", "generated"])
@pytest.mark.parametrize("wall", ["1.0", "0.99996"], ids=["starts-on-the-wall", "wall-within-first-step"])
def test_energy_error_of_a_node_that_reaches_a_wall_in_the_first_step(
    tmp_path: Path, wall: str, kernel: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 1 kg mass at 10 m/s (dt = 1e-5 s, 1e-4 m per step) hits a stonewall at once: all 50 J go into
    ``wall_energy``, KE + IE + E_wall - W_ext must stay 50 J at every sample and ``energy_error`` be round-off.
    (Found by the model generator: the t = 0 balance and record held that first impact's wall energy
    while the kinetic energy was still KE0, energy_error 1 - gap / (v dt): 1.0 on the plane, 0.4 for
    the wall at 0.99996. The t = 0 state is now the one before any impact, on every kernel.)
    The run lasts 10 steps (1e-4 s; 1000 before): the node rests on the wall after the first step, and
    the bug shows at the t = 0 sample. Planted (the reference's t = 0 record keeping the first impact's
    wall energy): fails at 10 steps as at 1000."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL", kernel)
    path = tmp_path / "wall-start.yaml"
    path.write_text(wall_spring(wall, end_time=1.0e-4))
    rc, out, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    assert rc == 0, err
    res = Results(tmp_path / "out")
    ds = res.dataset
    balance = (ds["kinetic_energy"] + ds["internal_energy"] + ds["wall_energy"] - ds["external_work"]).values[
        0
    ]
    final_wall = float(ds["wall_energy"][0, -1])
    err_value = float(ds["energy_error"][0])
    res.close()
    assert final_wall == pytest.approx(50.0)
    assert np.abs(balance - 50.0).max() < 1e-6, f"KE + IE + E_wall - W_ext over time: {balance[:3]} ..."
    assert err_value < 1e-6, f"energy_error {err_value} for a run that conserves energy"


PRELOADED = """\
name: preloaded
nodes:
  a: {position: [0.0], fixed: true}
  b: {position: [0.5], mass: 10.0}
curves:
  constant-pull: {x: [0.0, 0.001, 1.0], y: [0.0, 1000.0, 1000.0]}
springs:
  s: {nodes: [a, b], material: {type: nonlinear_elastic, curve: constant-pull}, initial_elongation: 0.5}
SPEED
end_time: 0.05
time_step: {dt: 1.0e-3}
output: {interval: 1.0e-3, histories: all}
"""


@pytest.mark.parametrize("speed", [None, 0.1], ids=["released-from-rest", "slow-start"])
def test_preloaded_spring_keeps_the_energy_balance(tmp_path: Path, speed: float | None) -> None:
    """A constant 1000 N pull on 10 kg (a preload on the flat part of the curve, e = 0.5 ... 0.375 m):
    x(t) = 0.5 + v0 t - 50 t^2, which central difference integrates exactly; the energy balance must hold
    to round-off and the variant must not fail.

    Formerly a BUG (found by the model generator), written as a curve with C(0) = 1000 N: the force present
    at t = 0 was left out of the first half step's work (KE + IE - KE0 - W_ext off by F0^2 dt^2 / (8 m),
    0.0125 J here), which released from rest (KE0 = W_ext = 0) failed as 'numerical instability' and at
    0.1 m/s gave energy_error = 0.25. Such a curve is now an input error; with initial_elongation the first
    half step books F0 on the mean rate and IE0 is in the balance."""
    path = tmp_path / "preloaded.yaml"
    path.write_text(
        PRELOADED.replace("SPEED", "" if speed is None else f"initial_velocity: {{b: [{speed}]}}")
    )
    rc, out, err = run_main("simulate", str(path), "-o", str(tmp_path / "out"))
    res = Results(tmp_path / "out")
    ds = res.dataset
    x_end = float(ds["position"][0, -1, 1, 0])
    balance = (ds["kinetic_energy"] + ds["internal_energy"] - ds["external_work"]).values[0]
    err_value = float(ds["energy_error"][0])
    res.close()
    assert rc == 0, err
    v0 = speed or 0.0
    assert x_end == pytest.approx(0.5 + v0 * 0.05 - 50.0 * 0.05**2, abs=1e-12)
    assert np.abs(balance - balance[0]).max() < 1e-9, balance[:3] - balance[0]
    assert err_value < 1e-6
