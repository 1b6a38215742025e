"""Every path of the ``crush`` and ``nonlinear_elastic`` spring material laws (docs/format.md), checked
against an independent oracle; time curves zero outside their range; and a regression test of a
memory-safety bug of the compiled kernel (no energy history written when none is requested).

Each test drives one 1-D spring through a prescribed elongation history and checks its force history
against an independent oracle of docs/format.md (to 1e-9 of the peak force), hand-computed values at the
turning points, and the compiled against the reference kernel (to 1e-12 of the peak): material_oracle.py
describes the oracle and the driving."""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np
import pytest

from helpers import run_model
from material_oracle import KERNEL_RTOL, PL, CrushOracle, Driven, ElasticOracle, driven_spring

# --------------------------------------------------------------------------------------------------
# crush and nonlinear_elastic
# --------------------------------------------------------------------------------------------------


def test_crush_loads_springs_back_separates_and_recontacts_on_the_same_line() -> None:
    """crush: F = min(0, L(e)) at new crush; spring-back with unloading_stiffness; no force when
    separated (also in tension, where L > 0); contact resumes on the same line; crushing beyond the
    previous e_min follows L again."""
    L = {"x": [-0.2, -0.01, 0.0, 0.1], "y": [-2.0e4, -1.0e4, 0.0, 5.0e3]}
    ku = 5.0e6
    mat = {"type": "crush", "loading": "L", "unloading_stiffness": ku}
    # 0.5 m/s: crush to -50 mm, spring back 1 mm, separate, pull to +50 mm, come back, crush to -100 mm
    path = [
        (0.0, 0.0),
        (0.1, -0.05),
        (0.102, -0.049),
        (0.12, -0.04),
        (0.3, 0.05),
        (0.496, -0.048),
        (0.5, -0.05),
        (0.6, -0.1),
        (0.8, 0.0),
    ]
    run = Driven(driven_spring(mat, {"L": L}, path, 5.0e-4))
    oracle = CrushOracle(PL(**L), ku)
    run.check_oracle(oracle)
    f_star = -1.0e4 - 0.04 * 1.0e4 / 0.19  # L(-0.05) = -12105.26 N
    assert run.at(0.1) == run.approx(f_star)
    assert run.at(0.102) == run.approx(f_star + ku * 0.001)  # spring-back: -7105.26
    assert run.at(0.12) == run.approx(0.0)  # separated
    assert run.at(0.3) == run.approx(0.0)  # tension: a crush spring cannot pull (L(0.05) = +2500)
    assert run.at(0.496) == run.approx(f_star + ku * 0.002)  # contact again on the same line: -2105.26
    assert run.at(0.5) == run.approx(f_star)
    assert run.at(0.6) == run.approx(-1.0e4 - 0.09 * 1.0e4 / 0.19)  # L(-0.1) = -14736.84
    assert run.at(0.8) == run.approx(0.0)
    assert np.all(run.F <= 0.0)
    assert oracle.e_min == pytest.approx(-0.1)


def test_nonlinear_elastic_extrapolates_beyond_both_ends_of_its_curve() -> None:
    """Material curves extrapolate along their first/last segment (docs/format.md): slope 60 beyond +-1."""
    C = {"x": [-1.0, -0.5, 0.0, 0.5, 1.0], "y": [-80.0, -50.0, 0.0, 60.0, 90.0]}
    mat = {"type": "nonlinear_elastic", "curve": "C"}
    path = [(0.0, 0.0), (3.0, 3.0), (9.0, -3.0), (12.24, 0.24)]
    run = Driven(driven_spring(mat, {"C": C}, path, 2.0e-2))
    run.check_oracle(ElasticOracle(PL(**C)))
    assert run.at(2.0) == run.approx(150.0)
    assert run.at(3.0) == run.approx(210.0)  # 90 + 60 * 2
    assert run.at(5.0) == run.approx(90.0)  # unloads on the same curve
    assert run.at(7.5) == run.approx(-110.0)  # e = -1.5
    assert run.at(9.0) == run.approx(-200.0)  # -80 - 60 * 2
    assert run.at(12.24) == run.approx(28.8)


def test_time_curves_are_zero_outside_their_range() -> None:
    """Loads scaled by time curves act only inside the curve's range (no extrapolation): on a free
    mass the velocity changes by the curves' impulse only. A triangle 0 -> 1 -> 0 on [0.1, 0.3] s
    (force 3 N, impulse 0.3 N s; extrapolated it would be -1 at t = 0) and a rectangle 1 on
    [0.4005, 0.6005] s (force -1 N, impulse -0.2 N s; extrapolated it would act for ever)."""
    model = {
        "name": "free-mass",
        "curves": {
            "tri": {"x": [0.1, 0.2, 0.3], "y": [0.0, 1.0, 0.0]},
            "box": {"x": [0.4005, 0.6005], "y": [1.0, 1.0]},
        },
        "nodes": {"p": {"position": [0.0], "mass": 2.0}},
        "initial_velocity": {"p": [0.5]},
        "loads": [
            {"node": "p", "force": [3.0], "curve": "tri"},
            {"node": "p", "force": [-1.0], "curve": "box"},
        ],
        "end_time": 1.0,
        "time_step": {"dt": 1.0e-3},
        "output": {"interval": 1.0e-3},
    }
    out, _, plan = run_model(model, kernel="generic")
    ref, _, _ = run_model(model, kernel="reference")
    t = np.arange(plan.n_out) * 1.0e-3
    v = out.histories["velocity"][:, 0, 0, 0]
    a = out.histories["acceleration"][:, 0, 0, 0]
    assert np.max(np.abs(v - ref.histories["velocity"][:, 0, 0, 0])) <= KERNEL_RTOL
    assert np.max(np.abs(a - ref.histories["acceleration"][:, 0, 0, 0])) <= KERNEL_RTOL
    tol = 1e-9
    before, between, after = t < 0.1 - 1e-9, (t > 0.3 + 1e-9) & (t < 0.4), t > 0.601
    assert np.max(np.abs(v[before] - 0.5)) <= tol and np.max(np.abs(a[before])) == 0.0
    assert np.max(np.abs(v[between] - (0.5 + 0.3 / 2.0))) <= tol and np.max(np.abs(a[between])) == 0.0
    assert np.max(np.abs(v[after] - (0.5 + 0.1 / 2.0))) <= tol and np.max(np.abs(a[after])) == 0.0
    assert a[int(round(0.2 / 1.0e-3))] == pytest.approx(1.5, abs=1e-9)  # peak of the triangle: 3 N / 2 kg


# --------------------------------------------------------------------------------------------------
# Found while writing these tests: a memory-safety bug of the compiled kernel (regression test)
# --------------------------------------------------------------------------------------------------


def test_compiled_kernel_writes_no_energy_history_when_none_is_requested(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``output: {histories: [spring_force, spring_elongation]}`` must not write energy histories.

    The compiled kernel gets a (1, 4, 1) placeholder for the energy histories when none is requested.
    At commit 142f4f2 it wrote ``h_energy[r, k, q]`` for every sample ``r`` regardless; numba does not
    check bounds, so real runs wrote past the buffer ('free(): invalid pointer', segfaults, hangs and a
    wrong force history were observed). 6e0b3d2 guards the write. Here the placeholder is replaced
    by a C-contiguous view of the first row of a larger NaN array, so any stray write lands,
    harmlessly and visibly, in its other rows (this test fails on 142f4f2's kernel).
    """
    from crashstudy.kernel import compiled

    real = compiled._run
    slot = list(inspect.signature(real.py_func).parameters).index("H")  # the histories record
    caught: dict[str, np.ndarray] = {}

    def guarded(*args: Any) -> Any:
        args = list(args)
        if args[slot].energy.shape == (1, 4, 1):  # the placeholder: no energy history requested
            guard = np.full((64, 4, 1), np.nan)
            caught["guard"] = guard
            args[slot] = args[slot]._replace(energy=guard[:1])
        return real(*args)

    monkeypatch.setattr(compiled, "_run", guarded)
    model = {
        "name": "k",
        "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
        "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
        "initial_velocity": {"b": [1.0]},
        "end_time": 0.5,
        "time_step": {"dt": 0.01},
        "output": {"interval": 0.01, "histories": ["spring_force", "spring_elongation"]},
    }
    out, _, plan = run_model(model, kernel="generic")
    assert plan.n_out == 51 and "guard" in caught
    assert np.all(np.isnan(caught["guard"][1:])), "energy samples written outside the (1, 4, 1) buffer"
