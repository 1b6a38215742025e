"""Physics of the central-difference solver against independent truths: 7. prescribed displacement and
velocity.

Every test compares a run with an analytic solution, with the scipy reference solver
(``tests/reference_scipy.py``, DOP853 at rtol 1e-10) or with the second kernel, and states its
tolerance. Models run at DEFAULT settings; physics_settings.py says which and why."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from helpers import run_model
from physics_settings import FAST, _rel

# --------------------------------------------------------------------------------------------------
# 7. Prescribed motion
# --------------------------------------------------------------------------------------------------

K_P = 3.0e4
PATH_X, PATH_Y = [0.0, 0.1, 0.2, 0.3], [0.0, 0.004, 0.001, 0.006]


def _pull(dim: int, end_time: float) -> dict[str, Any]:
    """A node whose displacement follows PATH (x 2) pulls a linear spring attached to a fixed node."""
    if dim == 1:
        nodes = {"anchor": {"position": [0.0], "fixed": True}, "grip": {"position": [0.5], "mass": 0.2}}
        pm = {"node": "grip", "quantity": "displacement", "direction": "x", "curve": "path", "scale": 2.0}
    else:  # along -y, away from the anchor above it: the spring stretches
        nodes = {
            "anchor": {"position": [0.0, 0.5], "fixed": True},
            "grip": {"position": [0.0, 0.0], "mass": 0.2, "fixed": ["x"]},
        }
        pm = {"node": "grip", "quantity": "displacement", "direction": "y", "curve": "path", "scale": -2.0}
    return {
        "name": "pull",
        "curves": {"path": {"x": PATH_X, "y": PATH_Y}},
        "nodes": nodes,
        "springs": {
            "s": {"nodes": ["anchor", "grip"], "material": {"type": "linear_elastic", "stiffness": K_P}}
        },
        "prescribed_motion": [pm],
        "end_time": end_time,
        "output": {"interval": 1.0e-3},
    }


@pytest.mark.parametrize("dim", [1, 2], ids=["1d", "2d"])
def test_prescribed_displacement_gives_spring_force_k_times_u(dim: int) -> None:
    """Spring force = k u(t) at every sample, 1e-9 relative to the largest force (positions are imposed).

    Measured: 7e-15.
    """
    out, _, plan = run_model(_pull(dim, end_time=0.25), FAST)
    t = np.arange(plan.n_out) * plan.interval
    expected = K_P * 2.0 * np.interp(t, PATH_X, PATH_Y)
    force = out.histories["spring_force"][:, 0, 0]
    assert out.status[0] == 0
    assert not np.isnan(force).any()
    assert np.max(np.abs(force - expected)) < 1e-9 * np.max(expected)


def test_prescribed_displacement_holds_up_to_the_last_knot_of_its_curve() -> None:
    """The path's last knot is t = 0.3 = end_time, inside the curve's range: at the last sample the force
    is still k u(0.3) = 360 N (1e-9 relative) and the grip's peak acceleration stays that of the path's
    kinks (about 1.1e3 m/s^2, as with end_time 0.25).

    Found: force 0.0 at t = 0.3 and 5.9e5 m/s^2 while t = n dt rounding past the last knot read the curve
    as 0 and the last step looked past end_time (both fixed in 133e37b).
    """
    out, _, _ = run_model(_pull(1, end_time=0.3), FAST)
    force = out.histories["spring_force"][:, 0, 0]
    expected = K_P * 2.0 * PATH_Y[-1]
    assert abs(force[-1] - expected) < 1e-9 * expected, (
        f"force at t=end_time {force[-1]} N, expected {expected} N"
    )
    assert out.peak_acceleration[1, 0] < 1.2e3, f"peak acceleration {out.peak_acceleration[1, 0]:.3g} m/s^2"


def _tow(initial_velocity: float) -> dict[str, Any]:
    """A 1 kg node towed at a prescribed 2 m/s (from t = 0) against a 1e4 N/m spring to a fixed node."""
    return {
        "name": "tow",
        "curves": {"speed": {"x": [0.0, 1.0], "y": [1.0, 1.0]}},
        "nodes": {"anchor": {"position": [0.0], "fixed": True}, "tug": {"position": [1.0], "mass": 1.0}},
        "springs": {
            "s": {"nodes": ["anchor", "tug"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}}
        },
        "prescribed_motion": [
            {"node": "tug", "quantity": "velocity", "direction": "x", "curve": "speed", "scale": 2.0}
        ],
        "initial_velocity": {"tug": [initial_velocity]},
        "end_time": 0.5,
        "output": {"interval": 1.0e-3},
    }


@pytest.mark.parametrize(
    "initial_velocity",
    [
        pytest.param(2.0, id="started-at-speed"),
        pytest.param(
            0.0,
            id="started-from-rest",
        ),
    ],
)
def test_prescribed_velocity_external_work_equals_kinetic_plus_internal_energy(
    initial_velocity: float,
) -> None:
    """Towed at constant 2 m/s for 0.5 s: KE = 2 J, spring energy k (1 m)^2 / 2 = 5000 J, so the work of
    the prescribed motion is KE + IE - KE0: 5000 J started at speed, 5002 J from rest (the jump at
    t = 0 does m v^2 / 2 = 2 J); balance 1e-9 relative.

    Found: from rest, external_work 5004 J (the first half step's work booked twice); fixed in 133e37b.
    """
    out, _, _ = run_model(_tow(initial_velocity), FAST)
    ke, ie, work, wall = out.final_energy[:, 0]
    assert _rel(ke, 2.0) < 1e-9 and _rel(ie, 5000.0) < 1e-9 and wall == 0.0
    expected = 5002.0 - 0.5 * initial_velocity**2
    assert _rel(work, expected) < 1e-9, f"external_work {work:.6f} J, expected {expected} J"
    assert out.energy_error[0] < 1e-9
