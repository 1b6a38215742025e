"""The critical step shared by the step choice and the pre-run check of a fixed dt (issue 25, item 2):
``timestep.critical_steps`` against closed forms, its no-damper branch against its damped branch, and
``batch.fixed_dt_check`` against the whole batch's step choice."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from crashstudy.arrays import timestep
from crashstudy.arrays.batch import build_batch, fixed_dt_check
from crashstudy.study.plan import load_study

MODEL = """
name: one-mass
units: SI
nodes:
  wall: {position: [0.0], fixed: true}
  m: {position: [1.0], mass: 2.0}
springs:
  s: {nodes: [wall, m], material: {type: linear_elastic, stiffness: 1.0e4}}
initial_velocity: {m: [-1.0]}
end_time: 0.01
time_step: {dt: 1.0e-3}
"""


def _topo(tmp_path: Path) -> Any:
    (tmp_path / "m.yaml").write_text(MODEL)
    return load_study({"name": "s", "model": str(tmp_path / "m.yaml")}).topology


def test_critical_step_of_one_mass_is_the_closed_form_with_and_without_damping(tmp_path: Path) -> None:
    """One mass m on a spring k to the wall: dt_crit = 0.99 * 2 / sqrt(2 k / m) (nodal bound, K_n = k);
    with a damping c: 0.99 * (2 / omega) (sqrt(1 + xi^2) - xi), xi = (2 c / m) / omega. Relative 1e-15."""
    topo = _topo(tmp_path)
    m = np.array([[np.inf, np.inf, np.inf], [2.0, 0.5, 8.0]])  # the wall's mass is never used
    k = np.array([[1.0e4, 3.0e4, 2.0e3]])
    c = np.array([[0.0, 5.0, 40.0]])
    omega = np.sqrt(2.0 * k[0] / m[1])
    xi = (2.0 * c[0] / m[1]) / omega
    want = 0.99 * (2.0 / omega) * (np.sqrt(1.0 + xi * xi) - xi)
    crit, ctrl = timestep.critical_steps(topo, m, k, c)
    np.testing.assert_allclose(crit, want, rtol=1e-15)
    assert ctrl.tolist() == [1, 1, 1]
    crit0, _ = timestep.critical_steps(topo, m, k, np.zeros_like(c))
    np.testing.assert_allclose(crit0, 0.99 * 2.0 / omega, rtol=1e-15)


def test_no_damper_branch_equals_the_damped_formula_bitwise(tmp_path: Path) -> None:
    """With no damper the damped limit at xi = 0 is taken without computing xi; it equals the damped
    branch (forced with a damping of exactly 0 beside one variant with a damper) bitwise, and a zero or
    NaN mass still goes through the damped branch (gamma = 0/0: no finite step)."""
    topo = _topo(tmp_path)
    rng = np.random.default_rng(3)
    V = 1000
    m = np.vstack([np.full(V, np.inf), rng.uniform(0.1, 10.0, V)])
    k = rng.uniform(1.0, 1e6, (1, V))
    fast, fctrl = timestep.critical_steps(topo, m, k, np.zeros((1, V)))
    damp = np.zeros((1, V + 1))
    damp[0, -1] = 1.0  # one damped variant sends the whole call through the damped branch
    mm = np.hstack([m, [[np.inf], [1.0]]])
    kk = np.hstack([k, [[1.0]]])
    slow, sctrl = timestep.critical_steps(topo, mm, kk, damp)
    assert np.array_equal(fast, slow[:V]) and np.array_equal(fctrl, sctrl[:V])
    odd = np.array([[np.inf, np.inf], [0.0, np.nan]])
    crit, ctrl = timestep.critical_steps(topo, odd, np.array([[1.0e4, 1.0e4]]), np.zeros((1, 2)))
    assert np.isinf(crit).all() and ctrl.tolist() == [-1, -1]


def test_fixed_dt_check_equals_the_batch_step_choice(tmp_path: Path) -> None:
    """``fixed_dt_check`` (the pre-run check) gives the refused flags and critical steps of
    ``build_batch``'s step choice, bitwise, over a mass x stiffness x dt matrix with refused variants."""
    (tmp_path / "m.yaml").write_text(MODEL)
    study = {
        "name": "s",
        "model": str(tmp_path / "m.yaml"),
        "matrix": {
            "nodes.m.mass": [0.01, 0.5, 2.0, 7.0],
            "springs.s.material.stiffness": [1.0e2, 1.0e4, 1.0e6],
            "time_step.dt": [1.0e-4, 1.0e-3],
        },
    }
    plan = load_study(study)
    P = plan.params(0, plan.n_variants)
    _, steps = build_batch(plan.topology, P, plan.interval)
    refused, crit = fixed_dt_check(plan.topology, P)
    assert refused.any() and not refused.all()
    assert np.array_equal(refused, steps.refused) and np.array_equal(crit, steps.dt_crit)
