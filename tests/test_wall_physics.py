"""Rigid-wall numbers that mean what they say (issue 23 item 4) and the rate of a prescribed node at a
kink of its displacement curve (item 12), on every kernel (reference, generic, generated).

Independent truths are closed forms: the momentum of a mass stopped by a wall, the force of a preloaded
spring, the peak force of a mass on a spring brought to rest, a damper's law at the prescribed speed.
The generated kernel runs these models side by side in one model (:func:`models.generated_parts`, shared
with tests/test_spring_features_*.py: one compiled kernel for all of them, :func:`helpers.generated_part`);
each test checks its own part of that run against its closed form.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from crashstudy.kernel.output import KernelOutput
from helpers import generated_part, run_model
from models import damped_stroke, penalty_hit, wall_hit, wall_rest

KERNELS = ["reference", "generic", "generated"]


def _rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


def _run(model: dict[str, Any], kernel: str, part: str) -> KernelOutput:
    """``model`` run by ``kernel``; the generated kernel runs it as part ``part`` of the one model of
    :func:`models.generated_parts` (:func:`helpers.generated_part`: its own nodes, springs and walls of that
    run's output, at this model's step, end time and output interval)."""
    if kernel == "generated":
        return generated_part(part, model)
    return run_model(model, kernel)[0]


@pytest.mark.parametrize("kernel", KERNELS)
def test_rigid_wall_impulse_is_the_momentum_and_does_not_depend_on_dt(kernel: str) -> None:
    """A free 4 t mass at 15.6 m/s stopped by a rigid wall: wall_impulse = m v0 (1 + e), e = 0, within
    1e-9 relative at dt = 0.1 ms and 0.05 ms; no force holds it afterwards, so peak_wall_force = 0 and
    its peak deceleration is 0 (before: peak_wall_force = m v0 / dt = 624 MN at 0.1 ms, 1248 MN at dt/2)."""
    m, v0 = 4000.0, 15.6
    got = []
    for dt in (1.0e-4, 0.5e-4):
        out = _run(wall_hit(dt), kernel, "hit")
        assert out.status[0] == 0
        assert _rel(out.wall_impulse[0, 0], m * v0) < 1e-9, out.wall_impulse[0, 0]
        assert out.peak_wall_force[0, 0] == 0.0
        assert out.peak_acceleration[0, 0] == 0.0
        got.append(out.wall_impulse[0, 0])
    assert _rel(got[0], got[1]) < 1e-9


@pytest.mark.parametrize("kernel", KERNELS)
def test_front_mass_held_by_the_wall_reports_the_spring_force_and_no_deceleration(kernel: str) -> None:
    """The front mass hits the wall with a rear mass on a spring behind it. Impulse: the front mass's
    momentum m1 v0 (the spring pushes it into the wall, that part is contact force), 1e-9 relative at dt
    and dt/2. Contact force: the spring force while the front is held, peak v0 sqrt(k m2) (the rear mass
    stopped by the spring; 15.6 sqrt(1e9) = 493 kN) within 1% (coarse step) and converging (dt/2 closer).
    The held front mass: peak deceleration 0 up to round-off (before: the spring force over its mass,
    12.5 g)."""
    m1, m2, v0, k = 4000.0, 1000.0, 15.6, 1.0e6
    f_peak = v0 * np.sqrt(k * m2)
    errs = []
    for dt in (1.0e-4, 0.5e-4):
        out = _run(wall_hit(dt, spring=True), kernel, "held")
        assert out.status[0] == 0
        assert _rel(out.wall_impulse[0, 0], m1 * v0) < 1e-9, out.wall_impulse[0, 0]
        assert abs(out.peak_force[0, 0] - out.peak_wall_force[0, 0]) <= 1e-9 * f_peak
        errs.append(_rel(out.peak_wall_force[0, 0], f_peak))
        assert out.peak_acceleration[0, 0] <= 1e-9 * f_peak / m1, out.peak_acceleration[0, 0]
    assert errs[0] < 1e-2 and errs[1] < errs[0], errs


@pytest.mark.parametrize("kernel", KERNELS)
def test_mass_resting_against_a_wall_under_a_preloaded_spring(kernel: str) -> None:
    """A 10 kg mass sits on a wall, a spring (k = 1e5 N/m, compressed 0.01 m) pushes it in: contact force
    = k 0.01 = 1000 N at every sample (1e-9 relative), deceleration 0 (before: 1000 N / 10 kg = 10.2 g),
    no impulse."""
    model = wall_rest()
    if kernel == "generated":  # the side-by-side model's stiffest parts need a step below this one's 0.5 ms
        model["time_step"] = {
            "dt": 1.0e-4
        }  # (the contact force and the zero deceleration do not depend on it)
    out = _run(model, kernel, "rest")
    assert out.status[0] == 0
    assert _rel(out.peak_wall_force[0, 0], 1000.0) < 1e-9
    assert np.all(np.abs(out.histories["wall_force"][:, 0, 0] - 1000.0) <= 1e-9 * 1000.0)
    assert out.peak_acceleration[1, 0] <= 1e-9 * 100.0
    assert np.all(np.abs(out.histories["acceleration"][:, 1, 0, 0]) <= 1e-9 * 100.0)
    assert out.wall_impulse[0, 0] <= 1e-9 * 1000.0 * 0.05


@pytest.mark.parametrize("kernel", KERNELS)
def test_damper_on_a_prescribed_stroke_peaks_at_the_law_of_the_fastest_prescribed_rate(kernel: str) -> None:
    """The damper's peak force is c times the fastest prescribed rate, 1000 x 6 = 6000 N (1e-6 relative:
    the rate is the step's displacement difference over dt), not the extrapolation across the kink
    v + dt/2 a (6 + 3 = 9 m/s: 9000 N before)."""
    out = _run(damped_stroke(), kernel, "stroke")
    assert out.status[0] == 0
    assert _rel(out.peak_force[1, 0], 1000.0 * 6.0) < 1e-6, out.peak_force[1, 0]


@pytest.mark.parametrize("kernel", KERNELS)
def test_penalty_wall_force_is_physical_and_converges_as_dt_halves(kernel: str) -> None:
    """A mass m at v0 into a penalty wall of stiffness k (an undamped contact spring): peak force
    v0 sqrt(k m) = 2000 N, contact time pi sqrt(m / k) = 3.14 ms (within one 10 us sample), an elastic
    rebound at v0 (1e-4), no impulse, the stored energy given back (wall_energy 0 after), energy_error
    < 1e-4. The peak force's error shrinks as dt halves (1e-5, 5e-6, 2.5e-6 s; measured 1.2e-5, 2.8e-6,
    4.6e-7 relative)."""
    m, v0, k = 1.0, 2.0, 1.0e6
    errs = []
    for dt in (1.0e-5, 5.0e-6, 2.5e-6):
        out = _run(penalty_hit(dt), kernel, "penalty")
        assert out.status[0] == 0
        errs.append(_rel(out.peak_wall_force[0, 0], v0 * np.sqrt(k * m)))
        on = np.flatnonzero(out.histories["wall_force"][:, 0, 0] > 0.0)
        assert abs((on[-1] - on[0] + 1) * 1.0e-5 - np.pi * np.sqrt(m / k)) <= 1.0e-5
        assert _rel(out.histories["velocity"][-1, 0, 0, 0], v0) < 1e-4
        assert out.wall_impulse[0, 0] == 0.0
        assert abs(out.histories["wall_energy"][-1, 0]) < 1e-12
        assert out.energy_error[0] < 1e-4  # the generated kernel's: that of the whole side-by-side model
        # this part's own balance, KE + wall_energy = KE0 at every sample (what energy_error measures when the
        # model runs alone; in the side-by-side model a 487 kJ part would hide this 2 J one; wall_energy is
        # the model's, and the other parts' walls are not reached nor pressed within these 6 ms)
        ke = 0.5 * m * out.histories["velocity"][:, 0, 0, 0] ** 2 + out.histories["wall_energy"][:, 0]
        assert np.abs(ke - 0.5 * m * v0**2).max() < 1e-4 * 0.5 * m * v0**2
    assert errs[0] < 1e-4 and errs[1] < errs[0] and errs[2] < errs[1], errs


def test_penalty_wall_stiffness_bounds_the_step() -> None:
    """One mass on a penalty wall: dt_crit = 0.99 / sqrt(k / m) = 0.99 ms for k = 1e6 N/m, m = 1 kg (the
    impact is resolved, arrays/timestep.py PENALTY_SHARE; was 0.99 x 2 / sqrt(k / m) = 1.98 ms, where one
    impact can gain several times its energy: test_wall_passive.py). A fixed dt of 1.2 ms is refused
    (invalid: above the critical step; it ran before), 0.95 ms runs."""
    from helpers import model_batch

    assert model_batch(penalty_hit(1.2e-3))[0].invalid[0] == 1
    assert model_batch(penalty_hit(0.95e-3))[0].invalid[0] == 0
